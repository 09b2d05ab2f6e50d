"""Sphinx configuration of the mcfric docs (MyST Markdown pages, numpydoc API reference).

Build: ``sphinx-build -W -b html docs docs/_build/html`` (warnings are errors in CI).
"""

import mcfric

project = "mcfric"
author = "the mcfric developers"
copyright = "2026, the mcfric developers"
release = mcfric.__version__
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
    "numpydoc",
]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3          # links such as theory.md#response-bounds
exclude_patterns = ["_build"]
root_doc = "index"

# numpydoc: no autosummary tables of class members (the classes document themselves)
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
autodoc_member_order = "bysource"
autodoc_typehints = "none"

html_theme = "alabaster"
html_title = "mcfric"
html_static_path = []
