"""`orbitrig calibrate`: calibration steps on the rig or the simulator, and the records' history.

  orbitrig calibrate list                  every record, oldest first; * marks the active one
  orbitrig calibrate show [NAME]           one record (default: the active one)
  orbitrig calibrate loads [--sim]         known static loads -> each load measuring system's gain matrix
  orbitrig calibrate runout [--sim]        slow roll without orbit -> each probe's runout at 1x, 2x spin
  orbitrig calibrate delay [--sim]         phase reference -> each channel's phase and delay behind the probes' mean
  orbitrig calibrate probes [--sim]        known displacement steps -> each probe's gain and linearity

A step writes a new record into the records' folder beside the rig configuration
(docs/calibration.md) and makes it the active one (``--no-activate``: it only writes it).
Exit status: 0 done, 1 the step failed (among them: a drive tripped, the link to the drives was
lost or an interlock failed (the lubricant supply, the CAN sensor node: [interlocks], as a sweep's)
during the step, the error naming the drive and its fault, the lost link or the interlock; drives not
confirmed stopped) or its output could not be written (a full disk: the record measured is written
and activated all the same, the error naming it; a reader gone away is no failure), 2 bad configuration or usage or a rig that does not answer before the step (each
transport named), 3 stopped (Ctrl-C, SIGTERM, SIGHUP, SIGQUIT: both drives are stopped and
confirmed at standstill first; a signal during the final ramp makes it an emergency stop;
every further signal cancels again, so nothing is waited for but that stop). On the rig the operator is first asked for the slow roll's manual settings
(orbit radius and static eccentricity zero, the pressures), both drives at standstill, and the
spindles start only after the Enter; the loads, the step or the reference are asked off only
with both drives at standstill; after a step that did not complete only told. A rig.toml that
cannot be written keeps its active record (exit 2, the new record written but not activated).
"""

from __future__ import annotations

import getpass
from pathlib import Path
from typing import Optional

import typer

from orbitrig.cli import calibrate_records as records
from orbitrig.cli.help_text import command_group
from orbitrig.cli.config_help import RIG_CONFIG_HELP
from orbitrig.cli.sim_options import DEFAULT_SPEEDUP
from orbitrig.cli.sweep_options import SimConfig, Speedup, operator_given
from rigunits import MICROMETRE, UM

_CONFIG = typer.Option(None, "--config", help=RIG_CONFIG_HELP)
_OPERATOR = typer.Option(None, "--operator", help="who calibrates (default: the login name)", callback=operator_given)
_RECESS = typer.Option(0.4826, "--recess-pressure-mpa", min=0.0, help="recess pressure while the spindles turn (MPa)")
_RATIO = typer.Option(0.25, "--pressure-ratio", min=0.01, max=0.99, help="pressure ratio while the spindles turn")
_ACTIVATE = typer.Option(True, "--activate/--no-activate", help="make the new record the rig's active one")
_REFERENCE_U = typer.Option(
    None,
    "--reference-u-pct",
    min=0.0,
    max=50.0,
    help="its certificate's relative standard uncertainty (%); required on the rig",
)


def _spin(rpm: float):
    """--spin-rpm: the slow roll speed (rpm), default ``rpm``."""
    return typer.Option(rpm, "--spin-rpm", min=1.0, help="slow roll speed (rpm)")


def _revolutions(count: int, per: str):
    """--revolutions: the revolutions averaged (``per``: what for, e.g. " per step"), default ``count``."""
    return typer.Option(count, "--revolutions", min=2, max=10_000, help=f"revolutions averaged{per}")


def register(app: typer.Typer) -> None:
    cal = command_group(
        "Calibrate the load measuring systems and probes; the calibration records.", no_args_is_help=True
    )
    app.add_typer(cal, name="calibrate")
    for name, command in (
        ("list", list_),
        ("show", show),
        ("loads", loads),
        ("runout", runout),
        ("delay", delay),
        ("probes", probes),
    ):
        cal.command(name)(command)


def list_(config: Optional[Path] = _CONFIG) -> None:
    """Every calibration record, oldest first (* the active one): date, step, operator, reference."""
    _guarded(lambda: records.list_records(config))


def _record_name(name: Optional[str]) -> Optional[str]:
    """NAME of `calibrate show`: a plain record name (orbitrig.config.RECORD_NAME), else a usage
    error (exit 2) naming the argument and the rule: no path (``../rig``) reaches a file."""
    from orbitrig.config import record_name_problem

    problem = None if name is None else record_name_problem(name)
    if problem is not None:
        raise typer.BadParameter(problem)
    return name


