"""examples/sugiyama.ipynb runs headless, top to bottom, with its own assertions."""

import nbformat
from nbclient import NotebookClient

from conftest import REPO


def test_the_sugiyama_notebook_runs():
    nb = nbformat.read(REPO / "examples" / "sugiyama.ipynb", as_version=4)
    NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(REPO / "examples")}}).execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.output_type == "error"]
    images = [o for o in outputs if "image/png" in o.get("data", {})]
    assert len(images) == 2, "the two time-space diagrams"
