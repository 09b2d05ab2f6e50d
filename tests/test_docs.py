"""The README and the docs tell the truth: their code runs as shown, their links resolve,
and nothing in the repository points outside it.

* every ```python block of README.md and docs/*.md runs, in order, one namespace per file,
  in a fresh directory;
* every ``$ command`` line of a ```console block runs and exits with 0 (``pip install``
  and ``pytest`` excepted: CI runs exactly those two around this suite); transcripts
  that are not meant to run are ```text blocks;
* every relative link of a page names a file of the repository;
* no tracked text file refers to a path outside the repository.
"""

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```", re.S | re.M)
#: Commands of console blocks that CI itself runs around this suite: by their program ...
NOT_HERE = ("pip", "pytest")
#: ... or whole (the README's main command, the default run: .ci/run's main job).
CI_RUNS = ("mcfric run",)


def blocks(page, kind):
    """The bodies of the fenced blocks of ``page`` whose info string is ``kind``."""
    return [body for info, body in FENCE.findall(page.read_text())
            if info.strip() == kind]


def _ids(pages):
    return [p.relative_to(ROOT).as_posix() for p in pages]


def test_readme_is_short():
    assert len(ROOT.joinpath("README.md").read_text().splitlines()) <= 200


@pytest.mark.parametrize("page", [p for p in PAGES if blocks(p, "python")],
                         ids=_ids([p for p in PAGES if blocks(p, "python")]))
def test_python_blocks_run(page, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    namespace = {"__name__": "__docs__"}
    for n, code in enumerate(blocks(page, "python"), 1):
        try:
            exec(compile(code, f"{page.name}, python block {n}", "exec"), namespace)
        except Exception as e:   # name the block: the traceback alone shows only exec
            raise AssertionError(f"{page.name}, python block {n} failed: {e!r}") from e


def _commands(page):
    out = []
    for body in blocks(page, "console"):
        for line in body.splitlines():
            if line.startswith("$ "):
                out.append(line[2:])
    return out


@pytest.mark.parametrize("page", [p for p in PAGES if _commands(p)],
                         ids=_ids([p for p in PAGES if _commands(p)]))
def test_console_commands_run(page, tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg")
    env["PATH"] = str(Path(sys.executable).parent) + os.pathsep + env.get("PATH", "")
    ran = 0
    for command in _commands(page):
        for part in command.split("&&"):
            if (shlex.split(part, comments=True)[0] in NOT_HERE
                    or part.strip() in CI_RUNS):
                continue
            r = subprocess.run(part, shell=True, cwd=tmp_path, env=env, capture_output=True,
                               text=True, timeout=900)
            assert r.returncode == 0, f"{page.name}: `{part.strip()}` -> {r.returncode}\n" \
                                      f"{r.stderr[-2000:]}"
            ran += 1
    assert ran or all(c.split()[0] in NOT_HERE or c.strip() in CI_RUNS
                      for c in _commands(page))


LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


@pytest.mark.parametrize("page", PAGES, ids=_ids(PAGES))
def test_relative_links_resolve(page):
    for target in LINK.findall(page.read_text()):
        if "://" in target or target.startswith("mailto:"):
            continue
        assert (page.parent / target).exists(), f"{page.name}: link to missing {target}"


def _tracked_text_files():
    try:
        names = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True,
                               text=True, check=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):   # not a git checkout: walk it
        names = [p.relative_to(ROOT).as_posix() for p in ROOT.rglob("*")
                 if p.is_file() and ".git" not in p.parts]
    return [ROOT / n for n in names if not n.endswith((".png", ".pdf"))]


def test_nothing_points_outside_the_repository():
    # spelled in two pieces so that this file does not match itself
    outside = re.compile("|".join([r"\.\./" + "shared", r"/" + "work/", r"/" + "home/",
                                   r"/" + "root/", "physics" + r"\.md",
                                   "kernel-" + r"notes\.md"]))
    hits = []
    for path in _tracked_text_files():
        try:
            text = path.read_text()
        except (UnicodeDecodeError, FileNotFoundError):
            continue
        hits += [f"{path.relative_to(ROOT)}: {m.group(0)}" for m in outside.finditer(text)]
    assert not hits, hits
