"""Before a sweep, a calibration step or a start of the rig service: does every transport of
the rig config answer? (The one owner of that check and of its words; orbitrig.cli and
orbitrig.service call it.)

Each link is opened once and closed again (the drives' once each drive's parameters have been
read, the CAN node's once its heartbeat has been read: daq.aux.AuxSensors.heard); nothing is
written to the drives and no
run directory (or record) exists yet, so a machine without the rig gets one clear message
naming every transport that does not answer, instead of a failed run that blocks the next try.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import logging
import threading

from orbitrig.config import RigConfig
from orbitrig.run.rig_io import Endpoints
from orbitrig.errors import OrbitrigError

#: seconds each transport may take to answer
TIMEOUT_S = 2.0

#: what to check for a serial port that does not open, by the error number the system gave
PORT_HINTS = {
    errno.ENOENT: "no such port: is the adapter plugged in? `ls -l /dev/serial/by-id/` names each one by its make "
    "and serial number, the path to give",
    errno.EACCES: "no permission: add this user to the port's group (`ls -l PORT`, usually dialout: "
    "`sudo usermod -aG dialout $USER`, then log in again)",
    errno.EBUSY: "in use by another program (`fuser -v PORT`)",
    errno.EAGAIN: "in use by another program, which holds its lock (`fuser -v PORT`)",  # an exclusive open's
}


def port_hint(err: BaseException) -> str:
    """What to check for a serial port that would not open, from the error number of `err` or of
    an error it was raised from (PORT_HINTS), "" for any other failure."""
    seen: BaseException | None = err
    while seen is not None:
        if isinstance(seen, OSError) and seen.errno in PORT_HINTS:
            return PORT_HINTS[seen.errno]
        seen = seen.__cause__ or seen.__context__
    return ""


async def _adc(url: str) -> None:
    from daq.transport import open_link

    link = await open_link(url, lambda data: None, lambda err: None, timeout=TIMEOUT_S)
    link.close()


async def _drives(url: str, spin_id: int, orbit_id: int) -> None:
    """Each drive's parameters read once: its device id answers (nothing written)."""
    from drives.link import ModbusLink
    from drives.registers import PARAMETERS

    with _pymodbus_quiet():  # it logs every refused connection itself
        async with ModbusLink(url, timeout=TIMEOUT_S, names={spin_id: "spin", orbit_id: "orbit"}) as link:
            for device_id in (spin_id, orbit_id):
                await link.read(device_id, *PARAMETERS)


#: checks under way (in any thread) while pymodbus is quieted, and its level before the first
_quieted = {"checks": 0, "level": logging.NOTSET}
_quieted_lock = threading.Lock()


@contextlib.contextmanager
def _pymodbus_quiet():
    """pymodbus' logger at CRITICAL while any check runs (a service's start-up check and a start's may
    overlap, each in a thread of its own), its own level given back once the last one ends."""
    quiet = logging.getLogger("pymodbus")
    with _quieted_lock:
        if _quieted["checks"] == 0:
            _quieted["level"] = quiet.level
            quiet.setLevel(logging.CRITICAL)
        _quieted["checks"] += 1
    try:
        yield
    finally:
        with _quieted_lock:
            _quieted["checks"] -= 1
            if _quieted["checks"] == 0:
                quiet.setLevel(_quieted["level"])


async def _can(rig: RigConfig) -> None:
    from daq.aux import AuxSensors

    t = rig.transports
    async with AuxSensors(
        t.can_channel, interface=t.can_interface, bitrate=t.can_bitrate, node_id=t.can_node_id
    ) as aux:
        await aux.heard()  # a bus that opens says nothing of the node on it


async def unreachable_transports(rig: RigConfig) -> list[str]:
    """One line per transport of ``rig`` that cannot be opened (empty: all answer)."""
    t = rig.transports
    checks = {
        "A/D board (adc_url)": _adc(t.adc_url),
        "drives (modbus_url, [drives] spin_id, orbit_id)": _drives(
            t.modbus_url, rig.drives.spin_id, rig.drives.orbit_id
        ),
        "CAN sensor node (can_interface, can_channel)": _can(rig),
    }
    results = await asyncio.gather(*checks.values(), return_exceptions=True)
    problems = []
    for what, result in zip(checks, results):
        if isinstance(result, (OrbitrigError, OSError)):
            hint = port_hint(result)
            problems.append(f"{what}: {result}" + (f"\n    {hint}" if hint else ""))
        elif isinstance(result, BaseException):
            raise result
    return problems


class RigUnreachable(OrbitrigError):
    """A transport of the rig config does not answer (nothing sent: a command exits 2, the
    service refuses the start)."""


def at_endpoints(rig: RigConfig, endpoints: Endpoints) -> RigConfig:
    """`rig` with its transports at `endpoints` (a simulator's own addresses)."""
    e = endpoints
    ends = {"modbus_url": e.modbus_url, "adc_url": e.adc_url, "can_channel": e.can_channel}
    at = rig.transports.model_copy(update={**ends, "can_interface": e.can_interface})
    return rig.model_copy(update={"transports": at})


async def say_what_answers(rig: RigConfig, logger: str) -> None:
    """Once, as a service starts on the rig: a warning naming each transport of `rig` that does not
    answer (not a refusal: the rig may be powered later; each start asks again), else an info line.
    Asked in a thread of its own (opening a port may block); said in the log named `logger`."""
    log = logging.getLogger(logger)
    try:
        problems = await asyncio.to_thread(asyncio.run, unreachable_transports(rig))
    except Exception as err:  # noqa: BLE001 - the service starts all the same
        log.warning("the rig's transports could not be asked at start-up: %r", err)
        return
    if problems:
        lines = "".join(f"\n  {p}" for p in problems)
        log.warning(
            "the rig does not answer yet ([transports] and [drives] in %s); each start asks again:%s", rig.file, lines
        )
    else:
        log.info("the rig answers: drives, A/D board and CAN sensor node")


async def require_rig_answers(rig: RigConfig, command: str, nothing: str) -> None:
    """Raise RigUnreachable naming every transport of `rig` that does not answer; `command` is
    the one to run on the simulator instead (e.g. 'orbitrig sweep --sim ...'), `nothing` what
    was not made (e.g. 'no run directory was made'). First a ConfigError when the active
    calibration record was measured on the simulator (orbitrig.config.check_on_the_rig)."""
    from orbitrig.config import check_on_the_rig

    check_on_the_rig(rig, nothing)
    await require_transports(rig, command, nothing)


async def require_transports(rig: RigConfig, command: str, nothing: str) -> None:
    """RigUnreachable, in the words of require_rig_answers, when a transport of `rig` does not answer
    (each opened once, within TIMEOUT_S, nothing written to the drives)."""
    problems = await unreachable_transports(rig)
    if problems:
        lines = "\n".join(f"  {p}" for p in problems)
        raise RigUnreachable(
            f"the rig does not answer ([transports] and [drives] in {rig.file}):\n{lines}\n"
            f"Nothing was started and {nothing}. On a machine without the rig, "
            f"run on the built-in simulator: {command}"
        )
