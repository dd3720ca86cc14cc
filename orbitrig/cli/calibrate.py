"""`orbitrig calibrate`: calibration steps on the rig or the simulator, and the records' history.

  orbitrig calibrate list                  every record, oldest first; * marks the active one
  orbitrig calibrate show [NAME]           one record (default: the active one)
  orbitrig calibrate loads [--sim]         known static loads -> each load measuring system's gain matrix
  orbitrig calibrate runout [--sim]        slow roll without orbit -> each probe's runout at 1x, 2x spin
  orbitrig calibrate delay [--sim]         phase reference -> each force channel's phase and delay behind the probes
  orbitrig calibrate probes [--sim]        known displacement steps -> each probe's gain and linearity

A step writes a new record into the records' folder beside the rig configuration
(docs/calibration.md) and makes it the active one (``--no-activate``: it only writes it).
Exit status: 0 done, 1 the step failed (among them: a drive tripped, the link to the drives was
lost or an interlock failed (the lubricant supply, the CAN sensor node: [interlocks], as a sweep's)
during the step, the error naming the drive and its fault, the lost link or the interlock; drives not
confirmed stopped) or its output could not be written (a full disk; a reader gone away is no
failure), 2 bad configuration or usage or a rig that does not answer before the step (each
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
from functools import partial
from pathlib import Path
from typing import Optional

import typer

from orbitrig.cli.help_text import command_group
from orbitrig.cli.config_help import RIG_CONFIG_HELP
from orbitrig.cli.signals import run_until_signal

DEFAULT_SPEEDUP = 40.0  # as orbitrig.cli.simulated_rig.DEFAULT_SPEEDUP
_CONFIG = typer.Option(None, "--config", help=RIG_CONFIG_HELP)
_OPERATOR = typer.Option(None, "--operator", help="who calibrates (default: the login name)")
_RECESS = typer.Option(0.4826, "--recess-pressure-mpa", min=0.0, help="recess pressure during the slow roll (MPa)")
_RATIO = typer.Option(0.25, "--pressure-ratio", min=0.01, max=0.99, help="pressure ratio during the slow roll")
_ACTIVATE = typer.Option(True, "--activate/--no-activate", help="make the new record the rig's active one")
_SIM_CONFIG = typer.Option(
    None,
    "--sim-config",
    help="simulator scenario: a TOML file or a shipped name (paper, clean, compressible); --sim only",
)
_SPEEDUP = typer.Option(DEFAULT_SPEEDUP, "--speedup", min=0.01, help="simulator time / wall time (--sim only)")
_REF_U = "its certificate's relative standard uncertainty (%); required on the rig"


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
    _guarded(lambda: _list(config))


def show(
    name: Optional[str] = typer.Argument(None, help="record name (default: the active record)"),
    config: Optional[Path] = _CONFIG,
) -> None:
    """Print one calibration record (its TOML text) and its SHA-256."""
    _guarded(lambda: _show(name, config))


def loads(
    sim: bool = typer.Option(False, "--sim", help="on the built-in simulator (it applies the loads)"),
    load_n: float = typer.Option(500.0, "--load-n", min=1.0, help="magnitude of each static load (N)"),
    reference_id: Optional[str] = typer.Option(
        None, "--reference-id", help="the reference's id (dead-weight set, load cell); required on the rig"
    ),
    reference_u_pct: Optional[float] = typer.Option(None, "--reference-u-pct", min=0.0, max=50.0, help=_REF_U),
    config: Optional[Path] = _CONFIG,
    operator: Optional[str] = _OPERATOR,
    spin_rpm: float = typer.Option(300.0, "--spin-rpm", min=1.0, help="slow roll speed (rpm)"),
    revolutions: int = typer.Option(50, "--revolutions", min=2, max=10_000, help="revolutions averaged per reading"),
    recess_pressure_mpa: float = _RECESS,
    pressure_ratio: float = _RATIO,
    activate: bool = _ACTIVATE,
    sim_config: Optional[Path] = _SIM_CONFIG,
    speedup: float = _SPEEDUP,
) -> None:
    """Static loads -> each load measuring system's 2 x 2 gain matrix.

    Known static loads in x and y (the default set: none, +-x, +-y, two diagonals), read by both
    load measuring systems; least squares gives each system's 2 x 2 gain matrix (cross terms
    included) and its uncertainty (residuals and the reference's). The sweep applies them to the forces.
    On the rig the operator applies each load and confirms it."""
    opts = _options(operator, spin_rpm, revolutions, recess_pressure_mpa, pressure_ratio, sim, sim_config, speedup)
    _guarded(lambda: _loads(config, opts, load_n, reference_id, reference_u_pct, activate))


def runout(
    sim: bool = typer.Option(False, "--sim", help="on the built-in simulator"),
    config: Optional[Path] = _CONFIG,
    operator: Optional[str] = _OPERATOR,
    spin_rpm: float = typer.Option(100.0, "--spin-rpm", min=1.0, help="slow roll speed (rpm)"),
    revolutions: int = typer.Option(100, "--revolutions", min=2, max=10_000, help="revolutions averaged"),
    recess_pressure_mpa: float = _RECESS,
    pressure_ratio: float = _RATIO,
    activate: bool = _ACTIVATE,
    sim_config: Optional[Path] = _SIM_CONFIG,
    speedup: float = _SPEEDUP,
) -> None:
    """Slow roll without orbit -> each probe's runout at 1x and 2x spin.

    Slow roll at low spin without orbit (orbit radius zero, the orbit spindle at the spin speed):
    each probe's runout phasors at 1x and 2x spin, stored in a new record."""
    opts = _options(operator, spin_rpm, revolutions, recess_pressure_mpa, pressure_ratio, sim, sim_config, speedup)
    _guarded(lambda: _runout(config, opts, activate))


def delay(
    sim: bool = typer.Option(False, "--sim", help="on the built-in simulator (it connects the reference)"),
    speeds_rpm: str = typer.Option(
        "300,600,900,1200,1500",
        "--speeds-rpm",
        help="orbit spindle speeds (rpm, the spin at 1/0.7 times), comma separated",
    ),
    reference_n: float = typer.Option(1000.0, "--reference-n", min=0.001, help="reference on the force channels (N)"),
    reference_um: float = typer.Option(20.0, "--reference-um", min=0.001, help="reference on the probes (um)"),
    config: Optional[Path] = _CONFIG,
    operator: Optional[str] = _OPERATOR,
    revolutions: int = typer.Option(100, "--revolutions", min=2, max=10_000, help="revolutions averaged per speed"),
    recess_pressure_mpa: float = _RECESS,
    pressure_ratio: float = _RATIO,
    activate: bool = _ACTIVATE,
    sim_config: Optional[Path] = _SIM_CONFIG,
    speedup: float = _SPEEDUP,
) -> None:
    """Phase reference -> each force channel's phase and time delay behind the probes.

    A reference signal locked to the orbit spindle on every channel's input, read at several
    slow-roll speeds: each force channel's lag behind the probes as a constant phase plus a time
    delay (a 0.3 degree lag moves D by kilograms). The sweep takes the lags out of the forces."""
    speeds = _speeds(speeds_rpm)
    opts = _options(operator, speeds[0], revolutions, recess_pressure_mpa, pressure_ratio, sim, sim_config, speedup)
    _guarded(lambda: _delay(config, opts, speeds, (reference_n, reference_um * 1e-6), activate))


def probes(
    sim: bool = typer.Option(False, "--sim", help="on the built-in simulator (it steps the journal)"),
    span_um: float = typer.Option(40.0, "--span-um", min=0.1, help="span of the steps, centred on zero (um)"),
    steps: int = typer.Option(5, "--steps", min=3, max=101, help="number of steps over the span"),
    reference_id: Optional[str] = typer.Option(None, "--reference-id", help="the micrometer's id; required on the rig"),
    reference_u_pct: Optional[float] = typer.Option(None, "--reference-u-pct", min=0.0, max=50.0, help=_REF_U),
    config: Optional[Path] = _CONFIG,
    operator: Optional[str] = _OPERATOR,
    spin_rpm: float = typer.Option(300.0, "--spin-rpm", min=1.0, help="slow roll speed (rpm)"),
    revolutions: int = typer.Option(50, "--revolutions", min=2, max=10_000, help="revolutions averaged per step"),
    recess_pressure_mpa: float = _RECESS,
    pressure_ratio: float = _RATIO,
    activate: bool = _ACTIVATE,
    sim_config: Optional[Path] = _SIM_CONFIG,
    speedup: float = _SPEEDUP,
) -> None:
    """Displacement steps -> each probe's gain and linearity.

    Known static steps of the journal (a micrometer), first along x, then along y, read by the probes
    of that axis: a line per probe gives its gain (the sweep applies it) with its uncertainty, and
    its linearity (largest deviation from the line, percent of the span)."""
    opts = _options(operator, spin_rpm, revolutions, recess_pressure_mpa, pressure_ratio, sim, sim_config, speedup)
    _guarded(lambda: _probes(config, opts, span_um, steps, reference_id, reference_u_pct, activate))


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

    if sim_config is not None and not sim:
        raise typer.BadParameter("--sim-config needs --sim", param_hint="--sim-config")
    who = operator or getpass.getuser()
    return StepOptions(who, spin_rpm, revolutions, recess_pressure_mpa, pressure_ratio, sim, sim_config, speedup)


def _guarded(fn) -> None:
    """Run a sub-command: exit 2 on a configuration error, a speed beyond the drive limits or a
    rig that does not answer (nothing sent), 1 on a failed step (a drive tripped, the link to
    the drives lost or an interlock failed during it, drives not confirmed stopped among them) or output that cannot be
    written (a full disk), 3 on Ctrl-C, SIGTERM, SIGHUP or SIGQUIT (both drives confirmed at
    standstill first). pymodbus' own log records never reach the terminal (debug logging only)."""
    from orbitrig.cli.calibrate_steps import CalibrationOptionError
    from orbitrig.cli.preflight import RigUnreachable
    from orbitrig.cli.signals import Interrupted
    from orbitrig.cli.terminal import OutputError, say
    from orbitrig.errors import ConfigError, OrbitrigError
    from orbitrig.run.modbus_log import keep_pymodbus_off_the_terminal

    keep_pymodbus_off_the_terminal()
    try:
        fn()
    except (ConfigError, CalibrationOptionError, RigUnreachable) as err:
        say(f"error: {err}", err=True)
        raise typer.Exit(2) from None
    except (OrbitrigError, OutputError) as err:
        say(f"error: {err}", err=True)
        raise typer.Exit(1) from None
    except (KeyboardInterrupt, Interrupted) as err:
        what = str(err) if isinstance(err, Interrupted) else "Ctrl-C"
        say(f"calibration stopped by {what}: the drives were stopped, no record written", err=True)
        raise typer.Exit(3) from None


def _rig_and_folder(config, writing: bool = True):
    """(rig, its records' folder); ``writing`` (a calibration step): refused in the shipped
    defaults (orbitrig.config.writable_home), before anything is started."""
    from orbitrig.config import default_rig_path, folder_of, load_rig, writable_home

    rig = load_rig(config)
    if writing:
        writable_home(config)
    return rig, folder_of(config or default_rig_path())


def _list(config) -> None:
    import datetime as _dt

    from orbitrig.cli.terminal import say
    from orbitrig.config import list_names, read_record
    from orbitrig.errors import ConfigError
    from rigunits import utc_iso

    rig, folder = _rig_and_folder(config, writing=False)
    names = list_names(folder)
    if not names:
        say(f"no calibration records in {folder}")
        return
    width = max(len(n) for n in names)
    for name in names:
        mark = "*" if name == rig.calibration_record else " "
        try:
            rec, _ = read_record(folder, name)
        except ConfigError as err:
            say(f"{mark} {name:<{width}}  unreadable: {err}")
            continue
        ref = f"{rec.reference.id} (u {rec.reference.uncertainty_pct:g} %)" if rec.reference else "-"
        when = utc_iso(_dt.datetime.fromisoformat(rec.date))  # the house format, whatever the file's spelling
        say(f"{mark} {name:<{width}}  {when}  {rec.step:<8} operator {rec.operator}  reference {ref}")


def _show(name, config) -> None:
    from orbitrig.cli.terminal import say
    from orbitrig.config import digest, read_record
    from orbitrig.errors import ConfigError

    rig, folder = _rig_and_folder(config, writing=False)
    name = name or rig.calibration_record
    if name is None:
        raise ConfigError(rig.file, ["names no active calibration record (calibration_record): give NAME"])
    _, text = read_record(folder, name)
    active = " (active)" if name == rig.calibration_record else ""
    say(f"# {folder / (name + '.toml')}{active}\n# sha256 {digest(text)}\n{text}", nl=False)


def _write(rig, folder, record, activate: bool, what: str) -> None:
    from orbitrig.cli.terminal import say
    from orbitrig.config import activate as make_active
    from orbitrig.config import write_record
    from orbitrig.errors import ConfigError

    header = (
        f"orbitrig calibration record (docs/calibration.md), written by `orbitrig calibrate {record.step}`.\n{what}"
    )
    name, _ = write_record(folder, record, header)
    say(f"calibration record {name} written to {folder}")
    if activate:
        try:
            make_active(rig.file, name)
        except ConfigError as err:  # rig.toml not writable (read-only, a full disk): it stays as it was
            raise ConfigError(err.file, [*err.problems, f"record {name} written, not activated"]) from None
        say(f'{rig.file}: calibration_record = "{name}" (active)')


def _reference(opts, reference_id, reference_u_pct, simulated: str):
    """The reference of a step: required on the rig; on the simulator exact unless given."""
    from orbitrig.config import Reference

    if not opts.sim and (reference_id is None or reference_u_pct is None):
        raise typer.BadParameter(
            "on the rig give the reference: --reference-id ID --reference-u-pct U", param_hint="--reference-id"
        )
    return Reference(id=reference_id or simulated, uncertainty_pct=reference_u_pct or 0.0)


def _loads(config, opts, load_n, reference_id, reference_u_pct, activate) -> None:
    from orbitrig.cli.calibrate_steps import check_rolls, loads_record
    from orbitrig.cli.terminal import say

    ref = _reference(opts, reference_id, reference_u_pct, "simulator: loads applied exactly")
    rig, folder = _rig_and_folder(config)
    check_rolls(rig, [opts.roll()], "--spin-rpm")
    record = run_until_signal(lambda: loads_record(rig, opts, load_n, ref, partial(say, err=True)))
    for lms, g in record.loads.items():
        say(
            f"{lms}: gain matrix {_matrix(g.gain, '.5f')} (u {_matrix(g.gain_u, '.2g')}), residual {g.residual_n:.3g} N"
        )
    _write(
        rig,
        folder,
        record,
        activate,
        "Units: gain 1 (f_journal = gain @ f_read + offset_n), offset_n and "
        "residual_n N; [uncertainty] gain_pct percent, phase_deg degrees, delay_us microseconds (k = 1).",
    )


def _matrix(rows, spec: str) -> str:
    """A matrix as its rows of numbers, each in format ``spec``: [[0.99778, 0.00131], [...]]."""
    return "[" + ", ".join("[" + ", ".join(format(v, spec) for v in row) + "]" for row in rows) + "]"


def _runout(config, opts, activate) -> None:
    from orbitrig.cli.calibrate_steps import check_rolls, runout_record
    from orbitrig.cli.terminal import say

    rig, folder = _rig_and_folder(config)
    check_rolls(rig, [opts.roll()], "--spin-rpm")
    record = run_until_signal(lambda: runout_record(rig, opts, partial(say, err=True)))
    runout = record.runout
    assert runout is not None  # runout_record measured it
    for p in ("x_a", "y_a", "x_b", "y_b"):
        h1, h2 = abs(runout.phasors(p)) * 1e6
        say(f"{p}: runout 1x {h1:.3f} um, 2x {h2:.3f} um")
    _write(rig, folder, record, activate, "Units: runout h1_um, h2_um micrometres [re, im] at 1x and 2x spin.")


def _delay(config, opts, speeds, amplitudes, activate) -> None:
    from orbitrig.cli.calibrate_steps import check_rolls, delay_record, delay_rolls
    from orbitrig.cli.terminal import say

    rig, folder = _rig_and_folder(config)
    check_rolls(rig, delay_rolls(opts, speeds), "--speeds-rpm")
    record = run_until_signal(lambda: delay_record(rig, opts, speeds, amplitudes, partial(say, err=True)))
    for name, d in record.delay.items():
        say(
            f"{name}: lags the probes by {d.phase_deg:.4f} deg (u {d.phase_u_deg:.2g}) "
            f"{'-' if d.delay_us < 0 else '+'} {abs(d.delay_us):.2f} us (u {d.delay_u_us:.2g})"
        )
    _write(
        rig,
        folder,
        record,
        activate,
        "Units: [delay] phase_deg degrees, delay_us microseconds: the force "
        "channel lags the probes by phase_deg + 360 f delay_us 1e-6 degrees at f Hz.",
    )


def _probes(config, opts, span_um, steps, reference_id, reference_u_pct, activate) -> None:
    import numpy as np

    from orbitrig.cli.calibrate_steps import check_rolls, probes_record
    from orbitrig.cli.terminal import say

    ref = _reference(opts, reference_id, reference_u_pct, "simulator: steps applied exactly")
    rig, folder = _rig_and_folder(config)
    check_rolls(rig, [opts.roll()], "--spin-rpm")
    grid = np.linspace(-span_um / 2, span_um / 2, steps) * 1e-6
    record = run_until_signal(lambda: probes_record(rig, opts, grid, ref, partial(say, err=True)))
    for p, g in record.probes.items():
        say(f"{p}: gain {g.gain:.5f} (u {g.gain_u:.2g}), linearity {g.linearity_pct:.3g} % of {g.span_um:g} um")
    _write(
        rig,
        folder,
        record,
        activate,
        "Units: [probes] gain 1 (x_journal = gain x_read), linearity_pct percent of span_um micrometres.",
    )
