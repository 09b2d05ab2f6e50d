"""The notebooks: committed without outputs, and executed end to end at the reduced size
(``MCFRIC_NOTEBOOK_SCALE=small``) with nbclient, in memory, from a temporary working
directory. Any cell error fails the test."""

import re
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = {"paper_figures.ipynb": 3, "statistics.ipynb": 6}   # name: figures it shows
CELL_TIMEOUT_S = 600


def _outputs(nb):
    return [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]


def _stdout(nb):
    return "".join(o.text for o in _outputs(nb) if o.output_type == "stream"
                   and o.name == "stdout")


@pytest.mark.parametrize("name", NOTEBOOKS)
def test_notebook_is_committed_without_outputs(name):
    nb = nbformat.read(ROOT / "notebooks" / name, as_version=4)
    nbformat.validate(nb)
    assert nb.metadata.kernelspec.name == "python3"
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code
    for cell in code:
        assert cell.outputs == [], f"{name}: a cell has outputs (clear them before committing)"
        assert cell.execution_count is None, f"{name}: a cell has an execution count"


@pytest.mark.parametrize("name", NOTEBOOKS)
def test_notebook_executes_at_small_scale(name, tmp_path, monkeypatch):
    src = ROOT / "notebooks" / name
    before = src.read_bytes()
    nb = nbformat.read(src, as_version=4)
    monkeypatch.setenv("MCFRIC_NOTEBOOK_SCALE", "small")
    monkeypatch.delenv("MPLBACKEND", raising=False)    # the kernel's inline backend shows figures
    monkeypatch.chdir(tmp_path)
    client = NotebookClient(nb, kernel_name="python3", timeout=CELL_TIMEOUT_S,
                            startup_timeout=120,
                            resources={"metadata": {"path": str(tmp_path)}})
    client.execute()                                   # raises CellExecutionError on any error

    outputs = _outputs(nb)
    assert not [o for o in outputs if o.output_type == "error"]
    text = _stdout(nb)
    assert "MCFRIC_NOTEBOOK_SCALE = 'small'" in text, "the notebook must print the size it used"
    images = sum("image/png" in o.get("data", {}) for o in outputs)
    assert images >= NOTEBOOKS[name], f"{name}: {images} figures shown"
    assert src.read_bytes() == before, "executed outputs must not be written into the repo"
    assert list(tmp_path.iterdir()) == [], "the notebook left files in its working directory"

    if name == "paper_figures.ipynb":
        # every ensemble lies inside its bounds (the notebook's own, computed verdicts)
        verdicts = re.findall(r"inside (?:the|the corrected) bounds: (\w+)", text)
        assert len(verdicts) == 5 and set(verdicts) == {"agrees"}, verdicts
        assert re.search(r"\d+ statements checked, \d+ not supported", text)
    else:
        assert "same members in both runs: True" in text
        assert "; 0 converged points outside the bounds" in text
        assert re.search(r"Wilson interval +\[\d\.\d+, \d\.\d+\]", text)
        assert re.search(r"Clopper-Pearson interval \[\d\.\d+, \d\.\d+\]", text)
