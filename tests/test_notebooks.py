"""Every notebook runs top to bottom (small grids), with its plots inline."""

from __future__ import annotations

from pathlib import Path

import nbformat
import pytest

NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("*.ipynb"))


def test_the_notebooks_are_there():
    assert {p.stem for p in NOTEBOOKS} == {"scara_manipulability", "p2us_kinematics", "p2us_workspace", "guidance",
                                        "paper_b_reproduction", "design_synthesis", "collisions"}


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_runs(path, tmp_path):
    from nbclient import NotebookClient

    nb = nbformat.read(path, as_version=4)
    NotebookClient(nb, timeout=300, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}).execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.output_type == "error"]
    assert not [o.text for o in outputs if o.output_type == "stream" and o.name == "stderr"], "warnings shown"
    text = "".join(o.get("text", "") + o.get("data", {}).get("text/plain", "") for o in outputs)
    assert "np.float64(" not in text and " at 0x" not in text, "raw reprs printed"
    assert nb.cells[0].cell_type == nb.cells[-1].cell_type == "markdown", "opens with what it shows, ends with findings"
    assert any("image/png" in o.get("data", {}) for o in outputs), "plots are drawn inline"
    assert any("text/html" in o.get("data", {}) for o in outputs), "the Meshcat view is embedded"
