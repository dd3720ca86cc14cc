"""`orbitrig calibrate loads` on the rig, the operator at its terminal: both drives are brought to
a confirmed standstill before the operator is asked to remove the loads, on the normal end as
on every other way out; after a step that did not complete (Ctrl-C, SIGTERM, several signals, a
failed acquisition) the command does not wait for an Enter with the drives turning: it stops
them, says what is left on the rig and ends (exit 3 interrupted, 1 failed), no record written.

Real parts: the simulator in its own process (`orbitrig sim`) behind a copy of the lab's
rig.toml, so the command sees a rig (no --sim) and prompts; the test plays the operator's hands
through the simulator's control API (`apply_load`), answers on the command's standard input (a
pipe kept open: nobody answers unless the test writes), reads the drives' speeds from the
simulator and sends real signals to the command's process."""

from __future__ import annotations

import re
import signal

import pytest
from pydantic import ValidationError

from orbitrig.config.calibration import ChannelUncertainty
from orbitrig.run.calibration import unrecordable
from support.calibrate_operator import Calibrate, Simulator, confirm_manual, wait

pytestmark = pytest.mark.timeout(300)
LOAD = re.compile(r"fx = ([+-][\d.]+) N, fy = ([+-][\d.]+) N")
LOADS = 7  # none, +-x, +-y, two diagonals (reduction.calibration.static_loads)


@pytest.fixture
def rig(tmp_path):
    """(simulator, rig.toml reaching it, the records' folder, a `calibrate()` starting the command)."""
    sim = Simulator()
    started: list[Calibrate] = []
    try:
        config = sim.rig_config(tmp_path)

        def calibrate() -> Calibrate:
            started.append(Calibrate(config))
            return started[-1]

        yield sim, config.parent / "calibration", calibrate
    finally:
        for c in started:
            c.close()
        sim.close()


def _apply(sim: Simulator, prompt: str) -> None:
    """The operator's hands: the load a prompt asks for, on the simulator's journal."""
    m = LOAD.search(prompt)
    fx, fy = (float(m.group(1)), float(m.group(2))) if m else (0.0, 0.0)
    assert m or "remove every calibration load" in prompt, prompt
    sim.call("apply_load", fx=fx, fy=fy)


def _turning(sim: Simulator) -> bool:
    return all(abs(w) > 250.0 for w in sim.rpm())  # the slow roll: 300 rpm


def test_the_loads_are_removed_only_once_both_drives_are_at_standstill(rig):
    sim, records, calibrate = rig
    before = sorted(p.name for p in records.iterdir())
    step = calibrate()
    confirm_manual(sim, step)  # prompt 1: before the slow roll starts both spindles
    for n in range(2, LOADS + 2):
        prompt = step.wait_prompt(n)
        assert _turning(sim), (n, sim.rpm())  # the loads are read at the slow roll
        assert prompt.startswith("the drives are turning: spin 300 rpm, orbit 300 rpm: "), prompt
        _apply(sim, prompt)
        step.enter()
    removal = step.wait_prompt(LOADS + 2)
    assert sim.rpm() == (0.0, 0.0), f"asked to remove the loads with the drives at {sim.rpm()} rpm: {removal!r}"
    assert removal == "both drives at standstill: remove every calibration load,", removal
    wait(lambda: "both drives stopped" in step.stderr(), 30, step.stderr)  # said before the prompt (another pipe)
    assert step.stderr().rstrip().endswith("both drives stopped"), step.stderr()
    sim.call("apply_load", fx=0.0, fy=0.0)
    step.enter()
    assert step.ended(sim) == 0, step.stderr()
    assert sim.rpm() == (0.0, 0.0)
    assert len(step.prompts()) == LOADS + 2
    (new,) = sorted(set(p.name for p in records.iterdir()) - set(before))
    assert new.endswith("-loads.toml"), new
    assert "Traceback" not in step.stderr()


