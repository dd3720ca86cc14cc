"""The rig.toml keys that describe this rig's hardware: a rig.toml the lab wrote must give each one.

The models' defaults are the paper's rig (the shipped config/rig.toml, the simulator's): a
bearing clearance, a probe offset or a supply pressure band left out would silently be that rig's,
and on another bearing the orbit radius asked for (eps_d x c), the measured displacements and
the interlocks would be wrong. So `load_rig` refuses a file without any of HARDWARE_KEYS (or a
channel without CHANNEL_KEYS), naming the section, its line and what to add. The other keys
(averaging, settle, verify, estimates, changeover, timeouts, switches) are how the procedure runs,
and keep their documented defaults. The shipped rig.toml and `orbitrig init`'s copy of it give
every key; a run's stored rig configuration is read as stored (rig_from_text).
"""

from __future__ import annotations

from orbitrig.config.messages import key_message, key_line

#: section -> key -> what it is (for the message); the value of the paper's rig is the model's default
HARDWARE_KEYS: dict[str, dict[str, str]] = {
    "transports": {
        "adc_url": "A/D board address (a serial port, or socket:// of its device server)",
        "adc_mode": "A/D board conversion: sequential or simultaneous",
        "modbus_url": "drives' Modbus link",
        "can_channel": "CAN bus of the sensor node",
        "can_interface": "python-can interface of the CAN adapter",
        "can_bitrate": "CAN bus bit rate (bit/s)",
        "can_node_id": "sensor node's CANopen node id",
    },
    "bearing": {
        "radius_mm": "journal radius (mm)",
        "clearance_um": "radial clearance c (µm; the orbit radius asked for is eps_d x c)",
    },
    "drives": {
        "max_spin_rpm": "spin drive's speed limit (rpm)",
        "max_orbit_rpm": "orbit drive's speed limit (rpm)",
        "spin_id": "spin drive's Modbus device id",
        "orbit_id": "orbit drive's Modbus device id",
    },
    "interlocks": {
        "supply_pressure_min_mpa": "lowest supply pressure to run at (MPa)",
        "supply_pressure_max_mpa": "highest supply pressure to run at (MPa)",
    },
}
#: keys of each [[channels]] entry besides those the model requires (index, name, unit, gain)
CHANNEL_KEYS: dict[str, str] = {"offset": "sensor offset (N or m; 0.0 when it has none)"}

_WHY = "a key of the rig's hardware is never taken from it"


def missing_hardware(data: dict, text: str, only: dict[str, dict[str, str]] | None = None) -> list[str]:
    """One problem per hardware key the parsed rig.toml ``data`` (its ``text``, for the lines: a
    missing key's is its table's header) does not give: "line N: key 'bearing.clearance_um':
    missing from [bearing]: add clearance_um = ..., this rig's radial clearance c ...".
    ``only``: these sections' keys (a part of HARDWARE_KEYS; the channels' are not checked)."""
    from orbitrig.config.rig import RigConfig

    shipped = RigConfig.model_fields
    problems = []
    for section, keys in (only or HARDWARE_KEYS).items():
        table = data.get(section)
        example = shipped[section].default
        if table is None:
            wanted = ", ".join(f"{k} = {_toml(getattr(example, k))}" for k in keys)
            problems.append(
                f"key '{section}': no [{section}] section: add it with this rig's {', '.join(keys)} "
                f"(the paper's rig has {wanted}, and {_WHY})"
            )
            continue
        if not isinstance(table, dict):
            continue  # not a table: the model says so
        at = key_line(text, (section,))
        for key, what in keys.items():
            if key not in table:
                problems.append(_missing(section, key, what, at, _toml(getattr(example, key))))
    for i, channel in enumerate(data.get("channels") or [] if only is None else []):
        if not isinstance(channel, dict):
            continue
        at = key_line(text, ("channels", i))
        for key, what in CHANNEL_KEYS.items():
            if key not in channel:
                name = channel.get("name", f"channels[{i}]")
                where = f"[[channels]] {name}"
                problems.append(_missing(f"channels[{i}]", key, what, at, "0.0", where))
    return problems


def _missing(path: str, key: str, what: str, at: int | None, paper: str, where: str = "") -> str:
    return key_message(
        at,
        f"{path}.{key}",
        f"missing from {where or f'[{path}]'}: add {key} = ..., this rig's {what}; "
        f"the paper's rig has {key} = {paper}, and {_WHY}",
    )


def _toml(value) -> str:
    """A default as TOML writes it (a string quoted, an enum by its value)."""
    value = getattr(value, "value", value)
    if isinstance(value, str):
        return f'"{value}"'
    return repr(value)