def show(
    name: Optional[str] = typer.Argument(
        None,
        metavar="NAME",
        help="record name, e.g. 2026-11-26T214904Z-loads (default: the active record)",
        callback=_record_name,
    ),
    config: Optional[Path] = _CONFIG,
) -> None:
    """Print one calibration record (its TOML text) and its SHA-256."""
    _guarded(lambda: records.show_record(name, config))


def loads(
    sim: bool = typer.Option(False, "--sim", help="on the built-in simulator (it applies the loads)"),
    load_n: float = typer.Option(500.0, "--load-n", min=1.0, help="magnitude of each static load (N)"),
    reference_id: Optional[str] = typer.Option(
        None, "--reference-id", help="the reference's id (dead-weight set, load cell); required on the rig"
    ),
    reference_u_pct: Optional[float] = _REFERENCE_U,
    config: Optional[Path] = _CONFIG,
    operator: Optional[str] = _OPERATOR,
    spin_rpm: float = _spin(300.0),
    revolutions: int = _revolutions(50, " per reading"),
    recess_pressure_mpa: float = _RECESS,
    pressure_ratio: float = _RATIO,
    activate: bool = _ACTIVATE,
    sim_config: SimConfig = None,
    speedup: Speedup = DEFAULT_SPEEDUP,
) -> None:
    """Static loads -> each load measuring system's 2 x 2 gain matrix.

    Known static loads in x and y (the default set: none, +-x, +-y, two diagonals), read by both
    load measuring systems; least squares gives each system's 2 x 2 gain matrix (cross terms
    included) and its uncertainty (residuals and the reference's). The sweep applies them to the forces.
    On the rig the operator applies each load and confirms it."""
    opts = _options(operator, spin_rpm, revolutions, recess_pressure_mpa, pressure_ratio, sim, sim_config, speedup)
    _guarded(lambda: records.loads(config, opts, load_n, reference_id, reference_u_pct, activate))


def runout(
    sim: bool = typer.Option(False, "--sim", help="on the built-in simulator"),
    config: Optional[Path] = _CONFIG,
    operator: Optional[str] = _OPERATOR,
    spin_rpm: float = _spin(100.0),
    revolutions: int = _revolutions(100, ""),
    recess_pressure_mpa: float = _RECESS,
    pressure_ratio: float = _RATIO,
    activate: bool = _ACTIVATE,
    sim_config: SimConfig = None,
    speedup: Speedup = DEFAULT_SPEEDUP,
) -> None:
    """Slow roll without orbit -> each probe's runout at 1x and 2x spin.

    Slow roll at low spin without orbit (orbit radius zero, the orbit spindle at the spin speed):
    each probe's runout phasors at 1x and 2x spin, stored in a new record."""
    opts = _options(operator, spin_rpm, revolutions, recess_pressure_mpa, pressure_ratio, sim, sim_config, speedup)
    _guarded(lambda: records.runout(config, opts, activate))


def delay(
    sim: bool = typer.Option(False, "--sim", help="on the built-in simulator (it connects the reference)"),
    speeds_rpm: str = typer.Option(
        "300,600,900,1200,1500",
        "--speeds-rpm",
        help="orbit spindle speeds (rpm, the spin at 1/0.7 times), comma separated",
    ),
    reference_n: float = typer.Option(1000.0, "--reference-n", min=0.001, help="reference on the force channels (N)"),
    reference_um: float = typer.Option(
        20.0, "--reference-um", min=0.001, help=f"reference on the probes ({MICROMETRE})"
    ),
    config: Optional[Path] = _CONFIG,
    operator: Optional[str] = _OPERATOR,
    revolutions: int = _revolutions(100, " per speed"),
    recess_pressure_mpa: float = _RECESS,
    pressure_ratio: float = _RATIO,
    activate: bool = _ACTIVATE,
    sim_config: SimConfig = None,
    speedup: Speedup = DEFAULT_SPEEDUP,
) -> None:
    """Phase reference -> each channel's phase and time delay behind the probes' mean.

    A reference signal locked to the orbit spindle on every channel's input, read at several
    speeds without orbit (reference runs, up to 2143 rpm spin: no slow roll): each force channel's lag behind the four probes' mean as a constant phase
    plus a time delay (a 0.3 degree lag moves D by kilograms), and each probe's (a warning when
    implausibly large). The sweep takes the lags out of the forces and the probes; each channel's
    uncertainty keeps its fit's."""
    speeds = _speeds(speeds_rpm)
    opts = _options(operator, speeds[0], revolutions, recess_pressure_mpa, pressure_ratio, sim, sim_config, speedup)
    _guarded(lambda: records.delay(config, opts, speeds, (reference_n, reference_um * UM), activate))


