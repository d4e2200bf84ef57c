"""The notebooks in examples/: kept without outputs in git, and executed against the server
(each ends by asserting what its figure shows). ``GEOMINT_EXAMPLES_OUT``, when set, is a
directory the executed notebooks are written to, with their figures."""

from __future__ import annotations

import os
import time
from pathlib import Path
from typing import List

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
NOTEBOOKS: List[Path] = sorted(EXAMPLES.glob("*.ipynb"))


def test_there_are_notebooks_for_every_paper_a_typed_in_system_and_basin_maps() -> None:
    names = {p.stem.split("_")[0] for p in NOTEBOOKS}
    assert {"000", "001", "003", "typed", "basins"} <= names, names


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_is_stored_without_outputs(path: Path) -> None:
    nb = nbformat.read(path, as_version=4)
    for cell in nb.cells:
        if cell.cell_type == "code":
            assert cell.outputs == [] and cell.execution_count is None, f"{path.name}: a cell has outputs"
        assert "execution" not in cell.metadata and "collapsed" not in cell.metadata
    assert "widgets" not in nb.metadata, f"{path.name}: widget state is stored"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_runs_against_the_server(path: Path, url: str) -> None:
    nb = nbformat.read(path, as_version=4)
    os.environ["GEOMINT_URL"] = url  # the kernel inherits it
    os.environ.setdefault("MPLBACKEND", "module://matplotlib_inline.backend_inline")
    started = time.monotonic()
    client = nbclient.NotebookClient(nb, timeout=120, kernel_name="python3",
                                     resources={"metadata": {"path": str(EXAMPLES)}})
    client.execute()
    elapsed = time.monotonic() - started
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
    assert not errors
    figures = sum("image/png" in o.get("data", {}) for c in nb.cells if c.cell_type == "code" for o in c.outputs)
    assert figures >= 1, f"{path.name} drew no figure"
    out = os.environ.get("GEOMINT_EXAMPLES_OUT")
    if out:
        Path(out).mkdir(parents=True, exist_ok=True)
        nbformat.write(nb, Path(out) / path.name)
    print(f"{path.name}: {elapsed:.1f} s")
