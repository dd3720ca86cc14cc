"""`orbitrig drives status`: both drives read over Modbus, nothing written."""

from __future__ import annotations


async def status_of(url: str, json_out: bool, d, id_from) -> int:
    """Both drives' state, reference and actual speed (rpm), torque, fault and parameters, read
    only (running drives keep running); `json_out`: one JSON object. Exit 0."""
    import json

    from drives.drive import Drive
    from drives.link import ModbusLink
    from orbitrig.cli.drives_hold import drive_line
    from orbitrig.cli.drives_checks import ID_FROM_DEFAULT
    from orbitrig.cli.terminal import say
    from rigunits import in_rpm

    out: dict = {"modbus": url}
    names = {d.spin_id: "spin", d.orbit_id: "orbit"}
    async with ModbusLink(url, timeout=d.timeout_s, names=names) as link:
        for name, device_id, bidirectional in (("spin", d.spin_id, False), ("orbit", d.orbit_id, True)):
            drive = Drive(link, device_id, name, bidirectional=bidirectional)
            params = await drive.read_parameters()
            st = (await drive.read_status()).to_dict()
            st["parameters"] = {
                "speed_scale_rpm": round(in_rpm(params.speed_scale), 3),
                "max_speed_rpm": round(in_rpm(params.max_speed), 3),
                "accel_time_s": params.accel_time,
                "decel_time_s": params.decel_time,
                "comm_loss_timeout_s": params.comm_loss_timeout,
                "at_setpoint_band_rpm": round(in_rpm(params.at_setpoint_band), 3),
            }
            out[name] = st | {"id_from": id_from[name]}
    if json_out:
        say(json.dumps(out))
    else:
        for name in ("spin", "orbit"):
            st, mark = out[name], "" if id_from[name] != ID_FROM_DEFAULT else f", {ID_FROM_DEFAULT}"
            say(f"{name:5s} (id {st['device_id']}{mark}): {drive_line(st)}")
    return 0
