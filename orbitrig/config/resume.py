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

from orbitrig.config.rig import RigConfig

#: the settings a resume may change: no stored number depends on them
ADDRESSES = frozenset({"adc_url", "modbus_url", "can_channel", "can_interface", "can_bitrate", "can_node_id"})
MAY_CHANGE = ("[transports] " + ", ".join(sorted(ADDRESSES)), "[estimates]", "[changeover]")
_EXCLUDED: dict[str, set[str] | bool] = {"transports": set(ADDRESSES), "estimates": True, "changeover": True}


def resume_differences(stored: RigConfig, given: RigConfig) -> list[str]:
    """The settings (keys of rig.toml: `[section]` or `[section] key`, and the calibration
    record's text) in which `given` differs from the `stored` configuration of the run being
    resumed, beyond MAY_CHANGE."""
    old, new = stored.model_dump(exclude=_EXCLUDED), given.model_dump(exclude=_EXCLUDED)
    out = []
    for key in sorted(old.keys() | new.keys()):
        a, b = old.get(key), new.get(key)
        if a == b:
            continue
        if isinstance(a, dict) and isinstance(b, dict):
            out += [f"[{key}] {k}" for k in sorted(a.keys() | b.keys()) if a.get(k) != b.get(k)]
        else:
            out.append(f"[{key}]" if isinstance(a, (dict, list)) or isinstance(b, (dict, list)) else key)
    if stored.record_text != given.record_text and "calibration_record" not in out:
        out.append(f"the text of calibration record {given.calibration_record}")
    return out
