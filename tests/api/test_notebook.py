"""examples/api.ipynb runs from top to bottom on a simulated run (nbclient, the python3
kernel of this interpreter) and its cells show what they promise."""

from __future__ import annotations

import nbformat
from nbclient import NotebookClient

from support.paths import ROOT


def test_example_notebook_runs(sim_run, tmp_path, monkeypatch):
    monkeypatch.setenv("ORBITRIG_RUN", str(sim_run))
    monkeypatch.setenv("PYTHONPATH", str(ROOT))
    nb = nbformat.read(ROOT / "examples" / "api.ipynb", as_version=4)
    client = NotebookClient(nb, timeout=120, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}})
    client.execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
    assert not [o for o in outputs if o.output_type == "error"]
    text = "\n".join(o.get("text", "") or o.get("data", {}).get("text/plain", "") for o in outputs)
    assert "(11, 11)" in text  # the kcd11 covariance over its free coefficients
    assert "fx_piezo: half peak-to-peak" in text
    assert "within_U" in text
    assert "(10, 2, 2), 'N/m')" in " ".join(text.split())  # the truth: Z (rows, 2, 2) as an array, K0 in N/m


def test_the_notebook_opened_in_examples_finds_the_readme_run(sim_run, tmp_path, monkeypatch):
    """Jupyter starts the notebook's kernel in examples/, and the README's main job writes runs/demo
    at the source tree's root: the first cells find it there, with no ORBITRIG_RUN set."""
    monkeypatch.delenv("ORBITRIG_RUN", raising=False)
    monkeypatch.setenv("PYTHONPATH", str(ROOT))
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "demo").symlink_to(sim_run)
    (tmp_path / "examples").mkdir()
    nb = nbformat.read(ROOT / "examples" / "api.ipynb", as_version=4)
    nb.cells = nb.cells[:2]  # the title and the cell that opens the run
    NotebookClient(
        nb, timeout=60, kernel_name="python3", resources={"metadata": {"path": str(tmp_path / "examples")}}
    ).execute()
    shown = nb.cells[1].outputs[0]["data"]["text/plain"]
    assert shown.startswith("RunData('../runs/demo', status=completed"), shown
