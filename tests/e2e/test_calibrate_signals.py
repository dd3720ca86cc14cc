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
    code, rest, unchanged = _calibration_sent(tmp_path, sig)
    assert code == 3, rest
    assert "both drives stopped" in rest
    assert f"calibration stopped by {sig.name}: no record written" in rest
    assert "Traceback" not in rest
    assert unchanged


def test_ctrl_z_does_not_suspend_a_slow_roll(tmp_path):
    """Ctrl-Z (SIGTSTP) while the slow roll holds the drives is refused with a line (before, the
    calibration was suspended and the drives turned unwatched until their comm-loss watchdog
    tripped them); SIGTERM then stops them as ever."""
    code, rest, unchanged = _calibration_sent(tmp_path, signal.SIGTSTP, signal.SIGCONT, signal.SIGTERM)
    assert code == 3, rest
    assert "Ctrl-Z ignored: orbitrig calibrate does not suspend while it commands the drives" in rest
    assert "both drives stopped" in rest and "calibration stopped by SIGTERM: no record written" in rest
    assert unchanged


def _calibration_sent(tmp_path, *signals: signal.Signals) -> tuple[int, str, bool]:
    """`calibrate runout --sim` sent `signals` (0.5 s apart) during its slow roll: (exit status,
    standard error from the first signal on, whether the records folder is unchanged)."""
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
        for sig in signals:
            time.sleep(0.5)
            proc.send_signal(sig)
        rest = proc.stderr.read()
        code = proc.wait(timeout=60)
    return code, rest, sorted(p.name for p in (tmp_path / "calibration").iterdir()) == records
