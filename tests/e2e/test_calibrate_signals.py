"""`orbitrig calibrate` ends on SIGTERM and SIGHUP as on Ctrl-C: both drives stopped first
(the session's emergency stop, confirmed at standstill), no record written, exit 3. Real
signals to a real subprocess on the simulator."""

from __future__ import annotations

import shutil
import signal
import time

import pytest

from support.rig_configs import patient_rig_config
from support.cli_helpers import orbitrig_started, reaped
from support.paths import ROOT

pytestmark = pytest.mark.timeout(120)


@pytest.mark.parametrize(
    "sig", [signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT], ids=["SIGTERM", "SIGHUP", "SIGQUIT"]
)  # SIGQUIT (Ctrl-\) as SIGTERM: no core dump with the drives turning
def test_a_signal_stops_the_drives_and_writes_no_record(tmp_path, sig):
    patient_rig_config(tmp_path)  # a link that holds with both cores busy
    shutil.copytree(ROOT / "config/calibration", tmp_path / "calibration")
    records = sorted(p.name for p in (tmp_path / "calibration").iterdir())
    config = str(tmp_path / "rig.toml")
    args = ("calibrate", "runout", "--sim", "--config", config, "--revolutions", "5000", "--speedup", "10")
    with reaped(orbitrig_started(*args)) as proc:
        lines = []
        for line in proc.stderr:  # the slow roll is held: the drives turn
            lines.append(line)
            if line.startswith("slow roll:"):
                break
        assert lines and lines[-1].startswith("slow roll: spin 100 rpm"), "".join(lines)
        time.sleep(0.5)
        proc.send_signal(sig)
        rest = proc.stderr.read()
        code = proc.wait(timeout=60)
    assert code == 3, rest
    assert "both drives stopped" in rest
    assert f"calibration stopped by {sig.name}: no record written" in rest
    assert "Traceback" not in rest
    assert sorted(p.name for p in (tmp_path / "calibration").iterdir()) == records
