"""JSON-lines control API of the simulator (loopback TCP), for a separate process.

One JSON object per line in, one per line out:
  {"cmd": "set_manual", "orbit_radius": 6e-6, "static_eccentricity": 0.2,
   "recess_pressure": 1e6, "pressure_ratio": 0.5}           -> {"ok": true}
  {"cmd": "truth", "spin": 200.0, "orbit": -60.0}            -> {"ok": true, "K": [[..]], "C": .., "D": ..}
  {"cmd": "true_phasors", "spin": .., "orbit": ..}           -> {"ok": true, "phasors": {"x_a": [re, im], ..}}
  {"cmd": "true_impedance", "spin": .., "orbit": ..}         -> {"ok": true, "re": [[..]], "im": [[..]]}
  {"cmd": "apply_load", "fx": 500.0, "fy": 0.0}              -> {"ok": true}   (static calibration load, N)
  {"cmd": "apply_displacement", "dx": 1e-5, "dy": 0.0}      -> {"ok": true}   (static probe step, m)
  {"cmd": "apply_reference", "force": 100.0, "probe": 2e-6}  -> {"ok": true}   (calibrator on every input; 0, 0: off)
  {"cmd": "inject", "fault": "drop_frames", "count": 3}      -> {"ok": true}
  {"cmd": "local_control", "spin": .., "orbit": ..}          -> {"ok": true}
  {"cmd": "state"}                                           -> {"ok": true, "spin": .., "orbit": .., ...}
Errors: {"ok": false, "error": "..."}. SI units throughout (m, Pa, rad/s; orbit signed).
"""

from __future__ import annotations

import asyncio
import json
import logging

import numpy as np

log = logging.getLogger(__name__)


def _jsonable(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, complex):
        return [value.real, value.imag]
    if isinstance(value, dict):
        return {k: _jsonable(v) for k, v in value.items()}
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    return value


def handle(rig, request: dict) -> dict:
    """Execute one control request on ``rig`` and return the reply object."""
    req = dict(request)
    cmd = req.pop("cmd", None)
    try:
        if cmd == "set_manual":
            rig.set_manual(**req)
            return {"ok": True}
        if cmd == "truth":
            return {"ok": True, **_jsonable(rig.truth(float(req["spin"]), float(req["orbit"])))}
        if cmd == "true_phasors":
            return {"ok": True, "phasors": _jsonable(rig.true_phasors(float(req["spin"]), float(req["orbit"])))}
        if cmd == "true_impedance":
            Z = rig.true_impedance(float(req["spin"]), float(req["orbit"]))
            return {"ok": True, "re": Z.real.tolist(), "im": Z.imag.tolist()}
        if cmd == "apply_load":
            rig.physics.apply_load(float(req["fx"]), float(req["fy"]))
            return {"ok": True}
        if cmd == "apply_displacement":
            rig.physics.apply_displacement(float(req["dx"]), float(req["dy"]))
            return {"ok": True}
        if cmd == "apply_reference":
            rig.physics.apply_reference(float(req["force"]), float(req["probe"]))
            return {"ok": True}
        if cmd == "inject":
            rig.inject(req.pop("fault"), **req)
            return {"ok": True}
        if cmd == "local_control":
            rig.local_control(spin=float(req["spin"]), orbit=float(req["orbit"]))
            return {"ok": True}
        if cmd == "state":
            return {"ok": True, **_jsonable(rig.state())}
        return {"ok": False, "error": f"unknown cmd {cmd!r}; known: set_manual, apply_load, apply_displacement, "
                                      "apply_reference, truth, "
                                      "true_phasors, true_impedance, inject, local_control, state"}
    except KeyError as err:
        return {"ok": False, "error": f"{cmd}: missing field {err.args[0]!r}"}
    except (TypeError, ValueError, RuntimeError) as err:
        return {"ok": False, "error": f"{cmd}: {err}"}


async def serve_control(rig, host: str = "127.0.0.1", port: int = 0) -> asyncio.base_events.Server:
    """Start the JSON-lines control server; returns the asyncio server."""

    async def client(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            while line := await reader.readline():
                if not line.strip():
                    continue
                try:
                    request = json.loads(line)
                    if not isinstance(request, dict):
                        raise ValueError("a request is a JSON object")
                    reply = handle(rig, request)
                except ValueError as err:
                    reply = {"ok": False, "error": f"bad request: {err}"}
                writer.write(json.dumps(reply).encode() + b"\n")
                await writer.drain()
        except (ConnectionError, OSError):
            pass
        finally:
            writer.close()

    return await asyncio.start_server(client, host, port)
