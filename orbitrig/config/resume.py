"""What a resumed run may take from a rig configuration given again (`sweep --resume --config`).

A resumed run measures its remaining points as it measured the first ones: the rig configuration
and the calibration record it stored are the ones it uses. A configuration given again may differ
only where no stored number depends on it: where the devices are (the addresses of
``[transports]``, e.g. a serial port renamed after a reboot; not ``adc_mode``, which decides how
the samples are split into channels) and the planning times (``[estimates]``, ``[changeover]``;
the run keeps the order it started with). Any other difference (the active calibration record's
text among them) is refused before anything is started.
"""

from __future__ import annotations

import tomllib

from orbitrig.config.rig import RigConfig

#: the settings a resume may change: no stored number depends on them
ADDRESSES = frozenset({"adc_url", "modbus_url", "can_channel", "can_interface", "can_bitrate", "can_node_id"})
MAY_CHANGE = ("[transports] " + ", ".join(sorted(ADDRESSES)), "[estimates]", "[changeover]")
_EXCLUDED: dict[str, set[str] | bool] = {"transports": set(ADDRESSES), "estimates": True, "changeover": True}


def resume_differences(stored: RigConfig, given: RigConfig) -> list[str]:
    """The settings (keys of rig.toml: `[section]` or `[section] key`, and the calibration
    record's text) in which `given` differs from the `stored` configuration of the run being
    resumed, beyond MAY_CHANGE."""
    out = _key_differences(stored.model_dump(exclude=_EXCLUDED), given.model_dump(exclude=_EXCLUDED))
    if stored.record_text != given.record_text and "calibration_record" not in out:
        out.append(f"the text of calibration record {given.calibration_record}")
    return out


def matrix_differences(stored: str, given: str) -> list[str]:
    """The keys of the matrix TOML (`key`, `[table] key`, `[table]`), named as resume_differences
    names rig.toml's, in which the `given` text differs from the `stored` one of the run being
    resumed; its comments or layout when no key differs."""
    try:
        out = _key_differences(tomllib.loads(stored), tomllib.loads(given))
    except tomllib.TOMLDecodeError:
        out = []
    return out or ["its text (comments or layout)"]


def matrix_differs(run: object, stored: str, given: str) -> str:
    """What a matrix given to a resume is told when its `given` text differs from the `stored` one
    of the run in `run` (its directory): the keys that differ (matrix_differences)."""
    return (
        f"differs from the matrix of the run being resumed in {run} in {', '.join(matrix_differences(stored, given))}"
    )


def _key_differences(old: dict, new: dict) -> list[str]:
    """The keys in which ``new`` differs from ``old``: `key`, `[table] key`, or `[table]` for a
    table that is new, gone, or a list of tables."""
    out = []
    for key in sorted(old.keys() | new.keys()):
        a, b = old.get(key), new.get(key)
        if a == b:
            continue
        if isinstance(a, dict) and isinstance(b, dict):
            out += [f"[{key}] {k}" for k in sorted(a.keys() | b.keys()) if a.get(k) != b.get(k)]
        else:
            out.append(f"[{key}]" if isinstance(a, (dict, list)) or isinstance(b, (dict, list)) else key)
    return out
