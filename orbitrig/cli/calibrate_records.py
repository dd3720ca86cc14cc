"""`orbitrig calibrate`'s work behind its options: the records' history (list, show), and each
step run to its record: measured on the rig or the simulator, its numbers printed, the record
written into the records' folder beside the rig configuration and made the active one."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from functools import partial

import typer

from orbitrig.cli.signals import run_until_signal
from rigunits import MICROMETRE, MICROSECOND, UM, micrometres


def rig_and_folder(config, writing: bool = True):
    """(rig, its records' folder: where a step writes, or (not writing) where the rig's active
    record is read, orbitrig.config.record_folder); ``writing`` (a calibration step): refused in the shipped
    defaults (orbitrig.config.writable_home), before anything is started, as is an active record of
    another rig or channel setup; not writing (list, show): such a record is shown, and said refused
    (_refused), so that the history shows what to make active."""
    from orbitrig.config import default_rig_path, folder_of, load_rig, record_folder, writable_home

    rig = load_rig(config, check_record=writing)
    if not writing:  # where the active record was read: the shipped folder for a rig.toml without its own
        _refused(rig)
        return rig, record_folder(rig.file)
    writable_home(config)
    return rig, folder_of(config or default_rig_path())


def _refused(rig) -> None:
    """A note on standard error when the active record would be refused by a run or step (measured
    on another rig or channel setup: orbitrig.config.check_record_rig)."""
    from orbitrig.cli.terminal import say
    from orbitrig.config import check_record_rig
    from orbitrig.errors import ConfigError

    if rig.record is None:
        return
    try:
        check_record_rig(rig, rig.record, rig.record_text)
    except ConfigError as err:
        say(f"note: the active record is refused by sweep, serve and the steps: {err}", err=True)


def list_records(config) -> None:
    """`calibrate list`: one line per record, oldest first (as taken: record_files.read_all), * the
    active one."""
    import datetime as _dt

    from orbitrig.cli.terminal import say
    from orbitrig.config import read_all, seal_mark
    from orbitrig.errors import ConfigError
    from rigunits import utc_iso

    rig, folder = rig_and_folder(config, writing=False)
    records = read_all(folder)
    if not records:
        say(f"no calibration records in {folder}")
        return
    width = max(len(n) for n, _, _ in records)
    for name, rec, text in records:
        mark = "*" if name == rig.calibration_record else " "
        if isinstance(rec, ConfigError):
            say(f"{mark} {name:<{width}}  unreadable: {rec}")
            continue
        ref = f"{rec.reference.id} (u {rec.reference.uncertainty_pct:g} %)" if rec.reference else "-"
        when = utc_iso(_dt.datetime.fromisoformat(rec.date))  # the house format, whatever the file's spelling
        sim = "  on the simulator" if rec.simulator else ""
        seal = seal_mark(text)
        say(f"{mark} {name:<{width}}  {when}  {rec.step:<8} operator {rec.operator}  reference {ref}{sim}{seal}")


def show_record(name, config) -> None:
    """`calibrate show`: the record ``name`` (None: the active one), its path, SHA-256 (of the whole
    text, as a run records it), whether it is as its step wrote it, and its text."""
    from orbitrig.cli.terminal import say
    from orbitrig.config import RecordStep, digest, read_record, seal_note
    from orbitrig.errors import ConfigError

    rig, folder = rig_and_folder(config, writing=False)
    name = name or rig.calibration_record
    if name is None:
        raise ConfigError(rig.file, ["names no active calibration record (calibration_record): give NAME"])
    record, text = read_record(folder, name)
    active = " (active)" if name == rig.calibration_record else ""
    whole = f"# sha256 {digest(text)} (of this whole file: a run records it as calibration_record_sha256; "
    whole += "the record's own sha256 line below is of its text without that line)"
    if record.step is RecordStep.INITIAL:  # its date is no calibration's: nothing was measured
        whole += (
            f"\n# initial record: nothing measured yet; dated {record.date[:10]}, when it was written "
            f"(operator: {record.operator}), not when anything was calibrated"
        )
    notes = "".join(f"{n}\n" for n in coverage_notes(record))
    say(f"# {folder / (name + '.toml')}{active}\n{whole}\n{seal_note(text)}\n{notes}{text}", nl=False)


def coverage_notes(record) -> list[str]:
    """`calibrate show`'s lines on each fitted section's expanded uncertainty: the k and dof its
    U was taken at; a section written before records held them: its u alone (k = 1), with what a
    U = 2 u would cover at its fit's dof where the record tells them (its loads, its steps)."""
    import numpy as np

    from reduction.statistics import Interval, coverage_factor, coverage_probability

    out = []
    for name, section in (("loads", record.loads), ("delay", record.delay), ("probes", record.probes)):
        for key, v in section.items():
            head = f"# [{name}.{key}]"
            if v.dof is not None:
                k = sorted({f"{x:.3g}" for x in np.ravel(v.k if name == "delay" else v.gain_k)})
                out.append(f"{head} U = k u at 95.45 %: k {', '.join(k)} (Student's t), the fit's dof {v.dof}")
                continue
            dof, old = v.fit_dof, f"{head} u alone (k = 1; written before records held dof and U)"
            if dof is not None:
                old += (
                    f": its fit's {dof} degrees of freedom make U = 2 u cover "
                    f"{100 * coverage_probability(2.0, dof):.1f} %, Student's t (k "
                    f"{coverage_factor(Interval.STUDENT_T, dof):.3g}) 95.45 %"
                )
            out.append(old)
    return out


