"""One simulated run shared by the API and data-file tests: the demo point on the clean
scenario with 10 revolutions per block (`orbitrig sweep --sim`, a few seconds)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def sim_run(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("api")
    matrix = tmp / "small.toml"
    text = (ROOT / "config" / "matrices" / "demo.toml").read_text()
    matrix.write_text(text.replace('name = "demo"', 'name = "small"\nrevolutions = 10'))
    env = {**os.environ, "PYTHONPATH": str(ROOT), "COLUMNS": "200"}
    done = subprocess.run([sys.executable, "-m", "orbitrig", "sweep", "--sim", "--sim-config", "clean",
                           "--matrix", str(matrix), "--out", str(tmp / "run")], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=180)  # fmt: skip
    if done.returncode != 0:  # a drive poll lost under heavy load: one retry, as a person would
        done = subprocess.run([sys.executable, "-m", "orbitrig", "sweep", "--sim", "--sim-config", "clean",
                               "--matrix", str(matrix), "--out", str(tmp / "run2")], cwd=ROOT, env=env,
                              capture_output=True, text=True, timeout=180)  # fmt: skip
        assert done.returncode == 0, done.stderr[-3000:]
        return tmp / "run2"
    return tmp / "run"
