"""`orbitrig calibrate runout` on the rig code path, a drive tripping or the drives' Modbus link lost
during the slow roll's acquisition: the step ends within seconds (not after the acquisition's
timeout, twice, blaming the A/D board), both drives stopped first, the error naming the drive and
its fault or the lost link, exit 1 (the step failed, docs/calibration.md), no record written, and
none of pymodbus' own log lines on the terminal.

Real parts: the simulator in its own process (`orbitrig sim`, speedup 10) behind a copy of the
lab's rig.toml; the test plays the operator and injects the fault through the simulator's control
API (a latched drive fault; the Modbus server made unresponsive)."""

from __future__ import annotations

import contextlib
import re
import time

import pytest

from support.calibrate_operator import Calibrate, Simulator, confirm_manual, wait

pytestmark = pytest.mark.timeout(300)
#: 500 revolutions at 100 rpm: 300 s of rig time, 30 s wall per block (the simulator's speed-up);
#: the acquisition's timeout, counted by the command in real time, is 3 x 300 s + its margin, about
#: 900 s wall: the fault is injected well within the block
RUNOUT_ARGS = ("runout", "--revolutions", "500")
ENDS_WITHIN_S = 20.0  # wall s from the fault to the command's end, with margin for a loaded machine
PYMODBUS = re.compile(r"pymodbus|No response received|Connection .* lost|send: 0x|recv: 0x|Processing: 0x", re.I)


#: the tests' lab link (tests/support/rig_configs.patient_rig_config: 1 s per request, lost after
#: 5 failed polls) made quicker for the link's loss, still twice the rig's 0.15 s for a loaded
#: machine: lost after 3 x (0.1 + 0.3) s; each stop not delivered (the step's, then the drives'
#: own on closing: each word tried twice, to each drive) takes some 3 s
QUICKER_LOSS = {"timeout_s = 1.0": "timeout_s = 0.3", "link_loss_polls = 5": "link_loss_polls = 3"}
QUICKER_LOSS["comm_loss_timeout_s = 10.0"] = "comm_loss_timeout_s = 3.0"


@contextlib.contextmanager
def rolling(folder, edits: dict[str, str] | None = None):
    """(simulator, the runout step at the slow roll, the records' folder, their names before) once
    the acquisition runs; `edits`: lines of the lab's rig.toml replaced (old: new)."""
    sim = Simulator()
    step = None
    try:
        config = sim.rig_config(folder)
        text = config.read_text()
        for old, new in (edits or {}).items():
            assert old in text, old
            text = text.replace(old, new)
        config.write_text(text)
        records = config.parent / "calibration"
        before = sorted(p.name for p in records.iterdir())
        step = Calibrate(config, RUNOUT_ARGS)
        confirm_manual(sim, step)
        wait(lambda: "slow roll: spin 100 rpm" in step.stderr() or step.proc.poll() is not None, 90, step.stderr)
        assert step.proc.poll() is None, step.stderr()
        assert all(abs(w) > 90.0 for w in sim.rpm()), sim.rpm()
        time.sleep(1.0)  # the hold (0.2 s wall) over: the block under way
        yield sim, step, records, before
    finally:
        if step is not None:
            step.close()
        sim.close()


def _ended(sim: Simulator, step: Calibrate) -> tuple[int, float, str]:
    """(exit status, wall s from now to the end, standard error)."""
    t0 = time.monotonic()
    code = step.ended(sim, timeout=60.0)  # far short of the acquisition's timeout (about 900 s wall)
    return code, time.monotonic() - t0, step.stderr()


def test_a_spin_drive_trip_during_the_slow_roll_ends_the_step_at_once(tmp_path):
    with rolling(tmp_path) as (sim, step, records, before):
        sim.call("inject", fault="drive_trip", drive=1, code=2310)
        code, took, err = _ended(sim, step)
        assert took < ENDS_WITHIN_S, (took, err)
        assert code == 1, err
        (line,) = [ln for ln in err.splitlines() if ln.startswith("orbitrig calibrate runout: error: ")]
        assert "spin drive" in line and "fault 2310" in line, line
        assert "no block at the slow roll" not in err and "acquisition failed" not in err, err
        assert err.index("both drives stopped") < err.index(line), err
        assert sim.rpm() == (0.0, 0.0)
        assert not PYMODBUS.search(err) and "Traceback" not in err, err
        assert sorted(p.name for p in records.iterdir()) == before


def test_a_lost_drive_link_during_the_slow_roll_ends_the_step_at_once(tmp_path):
    with rolling(tmp_path, QUICKER_LOSS) as (sim, step, records, before):
        sim.call("inject", fault="modbus_timeout", on=True)  # the drives answer no more
        code, took, err = _ended(sim, step)
        assert took < ENDS_WITHIN_S, (took, err)
        assert code == 1, err
        (line,) = [ln for ln in err.splitlines() if ln.startswith("orbitrig calibrate runout: error: ")]
        assert "link to the drives lost" in line and re.search(r"\b(spin|orbit) drive\b", line), line
        assert "drives not confirmed stopped" in line, line  # nobody can say they stopped: the link is gone
        assert "no block at the slow roll" not in err and "acquisition failed" not in err, err
        # their comm-loss watchdog (COMM_LOSS_TIMEOUT 3 s) ramps them down
        wait(lambda: sim.rpm() == (0.0, 0.0), 30, lambda: f"drives at {sim.rpm()} rpm")
        assert not PYMODBUS.search(err) and "Traceback" not in err, err
        assert sorted(p.name for p in records.iterdir()) == before