def reference(opts, reference_id, reference_u_pct, simulated: str):
    """The reference of a step: required on the rig; on the simulator exact unless given."""
    from orbitrig.config import Reference

    if not opts.sim and (reference_id is None or reference_u_pct is None):
        raise typer.BadParameter(
            "on the rig give the reference: --reference-id ID --reference-u-pct U", param_hint="--reference-id"
        )
    return Reference(id=reference_id or simulated, uncertainty_pct=reference_u_pct or 0.0)


def loads(config, opts, load_n, reference_id, reference_u_pct, activate) -> None:
    """`calibrate loads`: static loads of ``load_n`` N -> each system's gain matrix."""
    from orbitrig.cli.calibrate_steps import loads_record

    ref = reference(opts, reference_id, reference_u_pct, "simulator: loads applied exactly")
    _step(
        config,
        opts,
        activate,
        ([opts.roll()], "--spin-rpm"),
        lambda rig, note: loads_record(rig, opts, load_n, ref, note),
        lambda record: (
            f"{lms}: gain matrix {_matrix(g.gain, '.5f')} (u {_matrix(g.gain_u, '.2g')}; "
            f"U {_matrix(g.gain_U or [], '.2g')}, k {_k_text(g.gain_k or [])}, dof {g.dof}), "
            f"residual {g.residual_n:.3g} N"
            for lms, g in record.loads.items()
        ),
        "Units: gain 1 (f_journal = gain @ f_read + offset_n), offset_n and "
        "residual_n N; gain_u standard uncertainties (k = 1), gain_U = gain_k x gain_u expanded (about 95 %: "
        "Student's t at the effective degrees of freedom, the fit's dof); [uncertainty] gain_pct percent, "
        "phase_deg degrees, delay_us microseconds (k = 1).",
    )


def _k_text(rows) -> str:
    """A matrix of coverage factors: one number when its entries are alike to 3 digits, else its rows."""
    alike = {format(v, ".3g") for row in rows for v in row}
    return alike.pop() if len(alike) == 1 else _matrix(rows, ".3g")


def _matrix(rows, spec: str) -> str:
    """A matrix as its rows of numbers, each in format ``spec``: [[0.99778, 0.00131], [...]]."""
    return "[" + ", ".join("[" + ", ".join(format(v, spec) for v in row) + "]" for row in rows) + "]"


def runout(config, opts, activate) -> None:
    """`calibrate runout`: a slow roll without orbit -> each probe's runout at 1x and 2x spin."""
    from orbitrig.cli.calibrate_steps import runout_record
    from orbitrig.config import PROBE_CHANNELS

    def lines(record) -> Iterable[str]:
        runout = record.runout
        assert runout is not None  # runout_record measured it
        for p in PROBE_CHANNELS:
            (h1, h2), track = abs(runout.phasors(p)), dict(runout)[p]
            u = f" (u {track.h1_u_um:.3f}, {track.h2_u_um:.3f} µm)" if track.h1_u_um is not None else ""
            yield f"{p}: runout 1x {micrometres(h1, '.3f')}, 2x {micrometres(h2, '.3f')}{u}"
        if runout.slip_pct is not None:
            yield f"spin slip against the orbit spindle {runout.slip_pct:+.4f} % (u {runout.slip_u_pct:.4f} %), corrected"

    _step(
        config,
        opts,
        activate,
        ([opts.roll()], "--spin-rpm"),
        lambda rig, note: runout_record(rig, opts, note),
        lines,
        "Units: runout h1_um, h2_um micrometres [re, im] at 1x and 2x spin; h1_u_um, h2_u_um their "
        "standard uncertainties (micrometres, k = 1, from the revolutions' scatter); slip_pct, slip_u_pct "
        "percent: the spin's slip against the orbit spindle the revolutions were turned back by, and its "
        "standard uncertainty.",
    )


MEAN = "four probes' mean"  # what a probe's [delay] lag is behind


