"""Every tutorial notebook is stored without outputs, states its CPU time, and runs in fast mode."""

import os
from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

TUTORIALS = sorted((Path(__file__).resolve().parent.parent / "tutorials").glob("*.ipynb"))


def test_there_are_tutorials():
    assert len(TUTORIALS) >= 1


@pytest.mark.parametrize("path", TUTORIALS, ids=lambda p: p.stem)
def test_notebook_is_clean_and_runs(path, monkeypatch):
    nb = nbformat.read(path, as_version=4)
    assert "Expected CPU time" in nb.cells[0].source, "the first cell must state the expected CPU time"
    for cell in nb.cells:
        if cell.cell_type == "code":
            assert not cell.outputs and cell.execution_count is None, "notebooks are stored without outputs"
    monkeypatch.setenv("DEXART_LITE_FAST", "1")
    NotebookClient(nb, timeout=900, kernel_name="python3", resources={"metadata": {"path": str(path.parent)}}).execute()
