"""A calibration step at its slow roll asking its operator for a load, as `orbitrig calibrate` asks
on the rig: the step run by orbitrig.cli.signals.run_until_signal (its signals, Ctrl-Z refused),
the operator's prompt by orbitrig.cli.calibrate_steps.OperatorLoads on this process's terminal, the
drives those of the simulator in this process. Run as a script (``LIMIT_S``: the rig's [interlocks]
unanswered_pause_s), as a background job of a pseudo-terminal (support.job_control). It says
``confirmed at spin N rpm`` once Enter was pressed, or the step's failure, then which threads wrote
the prompt's lines (`prompt_writers`); exit 0 or 1."""

from __future__ import annotations

import sys
import threading

SPEEDUP = 20  # the simulator's time / wall time


def prompt_writers() -> set[str]:
    """The names of the threads that write the prompt's lines (the prompt, the words of a background
    job's read, the prompt asked again: orbitrig.cli.calibrate_prompt's `say` and `say_aside`), filled
    in as they write; the writing itself unchanged."""
    from orbitrig.cli import calibrate_prompt

    names: set[str] = set()

    def recorded(say):
        def writing(*args, **kwargs):
            names.add(threading.current_thread().name)
            return say(*args, **kwargs)

        return writing

    calibrate_prompt.say = recorded(calibrate_prompt.say)
    calibrate_prompt.say_aside = recorded(calibrate_prompt.say_aside)
    return names


def main(limit: float) -> int:
    from orbitrig.cli.calibrate_steps import OperatorLoads
    from orbitrig.cli.signals import run_until_signal
    from orbitrig.cli.simulated_rig import simulated_access
    from orbitrig.cli.terminal import say_aside
    from orbitrig.config import MPA, RPM, load_rig
    from orbitrig.run.calibration import CalibrationSession, SlowRoll
    from orbitrig.run.calibration_checks import CalibrationFailed
    from sim.rig import SimRig

    rig = load_rig()
    rig = rig.model_copy(update={"interlocks": rig.interlocks.model_copy(update={"unanswered_pause_s": limit})})
    roll = SlowRoll(spin=600 * RPM, recess_pressure=0.4826 * MPA, pressure_ratio=0.25, revolutions=5)

    async def step() -> float:
        async with SimRig(speedup=SPEEDUP, adc_pty=False) as sim_rig:
            session, hands = CalibrationSession(rig, simulated_access(sim_rig), say_aside), OperatorLoads()
            hands.watch(session)
            async with session:
                await session.roll(roll)
                await session.watched(lambda: hands.apply_load(500.0, 0.0))
                return sim_rig.speeds[0] / RPM

    writers = prompt_writers()
    try:
        spin = run_until_signal(step, "calibrate")
    except CalibrationFailed as err:
        say_aside(f"failed: {err}")
        return 1
    finally:
        say_aside(f"prompt lines written on: {', '.join(sorted(writers))}")
    say_aside(f"confirmed at spin {spin:.0f} rpm")
    return 0


if __name__ == "__main__":
    sys.exit(main(float(sys.argv[1])))
