"""JSON-lines control API of the simulator (loopback TCP), for a separate process.

One JSON object per line in, one per line out:
  {"cmd": "set_manual", "orbit_radius": 6e-6, "static_eccentricity": 0.2,
   "recess_pressure": 1e6, "pressure_ratio": 0.5}           -> {"ok": true}
  {"cmd": "truth", "spin": 200.0, "orbit": -60.0}            -> {"ok": true, "K": [[..]], "C": .., "D": ..}
  {"cmd": "true_phasors", "spin": .., "orbit": ..}           -> {"ok": true, "phasors": {"x_a": [re, im], ..}}
  {"cmd": "true_impedance", "spin": .., "orbit": ..}         -> {"ok": true, "re": [[..]], "im": [[..]]}
  {"cmd": "impedances", "spin": .., "orbits": [..]}          -> {"ok": true, "re": [[[..]]], "im": ..}  (n, 2, 2)
  {"cmd": "reference_fits", "spin": .., "orbits": [..]}      -> {"ok": true, "fits": {"constant": .., "power": ..}}
  {"cmd": "drives"}                                          -> {"ok": true, "drives": {"1": {"state", "rpm", ..}}}
  {"cmd": "apply_load", "fx": 500.0, "fy": 0.0}              -> {"ok": true}   (static calibration load, N)
  {"cmd": "apply_displacement", "dx": 1e-5, "dy": 0.0}      -> {"ok": true}   (static probe step, m)
  {"cmd": "apply_reference", "force": 100.0, "probe": 2e-6}  -> {"ok": true}   (calibrator on every input; 0, 0: off)
  {"cmd": "inject", "fault": "drop_frames", "count": 3}      -> {"ok": true}
  {"cmd": "local_control", "spin": .., "orbit": .., "hand_back": false} -> {"ok": true}
  {"cmd": "keypad", "drive": 1, "speed": 62.8}               -> {"ok": true}   (that drive's keypad takes it)
  {"cmd": "keypad", "drive": 1, "speed": null}               -> {"ok": true}   (its keypad gives control back)
  {"cmd": "state"}                                           -> {"ok": true, "spin": .., "orbit": .., ...}
Errors: {"ok": false, "error": "..."}. SI units throughout (m, Pa, rad/s; orbit signed); drive
speeds in rpm as in the registers. docs/protocols/sim-control.md describes each command.
"""

from __future__ import annotations

import asyncio
import json
import logging

import numpy as np

from sim.drive_registers import CW

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


def _orbits(req: dict) -> np.ndarray:
    return np.asarray(req["orbits"], dtype=float)


def _complex(Z: np.ndarray) -> dict:
    return {"re": Z.real.tolist(), "im": Z.imag.tolist()}


def _impedances(rig, req: dict) -> dict:
    return _complex(rig.true_impedances(float(req["spin"]), _orbits(req)))


def _drives(rig, req: dict) -> dict:
    """Per drive (Modbus device id), now: state, actual speed (rpm), faults, the control word it
    holds and the last ones written, time stamped."""
    rig.advance_drives()
    return {
        "drives": {
            str(dev): {
                "state": d.state,
                "rpm": d.actual_rpm,
                "fault": d.fault_code,
                "faults": list(d.faults),
                "control_word": d.read(CW, 1)[0],
                "keypad": d.keypad,
                "control_words": [list(w) for w in d.control_words],
            }
            for dev, d in rig.drives.items()
        }
    }


#: cmd -> (rig, request without "cmd") -> the reply's fields
COMMANDS = {
    "set_manual": lambda rig, req: rig.set_manual(**req),
    "truth": lambda rig, req: _jsonable(rig.truth(float(req["spin"]), float(req["orbit"]))),
    "true_phasors": lambda rig, req: {"phasors": _jsonable(rig.true_phasors(float(req["spin"]), float(req["orbit"])))},
    "true_impedance": lambda rig, req: _complex(rig.true_impedance(float(req["spin"]), float(req["orbit"]))),
    "impedances": _impedances,
    "reference_fits": lambda rig, req: {"fits": _jsonable(rig.reference_fits(float(req["spin"]), _orbits(req)))},
    "apply_load": lambda rig, req: rig.physics.apply_load(float(req["fx"]), float(req["fy"])),
    "apply_displacement": lambda rig, req: rig.physics.apply_displacement(float(req["dx"]), float(req["dy"])),
    "apply_reference": lambda rig, req: rig.physics.apply_reference(float(req["force"]), float(req["probe"])),
    "inject": lambda rig, req: rig.inject(req.pop("fault"), **req),
    "local_control": lambda rig, req: rig.local_control(
        spin=float(req["spin"]), orbit=float(req["orbit"]), hand_back=bool(req.get("hand_back", False))
    ),
    "keypad": lambda rig, req: rig.keypad(int(req["drive"]), None if req["speed"] is None else float(req["speed"])),
    "state": lambda rig, req: _jsonable(rig.state()),
    "drives": _drives,
}


#: the commands that solve the bearing (run in a worker thread, so the drives keep their answers)
NUMERIC = frozenset({"truth", "true_phasors", "true_impedance", "impedances", "reference_fits"})


def handle(rig, request: dict) -> dict:
    """Execute one control request on ``rig`` and return the reply object."""
    req = dict(request)
    cmd = req.pop("cmd", None)
    if cmd not in COMMANDS:
        return {"ok": False, "error": f"unknown cmd {cmd!r}; known: {', '.join(COMMANDS)}"}
    try:
        return {"ok": True, **(COMMANDS[cmd](rig, req) or {})}
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
                    heavy = request.get("cmd") in NUMERIC  # the bearing's numerics: off the loop
                    reply = await asyncio.to_thread(handle, rig, request) if heavy else handle(rig, request)
                except ValueError as err:
                    reply = {"ok": False, "error": f"bad request: {err}"}
                writer.write(json.dumps(reply).encode() + b"\n")
                await writer.drain()
        except (ConnectionError, OSError, asyncio.CancelledError):  # cancelled: the simulator ends
            pass
        finally:
            writer.close()

    return await asyncio.start_server(client, host, port)
