"""Every notebook runs top to bottom in smoke mode (CI=1), through a real Jupyter kernel,
and keeps its files beside itself (nothing left in the system's temporary folder)."""

from __future__ import annotations

from pathlib import Path

import nbformat
import pytest
from nbclient import NotebookClient

NOTEBOOKS = sorted((Path(__file__).resolve().parent.parent / "notebooks").glob("*.ipynb"))

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs_in_smoke_mode(
    path: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("CI", "1")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    temporary = tmp_path / "system_tmp"  # the kernel's TMPDIR: must stay empty
    temporary.mkdir()
    monkeypatch.setenv("TMPDIR", str(temporary))
    work = tmp_path / "beside_the_notebook"
    work.mkdir()
    notebook = nbformat.read(path, as_version=4)
    assert not any(cell.get("outputs") for cell in notebook.cells if cell.cell_type == "code"), (
        f"{path.name} is stored with outputs; clear them before committing"
    )
    client = NotebookClient(
        notebook, timeout=600, kernel_name="python3", resources={"metadata": {"path": work}}
    )
    client.execute()
    text = "".join(
        output.get("text", "")
        for cell in notebook.cells
        if cell.cell_type == "code"
        for output in cell.outputs
    )
    assert "Traceback" not in text
    left = sorted(p.name for p in temporary.iterdir())
    assert not left, f"{path.name} left {left} in the system's temporary folder"
    images = [
        output
        for cell in notebook.cells
        if cell.cell_type == "code"
        for output in cell.outputs
        if "image/png" in output.get("data", {})
    ]
    assert images, f"{path.name} showed no figure"


def test_the_documented_notebooks_exist() -> None:
    assert {"01_rig_tour", "02_paper_experiment"} <= {p.stem for p in NOTEBOOKS}