@pytest.mark.parametrize(
    "signals",
    [(signal.SIGINT,), (signal.SIGTERM,), (signal.SIGINT, signal.SIGINT, signal.SIGTERM)],
    ids=["ctrl-c", "sigterm", "ctrl-c-twice-and-sigterm"],
)
def test_a_signal_at_a_prompt_stops_the_drives_and_ends_without_asking_again(rig, signals):
    sim, records, calibrate = rig
    before = sorted(p.name for p in records.iterdir())
    step = calibrate()
    confirm_manual(sim, step)
    _apply(sim, step.wait_prompt(2))
    step.enter()
    prompt = step.wait_prompt(3)  # +x: the drives turn, the command waits for the operator
    assert _turning(sim) and "apply the static load fx = +500.0 N" in prompt, (sim.rpm(), prompt)
    for sig in signals:
        step.proc.send_signal(sig)
    code = step.ended(sim)
    err = step.stderr()
    assert code == 3, err
    assert sim.rpm() == (0.0, 0.0)
    assert len(step.prompts()) == 3, step.stdout()  # nobody asked anything more
    told = "both drives at standstill: remove every calibration load (the step did not complete)"
    # signals sent together may reach the command in another order (each thread can take one)
    first = {"Ctrl-C" if s == signal.SIGINT else s.name for s in signals}
    (end,) = re.findall(r"calibration stopped by (.+): no record written", err)
    assert end in first, err
    assert err.index("both drives stopped") < err.index(told) < err.index("calibration stopped by"), err
    assert "Traceback" not in err
    assert sorted(p.name for p in records.iterdir()) == before


def test_a_failed_acquisition_stops_the_drives_before_anything_is_asked(rig):
    sim, records, calibrate = rig
    before = sorted(p.name for p in records.iterdir())
    step = calibrate()
    confirm_manual(sim, step)
    _apply(sim, step.wait_prompt(2))
    step.enter()
    prompt = step.wait_prompt(3)
    assert _turning(sim), sim.rpm()
    sim.call("inject", fault="stall_clock")  # the board's clock frozen: no block at the slow roll
    _apply(sim, prompt)
    step.enter()
    code = step.ended(sim)
    err = step.stderr()
    assert code == 1, err
    assert sim.rpm() == (0.0, 0.0)
    assert len(step.prompts()) == 3, step.stdout()
    told = "both drives at standstill: remove every calibration load (the step did not complete)"
    assert err.index("acquisition failed") < err.index("both drives stopped") < err.index(told), err
    assert "error: no block at the slow roll" in err and "Traceback" not in err
    assert sorted(p.name for p in records.iterdir()) == before


def test_readings_that_do_not_follow_the_loads_fail_the_step_saying_so(rig):
    """The operator confirms every prompt but applies no load: the gain matrices fitted to
    readings of nothing have uncertainties no record can hold, so the step fails (exit 1), says
    why, writes no record, and prints no traceback."""
    sim, records, calibrate = rig
    before = sorted(p.name for p in records.iterdir())
    step = calibrate()
    confirm_manual(sim, step)
    for n in range(2, LOADS + 2):
        step.wait_prompt(n)
        step.enter()  # the loads asked for are never applied
    step.wait_prompt(LOADS + 2)  # both drives at standstill: remove every calibration load
    step.enter()
    code = step.ended(sim)
    err = step.stderr()
    assert code == 1, err
    assert "error: the fitted gain matrices cannot be recorded" in err and "were the loads applied as asked?" in err
    assert "gain_pct = " in err and "Traceback" not in err and "errors.pydantic.dev" not in err
    assert sim.rpm() == (0.0, 0.0)
    assert sorted(p.name for p in records.iterdir()) == before


def test_values_no_record_holds_are_said_field_by_field_on_one_line():
    with pytest.raises(ValidationError) as caught:
        ChannelUncertainty(gain_pct=334.4453, phase_deg=-1.0)
    err = unrecordable("the fitted gain matrices", caught.value, "were the loads applied as asked?")
    assert str(err) == (
        "the fitted gain matrices cannot be recorded (gain_pct = 334.4: input should be less than or equal to 50; "
        "phase_deg = -1: input should be greater than or equal to 0); were the loads applied as asked? "
        "no record written"
    )
    assert str(unrecordable("the fitted lags", caught.value)).endswith("); no record written")
