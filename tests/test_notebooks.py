"""Every notebook in ``notebooks/`` executes top to bottom without an error (so none rots).

Each runs in a fresh ``python3`` kernel (nbclient) with the Agg backend, from the
notebooks folder; a cell that raises (including a notebook's own ``assert``) fails the
test with the cell's traceback. Outputs are not written back: notebooks are committed
without them.
"""

from pathlib import Path

import pytest

from _helpers import GC_THRESHOLD  # tests/_helpers.py

NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("*.ipynb"))
CELL_TIMEOUT_S = 300
# the kernel's Python tuned as the test workers' (`_helpers.GC_THRESHOLD`)
KERNEL_GC = (
    f"--IPKernelApp.exec_lines=['import gc', 'gc.freeze()', 'gc.set_threshold{GC_THRESHOLD}']"
)


def test_there_are_notebooks():
    assert len(NOTEBOOKS) >= 5, NOTEBOOKS


@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # jupyter_client / zmq internals
@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_executes(path, monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    monkeypatch.setenv("MPLBACKEND", "Agg")  # inherited by the kernel
    monkeypatch.setenv("PYDEVD_DISABLE_FILE_VALIDATION", "1")  # quiet the debugger's warning
    nb = nbformat.read(path, as_version=4)
    assert not any(c.get("outputs") for c in nb.cells if c.cell_type == "code"), (
        f"{path.name} is committed with outputs; clear them first"
    )
    client = nbclient.NotebookClient(
        nb,
        timeout=CELL_TIMEOUT_S,
        kernel_name="python3",
        extra_arguments=[KERNEL_GC],
        resources={"metadata": {"path": str(path.parent)}},
    )
    try:
        client.execute()
    except nbclient.exceptions.CellExecutionError as err:
        pytest.fail(f"{path.name}: a cell raised\n{err}", pytrace=False)
    # every code cell ran
    assert all(c.get("execution_count") for c in nb.cells if c.cell_type == "code")
