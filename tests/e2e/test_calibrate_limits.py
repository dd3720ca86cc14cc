"""`orbitrig calibrate` checks every speed of a step against the rig's drive limits before
anything is sent (the drives' own check, as `orbitrig drives run`): exit 2 naming the option
and the limit, no slow roll begun, no record written. Real subprocess runs on the simulator."""

from __future__ import annotations

import shutil

import pytest

from support.cli_helpers import orbitrig
from support.paths import ROOT

pytestmark = pytest.mark.timeout(120)


def _rig(tmp_path, max_spin_rpm: float | None = None):
    text = (ROOT / "config/rig.toml").read_text()
    if max_spin_rpm is not None:
        text = text.replace("max_spin_rpm = 2500.0", f"max_spin_rpm = {max_spin_rpm}", 1)
    (tmp_path / "rig.toml").write_text(text)
    shutil.copytree(ROOT / "config/calibration", tmp_path / "calibration")
    return tmp_path / "rig.toml"


@pytest.mark.parametrize(
    "args, option, rolled",
    [  # the delay step's runs reach thousands of rpm: named reference runs, no slow roll
        (
            ("delay", "--speeds-rpm", "300,600,5000"),
            "--speeds-rpm",
            "reference run at spin 7142.86 rpm, orbit 5000 rpm",
        ),
        (("runout", "--spin-rpm", "3000"), "--spin-rpm", "slow roll at spin 3000 rpm, orbit 3000 rpm"),
    ],
)
def test_a_speed_beyond_the_limits_is_refused_before_anything_is_sent(tmp_path, args, option, rolled):
    rig = _rig(tmp_path)
    before = sorted((tmp_path / "calibration").iterdir())
    p = orbitrig("calibrate", *args, "--sim", "--config", str(rig))
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert f"error: {option}: {rolled}: " in p.stderr
    assert ("slow roll" in p.stderr) == (args[0] != "delay"), p.stderr
    assert "exceeds the limit max_spin = 261.799 rad/s (2500.0 rpm)" in p.stderr
    assert f"the rig's [drives] in {rig}); nothing sent" in p.stderr
    assert "slow roll:" not in p.stderr and "drives stopped" not in p.stderr  # nothing turned
    assert sorted((tmp_path / "calibration").iterdir()) == before


@pytest.mark.parametrize("step", ["loads", "probes"])
def test_every_step_checks_its_slow_roll_against_the_configured_limit(tmp_path, step):
    rig = _rig(tmp_path, max_spin_rpm=250.0)  # the default slow roll, 300 rpm, is above it
    p = orbitrig("calibrate", step, "--sim", "--config", str(rig))
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert "error: --spin-rpm: slow roll at spin 300 rpm, orbit 300 rpm: " in p.stderr
    assert "exceeds the limit max_spin = 26.180 rad/s (250.0 rpm)" in p.stderr
    assert "slow roll:" not in p.stderr
