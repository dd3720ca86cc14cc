"""`drives stop` and `drives status` with a rig configuration that is refused: they still reach
the drives whenever its `[transports] modbus_url` and `[drives]` device ids can be taken
(orbitrig.config.drives_link), saying the file's errors as the full load says them, and end
CONFIG_ERRORS instead of 0; else they name what cannot be taken and the option that gives it."""

from __future__ import annotations

#: exit status of `drives stop|status` done, but with a rig configuration that has errors
CONFIG_ERRORS = 3


def despite_errors(command, config, modbus, id_options, err):
    """(URL, [drives], the error when built-in [drives] defaults stand in for the file's)
    for `drives COMMAND` whose rig configuration `config` was refused with ConfigError `err`;
    `id_options`: (--spin-id, --orbit-id). Exit 2, nothing sent, when the URL or the ids cannot be
    taken and no option gives them (with --modbus, ids that cannot be taken are the built-in ones)."""
    from orbitrig.config import Drives, drives_link
    from orbitrig.errors import ConfigError

    try:
        link = drives_link(config)
    except ConfigError:  # not read, not TOML: nothing can be taken from it
        if modbus is None:
            _refuse(command, err, "the rig configuration cannot be read", "--modbus URL (and --spin-id, --orbit-id)")
        return modbus, Drives(), err
    url, d, fallback = modbus or link.url, link.drives, None
    if url is None:
        _refuse(command, err, "its [transports] modbus_url cannot be taken", "--modbus URL")
    if d is None:
        if modbus is None and None in id_options:
            _refuse(command, err, "its [drives] spin_id, orbit_id cannot be taken", "--spin-id ID --orbit-id ID")
        d, fallback = Drives(), err
    if fallback is None:
        _warn(command, url, modbus, id_options, err)
    return url, d, fallback


def _refuse(command: str, err, what: str, how: str) -> None:
    from orbitrig.cli.failure import fail

    fail(f"{err}; nothing sent\n  {what}: give {how}", 2, part="config", command=f"drives {command}")


def _warn(command: str, url: str, modbus, id_options, err) -> None:
    """The WARNING, before the drives are reached, that the rig configuration has errors (each
    naming the file, line and key) and what is used all the same: the URL and device ids as taken
    from the file or from the options (`id_options`: --spin-id, --orbit-id, None where not given)."""
    from orbitrig.cli.drives_checks import said_aside

    source = "--modbus" if modbus else "[transports] modbus_url"
    said_aside(
        command,
        f"WARNING: the rig configuration has errors (every other command refuses it; exit {CONFIG_ERRORS} once "
        f"done); the drives at {url} ({source}) and {_ids_used(id_options)} are used all the same:\n{err}",
    )


def _ids_used(id_options) -> str:
    """Which device ids a command despite the file's errors uses: the file's, the options', or both."""
    given = [f"{option} {value}" for option, value in zip(("--spin-id", "--orbit-id"), id_options) if value is not None]
    if not given:
        return "its [drives] device ids"
    if len(given) == len(id_options):
        return f"the device ids of the options ({', '.join(given)})"
    kept = "orbit_id" if id_options[0] is not None else "spin_id"
    return f"the device id of {given[0]} and its [drives] {kept}"


def config_errors_code(command: str, code: int, errors) -> int:
    """`code`, or CONFIG_ERRORS, said once more, for a command done (0) with a rig configuration
    that has `errors` (None: none)."""
    if errors is None or code != 0:
        return code
    from orbitrig.cli.drives_checks import said_aside

    done = "both drives stopped" if command == "stop" else "both drives read"
    said_aside(command, f"WARNING: {done}, but the rig configuration has errors ({errors.file}, above)")
    return CONFIG_ERRORS