def delay(config, opts, speeds, amplitudes, activate) -> None:
    """`calibrate delay`: the phase reference at each of ``speeds`` (rpm) -> each channel's lag."""
    from orbitrig.cli.calibrate_steps import delay_record, delay_rolls

    _step(
        config,
        opts,
        activate,
        (delay_rolls(opts, speeds), "--speeds-rpm"),
        lambda rig, note: delay_record(rig, opts, speeds, amplitudes, note),
        lambda record: (
            f"{name}: lags the {'probes' if name.startswith('f') else MEAN} by {d.phase_deg:.4f} deg "
            f"(u {d.phase_u_deg:.2g}, U {d.phase_U_deg:.2g}) "
            f"{'-' if d.delay_us < 0 else '+'} {abs(d.delay_us):.2f} {MICROSECOND} (u {d.delay_u_us:.2g}, "
            f"U {d.delay_U_us:.2g}; k {d.k:.3g}, dof {d.dof})"
            for name, d in record.delay.items()
        ),
        "Units: [delay] phase_deg degrees, delay_us microseconds: the channel lags the "
        "four probes' mean by phase_deg + 360 f delay_us 1e-6 degrees at f Hz. The sweep takes every "
        "channel's lag out (probe_lags_corrected: the probes' too), so [uncertainty] holds the fits' own; "
        "phase_U_deg, delay_U_us = k x phase_u_deg, delay_u_us (about 95 %: Student's t at the line's dof).",
    )


def probes(config, opts, span_um, steps, reference_id, reference_u_pct, activate) -> None:
    """`calibrate probes`: ``steps`` displacement steps over ``span_um`` µm -> each probe's gain and linearity."""
    import numpy as np

    from orbitrig.cli.calibrate_steps import probes_record

    ref = reference(opts, reference_id, reference_u_pct, "simulator: steps applied exactly")
    grid = np.linspace(-span_um / 2, span_um / 2, steps) * UM
    _step(
        config,
        opts,
        activate,
        ([opts.roll()], "--spin-rpm"),
        lambda rig, note: probes_record(rig, opts, grid, ref, note),
        lambda record: (
            f"{p}: gain {g.gain:.5f} (u {g.gain_u:.2g}; U {g.gain_U:.2g}, k {g.gain_k:.3g}, dof {g.dof}), "
            f"linearity {g.linearity_pct:.3g} % of {g.span_um:g} {MICROMETRE}"
            for p, g in record.probes.items()
        ),
        "Units: [probes] gain 1 (x_journal = gain x_read), gain_u its standard uncertainty, gain_U = gain_k "
        "x gain_u expanded (about 95 %: Student's t at the effective degrees of freedom, the line's dof); "
        "linearity_pct percent of span_um micrometres.",
    )


def _step(config, opts, activate: bool, rolls, measure: Callable, lines: Callable, units: str) -> None:
    """One step: the rig and its records' folder (refused in the shipped defaults), ``rolls``
    (the step's slow rolls, the option that sets them) within the drive limits, ``measure(rig,
    note)`` run until a signal, ``lines(record)`` printed, the record written with ``units``.
    Standard output that cannot take the lines (a full disk behind ``> file``) does not lose
    what was measured: the record is written (and made active) all the same, then the step
    fails on the output (OutputError), naming the record."""
    from orbitrig.cli.calibrate_steps import check_rolls
    from orbitrig.cli.terminal import OutputError, say

    rig, folder = rig_and_folder(config)
    check_rolls(rig, *rolls)
    if opts.sim:
        _other_scenario(rig, opts)
    record = run_until_signal(lambda: measure(rig, partial(say, err=True)), "calibrate")
    try:
        for line in lines(record):
            say(line)
    except OutputError as err:  # the stream is silenced (orbitrig.cli.terminal): the record still written
        name = _write(rig, folder, record, activate, units)
        kept = f"record {name} written to {folder}" + (" and made active" if activate else "")
        raise OutputError(
            err.errno, f"{err.strerror} ({kept}; its numbers: orbitrig calibrate show {name})", err.filename
        ) from err
    _write(rig, folder, record, activate, units)


def _other_scenario(rig, opts) -> None:
    """A warning when a --sim step starts from a record measured on another simulator scenario
    (orbitrig.config.other_scenario, as a --sim sweep warns): the new record keeps what the step
    does not measure from it, yet names this step's scenario."""
    from orbitrig.cli.scenarios import scenario_of
    from orbitrig.cli.terminal import say
    from orbitrig.config import other_scenario

    scenario = scenario_of(opts.sim_config)
    warning = other_scenario(rig, scenario.name, scenario.text)
    if warning is not None:
        say(
            f"warning: {warning}; the record this step writes keeps what it does not measure from that "
            "record, under this step's scenario",
            err=True,
        )


def _write(rig, folder, record, activate: bool, what: str) -> str:
    """The record written into ``folder`` (``what``: its header's units) and, ``activate``, made
    rig.toml's active one; returns its name."""
    from orbitrig.cli.terminal import say
    from orbitrig.config import activate as make_active
    from orbitrig.config import write_dated
    from orbitrig.errors import ConfigError

    header = (
        f"orbitrig calibration record (docs/calibration.md), written by `orbitrig calibrate {record.step}`.\n{what}"
    )
    _, name, _ = write_dated(folder, record, lambda _: header)  # this step's of this second there: the next
    say(f"calibration record {name} written to {folder}")
    if activate:
        try:
            make_active(rig.file, name)
        except ConfigError as err:  # rig.toml not writable (read-only, a full disk): it stays as it was
            raise ConfigError(err.file, [*err.problems, f"record {name} written, not activated"]) from None
        say(f'{rig.file}: calibration_record = "{name}" (active)')
    return name
