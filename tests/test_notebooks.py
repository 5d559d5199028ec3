"""The notebooks: one percent-format ``.py`` per notebook is the source of truth, paired by jupytext with the
committed ``.ipynb`` (no outputs). Every notebook runs top to bottom from its ``.py`` on a clean kernel, in a
scratch directory (so it can only find shipped files through the package), with ``CARTPOLE_QUICK=1`` to shorten
its long runs; its own asserts check its results, and it draws at least one figure. With ``CARTPOLE_NOTEBOOK_OUTPUTS``
set to a folder (``make test`` sets it), each executed notebook is also written there, so the documentation site shows
the outputs of this run instead of executing the notebooks a second time (docs/conf.py)."""
import os
from pathlib import Path

import jupytext
import pytest
import nbformat
from nbclient import NotebookClient

NOTEBOOK_DIR = Path(__file__).resolve().parent.parent / "notebooks"
SOURCES = sorted(NOTEBOOK_DIR.glob("*.py"))
PAIRED = sorted(NOTEBOOK_DIR.glob("*.ipynb"))
CELL_TIMEOUT = 300   # s per cell; with CARTPOLE_QUICK=1 a whole notebook takes well under a minute


def cells(nb):
    """(cell type, source) of every cell, the part of a notebook that pairing keeps identical."""
    return [(c.cell_type, c.source.strip()) for c in nb.cells]


def test_every_notebook_is_a_pair_of_percent_source_and_ipynb():
    assert SOURCES, "no notebook sources found"
    assert [p.stem for p in SOURCES] == [p.stem for p in PAIRED]
    for path in SOURCES:
        text = path.read_text()
        assert "# %%" in text, f"{path.name} is not in jupytext's percent format"
        nb = jupytext.read(path)
        assert nb.metadata["jupytext"]["formats"] == "ipynb,py:percent", path.name


@pytest.mark.parametrize("path", SOURCES, ids=[p.stem for p in SOURCES])
def test_ipynb_is_in_sync_with_its_source_and_has_no_outputs(path):
    source = jupytext.read(path)
    paired = jupytext.read(path.with_suffix(".ipynb"))
    assert cells(paired) == cells(source), (
        f"{path.with_suffix('.ipynb').name} differs from {path.name}: run `jupytext --sync {path.relative_to(NOTEBOOK_DIR.parent)}`")
    assert paired.metadata.get("jupytext", {}).get("formats") == "ipynb,py:percent"
    for cell in paired.cells:
        if cell.cell_type == "code":
            assert not cell.get("outputs") and cell.get("execution_count") is None, (
                f"{path.with_suffix('.ipynb').name} is committed with outputs: clear them")


@pytest.mark.parametrize("path", SOURCES, ids=[p.stem for p in SOURCES])
def test_notebook_runs_its_checks_and_makes_a_figure(path, tmp_path, monkeypatch):
    monkeypatch.setenv("CARTPOLE_QUICK", "1")
    monkeypatch.setenv("CARTPOLE_OUT", str(tmp_path))
    monkeypatch.setenv("MUJOCO_GL", os.environ.get("MUJOCO_GL", "egl"))
    nb = jupytext.read(path)
    NotebookClient(nb, timeout=CELL_TIMEOUT, kernel_name="python3",
                   resources={"metadata": {"path": str(tmp_path)}}).execute()
    images = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
              if "image/png" in o.get("data", {})]
    assert images, f"{path.name} produced no figure"
    keep = os.environ.get("CARTPOLE_NOTEBOOK_OUTPUTS")
    if keep:  # the documentation site renders these (docs/conf.py)
        Path(keep).mkdir(parents=True, exist_ok=True)
        nbformat.write(nb, Path(keep) / path.with_suffix(".ipynb").name)