def probes(
    sim: bool = typer.Option(False, "--sim", help="on the built-in simulator (it steps the journal)"),
    span_um: float = typer.Option(
        40.0, "--span-um", min=0.1, help=f"span of the steps, centred on zero ({MICROMETRE})"
    ),
    steps: int = typer.Option(5, "--steps", min=3, max=101, help="number of steps over the span"),
    reference_id: Optional[str] = typer.Option(None, "--reference-id", help="the micrometer's id; required on the rig"),
    reference_u_pct: Optional[float] = _REFERENCE_U,
    config: Optional[Path] = _CONFIG,
    operator: Optional[str] = _OPERATOR,
    spin_rpm: float = _spin(300.0),
    revolutions: int = _revolutions(50, " per step"),
    recess_pressure_mpa: float = _RECESS,
    pressure_ratio: float = _RATIO,
    activate: bool = _ACTIVATE,
    sim_config: SimConfig = None,
    speedup: Speedup = DEFAULT_SPEEDUP,
) -> None:
    """Displacement steps -> each probe's gain and linearity.

    Known static steps of the journal (a micrometer), first along x, then along y, read by the probes
    of that axis: a line per probe gives its gain (the sweep applies it) with its uncertainty, and
    its linearity (largest deviation from the line, percent of the span)."""
    opts = _options(operator, spin_rpm, revolutions, recess_pressure_mpa, pressure_ratio, sim, sim_config, speedup)
    _guarded(lambda: records.probes(config, opts, span_um, steps, reference_id, reference_u_pct, activate))


def _speeds(text: str) -> list[float]:
    try:
        speeds = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise typer.BadParameter(f"not a list of numbers: {text!r}", param_hint="--speeds-rpm") from None
    if len(set(speeds)) < 3 or any(not 0 < v < 1e5 for v in speeds):
        raise typer.BadParameter("give 3 or more distinct positive speeds (rpm)", param_hint="--speeds-rpm")
    return speeds


def _options(operator, spin_rpm, revolutions, recess_pressure_mpa, pressure_ratio, sim, sim_config, speedup):
    from orbitrig.cli.calibrate_steps import StepOptions
    from orbitrig.cli.scenarios import needs_sim

    needs_sim(sim, sim_config)
    who = operator or getpass.getuser()
    return StepOptions(who, spin_rpm, revolutions, recess_pressure_mpa, pressure_ratio, sim, sim_config, speedup)


def _guarded(fn) -> None:
    """Run a sub-command: exit 2 on a configuration error, a speed beyond the drive limits or a
    rig that does not answer (nothing sent), 1 on a failed step (a drive tripped, the link to
    the drives lost or an interlock failed during it, drives not confirmed stopped among them) or output that cannot be
    written (a full disk), 3 on Ctrl-C, SIGTERM, SIGHUP or SIGQUIT (both drives confirmed at
    standstill first, or, while the rig still opened, both took the stop word: the session's note
    before says which, and the last line says nothing more of the drives). pymodbus' own log
    records never reach the terminal (debug logging only)."""
    from orbitrig.cli.calibrate_steps import CalibrationOptionError
    from orbitrig.run.rig_answers import RigUnreachable
    from orbitrig.cli.failure import fail
    from orbitrig.cli.signals import Interrupted
    from orbitrig.cli.terminal import OutputError, say
    from orbitrig.errors import ConfigError, OrbitrigError
    from orbitrig.run.modbus_log import keep_pymodbus_off_the_terminal

    keep_pymodbus_off_the_terminal()
    try:
        fn()
    except (ConfigError, CalibrationOptionError, RigUnreachable) as err:
        fail(str(err), 2)
    except (OrbitrigError, OutputError) as err:
        fail(str(err), 1)
    except (KeyboardInterrupt, Interrupted) as err:
        what = str(err) if isinstance(err, Interrupted) else "Ctrl-C"
        say(f"calibration stopped by {what}: no record written", err=True)  # the drives: the note before
        raise typer.Exit(3) from None
