"""What a resumed run may take from a rig configuration given again (`sweep --resume --config`).

A resumed run measures its remaining points as it measured the first ones: the rig configuration
and the calibration record it stored are the ones it uses. A configuration given again may differ
only where the data do not depend on it: where the devices are (``[transports]``, e.g. a serial
port renamed after a reboot) and the planning times (``[estimates]``, ``[changeover]``; the run
keeps the order it started with). Any other difference (the active calibration record's text
among them) is refused before anything is started.
"""

from __future__ import annotations

from orbitrig.config.rig import RigConfig

#: the sections of rig.toml a resume may change: no stored number depends on them
MAY_CHANGE = frozenset({"transports", "estimates", "changeover"})


def resume_differences(stored: RigConfig, given: RigConfig) -> list[str]:
    """The settings (top-level keys of rig.toml, and the calibration record) in which `given`
    differs from the `stored` configuration of the run being resumed, beyond MAY_CHANGE."""
    old, new = stored.model_dump(exclude=set(MAY_CHANGE)), given.model_dump(exclude=set(MAY_CHANGE))
    keys = sorted(k for k in old.keys() | new.keys() if old.get(k) != new.get(k))
    out = [f"[{k}]" if isinstance(old.get(k, new.get(k)), (dict, list)) else k for k in keys]
    if stored.record_text != given.record_text and "calibration_record" not in keys:
        out.append(f"the text of calibration record {given.calibration_record}")
    return out
