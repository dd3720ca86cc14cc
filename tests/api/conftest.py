"""One simulated run shared by the API and data-file tests: the demo point on the clean
scenario with 10 revolutions per block (`orbitrig sweep --sim --speedup 10`, under 10 s). The rig
file allows slower Modbus answers (0.3 s; the loss still declared before the drives'
1 s watchdog), as a loaded test machine needs."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

from support.cli_helpers import orbitrig_cmd
from support.paths import ROOT
from support.sweep_helpers import demo_text


@pytest.fixture(scope="session")
def sim_run(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("api")
    matrix = tmp / "small.toml"
    matrix.write_text(demo_text("small", 10))
    rig = tmp / "rig.toml"
    text = (ROOT / "config" / "rig.toml").read_text()
    rig.write_text(
        text.replace("timeout_s = 0.15", "timeout_s = 0.3").replace("link_loss_polls = 3", "link_loss_polls = 2")
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT), "COLUMNS": "200"}
    for attempt in ("run", "run2"):  # a drive answer lost under heavy load: one retry, as a person would
        done = subprocess.run(
            orbitrig_cmd(
                "sweep",
                "--sim",
                "--sim-config",
                "clean",
                "--speedup",
                "10",
                "--config",
                str(rig),
                "--matrix",
                str(matrix),
                "--out",
                str(tmp / attempt),
            ),
            cwd=ROOT,
            env=env,
            capture_output=True,
            text=True,
            timeout=180,
        )
        if done.returncode == 0 or _point_complete(tmp / attempt / "run.h5"):  # a trip while stopping at the end
            return tmp / attempt
    raise AssertionError(done.stderr[-3000:])


def _point_complete(path: Path) -> bool:
    import h5py

    if not path.is_file():
        return False
    with h5py.File(path, "r") as f:
        return "points/0000" in f and bool(f["points/0000"].attrs.get("complete"))


@pytest.fixture(scope="session")
def synthetic_run(tmp_path_factory) -> Path:
    """The report tests' synthetic run (frequency-dependent fits with their adequacy test, a
    refused model, an incomplete point), consolidated into run.h5."""
    from support.report_synthetic import write_synthetic_run

    return write_synthetic_run(tmp_path_factory.mktemp("synthetic") / "run")  # finished: run.h5 beside the pieces
