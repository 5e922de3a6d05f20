"""The tutorials (docs/tutorials/*.ipynb) run headless as a reader runs them, each in a
fresh folder, with nbclient: every cell executes without an error, and the assertions the
notebooks make on their own results (a finished planner task, a followed hose, a pressed
switch, a campaign's table) hold. Each notebook matches its jupytext script."""

from __future__ import annotations

import jupytext
import nbformat
import pytest
from conftest import REPO
from nbclient import NotebookClient

TUTORIALS = sorted((REPO / "docs" / "tutorials").glob("*.ipynb"))


def _Cells(notebook) -> list[tuple[str, str]]:
    return [(cell.cell_type, cell.source.strip()) for cell in notebook.cells]


def test_there_are_four_tutorials():
    assert [p.stem[:2] for p in TUTORIALS] == ["01", "02", "03", "04"]


@pytest.mark.parametrize("notebook", TUTORIALS, ids=lambda p: p.stem)
def test_each_notebook_matches_its_script(notebook):
    script = jupytext.read(notebook.with_suffix(".py"))
    assert _Cells(nbformat.read(notebook, as_version=4)) == _Cells(script), (
        f"{notebook.name} and its .py differ: `jupytext --sync {notebook}`"
    )


@pytest.mark.slow
@pytest.mark.parametrize("notebook", TUTORIALS, ids=lambda p: p.stem)
def test_the_tutorial_runs(notebook, tmp_path):
    nb = nbformat.read(notebook, as_version=4)
    client = NotebookClient(
        nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute()  # raises CellExecutionError on the first failing cell
    shown = [o for cell in nb.cells for o in cell.get("outputs", []) if "data" in o]
    assert any("<iframe" in o["data"].get("text/html", "") for o in shown)  # Meshcat or report
