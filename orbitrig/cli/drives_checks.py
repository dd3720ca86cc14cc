"""Checks of `orbitrig drives` options before anything is sent: the rig
configuration and device ids, times, and limits that may only tighten the
configuration's. `open_config` and `check_seconds` say why a check fails and exit 2 themselves
(typer.Exit, at the command line's boundary: nothing sent); `despite_errors` (drives_despite) what
`status` and `stop` take from a rig configuration that is refused."""

from __future__ import annotations

import math

from drives.registers import MAX_DEVICE_ID, MIN_DEVICE_ID
from orbitrig.cli.drives_despite import despite_errors
from orbitrig.cli.failure import fail
from rigunits import DAY

MAX_SECONDS = DAY  # longest --settle/--timeout/--status-every accepted


def check_seconds(command: str, **options: tuple[float | None, bool]) -> None:
    """Nothing if every option (name -> (value s, zero allowed)) is a finite time
    of at most a day; else print why and exit 2 (typer.Exit: nothing sent)."""
    problems = []
    for name, (value, zero_ok) in options.items():
        if value is None:
            continue
        low_ok = value >= 0 if zero_ok else value > 0
        if not (math.isfinite(value) and low_ok and value <= MAX_SECONDS):
            bound = ">= 0" if zero_ok else "> 0"
            problems.append(
                f"--{name.replace('_', '-')} {value:g} s must be finite, {bound} and at most {MAX_SECONDS:g} s"
            )
    if problems:
        fail(f"{'; '.join(problems)}; nothing sent", 2, command=f"drives {command}")


def effective_limits(
    d, *, max_spin=None, max_orbit=None, min_ratio=None, max_ratio=None, file: str = "the rig configuration"
):
    """DriveLimits (rad/s) of the rig's [drives] section `d`, tightened by the
    command line's values (rpm, ratios). ValueError naming the option if one
    is looser than the configuration (or contradicts another)."""
    from orbitrig.config import RPM
    from drives.limits import DriveLimits

    problems = []

    def tighter(option, value, key, configured, *, upper: bool, unit: str = ""):
        if value is None:
            return configured
        if not (math.isfinite(value) and value >= 0):
            problems.append(f"{option} {value:g}{unit} is not a finite value >= 0")
            return configured
        if configured is not None and (value > configured if upper else value < configured):
            word = "above" if upper else "below"
            problems.append(
                f"{option} {value:g}{unit} is {word} the rig's drives.{key} = {configured:g}{unit} "
                f"({file}): the command line may only tighten the rig's limits"
            )
            return configured
        return value

    spin = tighter("--max-spin", max_spin, "max_spin_rpm", d.max_spin_rpm, upper=True, unit=" rpm")
    orbit = tighter("--max-orbit", max_orbit, "max_orbit_rpm", d.max_orbit_rpm, upper=True, unit=" rpm")
    lo = tighter("--min-ratio", min_ratio, "min_ratio", d.min_ratio, upper=False)
    hi = tighter("--max-ratio", max_ratio, "max_ratio", d.max_ratio, upper=True)
    if not problems and lo is not None and hi is not None and lo > hi:
        problems.append(f"min ratio {lo:g} > max ratio {hi:g} (options and {file} together)")
    if problems:
        raise ValueError("; ".join(problems))
    return DriveLimits(max_spin=spin * RPM, max_orbit=orbit * RPM, min_ratio=lo, max_ratio=hi)


#: where a drive's device id came from (`open_config`): `drives status --json`'s "id_from"
ID_FROM_CONFIG, ID_FROM_OPTION, ID_FROM_DEFAULT = "configuration", "option", "built-in default"
NAMES = ("spin", "orbit")


def open_config(command, config, modbus, spin_id, orbit_id, *, required: bool):
    """(Modbus URL, the [drives] section with the ids from the options, where each id came from:
    {"spin": ID_FROM_*, "orbit": ...}, the rig configuration's errors or None); else print why not
    and exit 2 (typer.Exit: nothing sent). `run` needs a rig configuration without errors; `status`
    and `stop` of one refused take what it still gives of the drives' link (`despite_errors`)."""
    from orbitrig.config import load_rig
    from orbitrig.errors import ConfigError

    errors = None
    try:
        rig = load_rig(config)
        url, d, fallback = modbus or rig.transports.modbus_url, rig.drives, None
    except ConfigError as err:
        if required:
            fail(str(err), 2, part="config", command=f"drives {command}")
        url, d, fallback = despite_errors(command, config, modbus, (spin_id, orbit_id), err)
        errors = err
    ids = _id_options(command, spin_id, orbit_id)
    id_from = {
        n: ID_FROM_OPTION if f"{n}_id" in ids else ID_FROM_DEFAULT if fallback else ID_FROM_CONFIG for n in NAMES
    }
    if ids:
        d = d.model_copy(update=ids)
        if d.spin_id == d.orbit_id:
            fail(f"spin and orbit id are both {d.spin_id}; nothing sent", 2, command=f"drives {command}")
    if fallback is not None:
        said_aside(command, fallback_warning(fallback, d, id_from))
    return url, d, id_from, errors


def said_aside(command: str, text: str) -> None:
    """A note or WARNING of `drives COMMAND` on standard error that the command's work does not
    depend on: a standard error that cannot take it (a full disk) keeps no stop from going out,
    and the exit status still says how the drives ended."""
    from orbitrig.cli.terminal import say_aside

    say_aside(f"orbitrig drives {command}: {text}")


def fallback_warning(err, d, id_from) -> str:
    """The WARNING of a command that goes on without its rig configuration (`err`, naming the
    file): which device ids it addresses and where each came from."""
    ids = ids_said(d, id_from)
    hint = (
        "" if ID_FROM_DEFAULT not in id_from.values() else "; give --spin-id/--orbit-id if the rig's drives have others"
    )
    return f"WARNING: rig configuration not read ({err}): built-in [drives] defaults; drives addressed: {ids}{hint}"


def ids_said(d, id_from) -> str:
    """'spin (id 1, built-in default), orbit (id 2, built-in default)': the ids of [drives] `d`, each's source."""
    ids = {"spin": d.spin_id, "orbit": d.orbit_id}
    return ", ".join(f"{n} (id {ids[n]}, {id_from[n]})" for n in NAMES)


def _id_options(command, spin_id, orbit_id) -> dict[str, int]:
    """{"spin_id": ..., "orbit_id": ...} of the options given; exit 2 for one out of range."""
    ids = {}
    for option, key, value in (("--spin-id", "spin_id", spin_id), ("--orbit-id", "orbit_id", orbit_id)):
        if value is None:
            continue
        if not MIN_DEVICE_ID <= value <= MAX_DEVICE_ID:
            fail(
                f"{option} {value} is not a Modbus device id ({MIN_DEVICE_ID}..{MAX_DEVICE_ID}); nothing sent",
                2,
                command=f"drives {command}",
            )
        ids[key] = value
    return ids
