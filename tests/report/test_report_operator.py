"""`orbitrig report` as an operator reads it after a crash."""

import h5py
from typer.testing import CliRunner

from orbitrig.cli import app

from report_synthetic import write_synthetic_run


def test_report_of_a_killed_run_says_how_to_continue_it(tmp_path):
    run = write_synthetic_run(tmp_path / "run", n_points=1, incomplete=1)
    with h5py.File(run / "run.h5", "r+") as f:  # what kill -9 leaves: the status never left 'running'
        f.attrs["status"] = "running"
    r = CliRunner().invoke(app, ["report", str(run), "--point", "0"])
    assert r.exit_code == 0, r.output
    assert "run running: 1 complete point(s), 1 incomplete" in r.stdout
    assert f"orbitrig sweep --resume {run}" in r.stdout
