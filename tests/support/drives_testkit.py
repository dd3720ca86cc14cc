"""The simulator's drives for the drives/ tests: two DriveModels behind a real
Modbus server (TCP, or RTU over a pty), ramps sped up, an observer that reads
the drives' registers without going through drives/.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass

from drives.limits import DriveLimits
from drives.rig import RigDrives
from sim import drive_registers as sim_registers
from sim.clock import AwakeClock
from sim.drive_model import DriveModel
from sim.modbus_server import ModbusEndpoint, serve_modbus_rtu_pty, serve_modbus_tcp

from support.cli_helpers import orbitrig_async, orbitrig_here, reaped_async

SPEEDUP = 25.0  # simulated s per wall s for ramps (the watchdog stays in wall time)
RPM = 2.0 * 3.141592653589793 / 60.0

# Spec control words, written out here (not imported from drives/) on purpose.
CW_RUN, CW_RAMP_STOP, CW_EMERGENCY = 0x047F, 0x047E, 0x047B
#: s a command started in a subprocess may take to bring the drives to its setpoint: mostly its own
#: start (python, orbitrig's imports), which took over 10 s with both cores busy and 4 test workers
CLI_START_S = 60.0


@dataclass
class SimDrives:
    """Spin (id 1) and orbit (id 2) drive models served at `url`."""

    kind: str
    models: dict[int, DriveModel]
    endpoint: ModbusEndpoint
    loop: asyncio.AbstractEventLoop | None = None  # the loop serving them, when not the test's own

    def in_loop(self, fn, *args) -> None:
        """`fn(*args)` (a change to a drive model) run by the loop serving the drives."""
        if self.loop is None:
            fn(*args)
        else:
            asyncio.run_coroutine_threadsafe(_call(fn, *args), self.loop).result(10)

    @property
    def url(self) -> str:
        return self.endpoint.url

    def keypad_run(self, dev: int, rpm: float) -> None:
        """Drive `dev` run at its keypad at `rpm` and control handed back: turning under no command of
        the network (SW REMOTE = 0) until the network's next control word takes it."""
        self.models[dev].local_control(rpm)
        self.models[dev].hand_back()

    # -- observer: the drives' own registers, not via drives/ (feeds no watchdog)
    def regs(self, dev: int) -> dict[str, int]:
        w = self.models[dev].read(0, 7)
        s16 = [v - 0x10000 if v & 0x8000 else v for v in w]
        return {"CW": w[0], "REF": s16[1], "SW": w[3], "ACT": s16[4], "FAULT": w[6]}

    def rpm(self, dev: int) -> float:
        self.models[dev].advance()
        return self.models[dev].actual_rpm

    async def wait_for(self, cond, timeout: float, what: str) -> float:
        """Poll `cond()` every 10 ms; returns the seconds it took."""
        t0 = time.monotonic()
        while not cond():
            if time.monotonic() - t0 > timeout:
                raise AssertionError(f"{what} not within {timeout} s: {self.regs(1)} {self.regs(2)}")
            await asyncio.sleep(0.01)
        return time.monotonic() - t0

    def not_the_watchdog(self, dev: int) -> bool:
        """No comm-loss trip (fault 7510) while a client still talked to drive ``dev``. The
        watchdog stays armed after the last client leaves (at standstill), so on a starved
        machine it may latch 7510 before this read: then no request came after the silence
        that tripped it."""
        model, fault = self.models[dev], self.regs(dev)["FAULT"]
        return fault == 0 or (fault == sim_registers.COMM_LOSS_FAULT and model.comm_lost_after == model.last_request)

    async def wait_stopped(self, timeout: float = 3.0) -> float:
        return await self.wait_for(lambda: self.regs(1)["ACT"] == 0 and self.regs(2)["ACT"] == 0, timeout, "standstill")


async def _call(fn, *args) -> None:
    fn(*args)


async def wait_until(cond, timeout: float, what: str) -> None:
    """Poll `cond()` every 10 ms on the running loop's clock; fail naming `what` after `timeout` s."""
    loop = asyncio.get_running_loop()
    t_end = loop.time() + timeout
    while not cond():
        assert loop.time() < t_end, f"{what} not within {timeout} s"
        await asyncio.sleep(0.01)


def open_rig(sim: SimDrives, limits: DriveLimits, **kw) -> RigDrives:
    """RigDrives on the simulator with test timings (poll 50 ms, request timeout 0.1 s, watchdog 0.5 s)."""
    kw.setdefault("poll_interval", 0.05)
    kw.setdefault("timeout", 0.1)  # link_loss_polls 3 x (0.05 + 0.1) s < 0.5 s watchdog
    kw.setdefault("comm_loss_timeout", 0.5)
    return RigDrives(sim.url, limits, **kw)


def make_models(speedup: float = SPEEDUP, *, awake: bool = False) -> dict[int, DriveModel]:
    """The two drives; their watchdog in wall time, or (awake) on an AwakeClock as in the
    simulator process, which leaves out the serving loop's stalls (a master in another process)."""
    t0 = time.monotonic()

    def clock() -> float:
        return (time.monotonic() - t0) * speedup

    wall = AwakeClock() if awake else None
    return {
        1: DriveModel(1, clock=clock, bidirectional=False, wall_clock=wall),
        2: DriveModel(2, clock=clock, bidirectional=True, wall_clock=wall),
    }


async def serve(kind: str, models: dict[int, DriveModel]) -> ModbusEndpoint:
    if kind == "tcp":
        return await serve_modbus_tcp(models)
    return await serve_modbus_rtu_pty(models)


@contextlib.contextmanager
def served_from_a_thread(kind: str, speedup: float, *, awake: bool = False) -> Iterator[SimDrives]:
    """The drives served from a loop in another thread, so that a command run in this thread
    (its own `asyncio.run`, its signal handlers) owns this one."""
    loop = asyncio.new_event_loop()
    thread = threading.Thread(target=loop.run_forever, daemon=True)
    thread.start()
    models = make_models(speedup=speedup, awake=awake)
    endpoint = asyncio.run_coroutine_threadsafe(serve(kind, models), loop).result(10)
    try:
        yield SimDrives(kind, models, endpoint, loop)
    finally:
        asyncio.run_coroutine_threadsafe(endpoint.aclose(), loop).result(10)
        loop.call_soon_threadsafe(loop.stop)
        thread.join(10)


def set_parameter(model: DriveModel, address: int, value: int) -> None:
    model.write(address, [value])


PARAM = {
    "SPEED_SCALE": sim_registers.SPEED_SCALE,
    "MAX_SPEED": sim_registers.MAX_SPEED,
    "COMM_LOSS_TIMEOUT": sim_registers.COMM_LOSS_TIMEOUT,
    "DECEL_TIME": sim_registers.DECEL_TIME,
}


async def exit_with_registers(proc: asyncio.subprocess.Process, sim: SimDrives) -> tuple[int, str, list[dict]]:
    """(exit status, standard error, both drives' registers as the command exited) of `proc`."""
    async with reaped_async(proc):
        _, err = await asyncio.wait_for(proc.communicate(), 40)
        at_exit = [sim.regs(dev) for dev in (1, 2)]
    return proc.returncode, err.decode(), at_exit


async def run_cli(*args: str, timeout: float = CLI_START_S + 20.0) -> tuple[int, str, str]:
    """`python -m orbitrig <args>` run to its end in a subprocess while this loop keeps serving
    (cli_helpers.orbitrig_async), within ``timeout`` s (its start with both cores busy included)."""
    return await orbitrig_async(*args, timeout=timeout)


def invoke_cli(*args: str) -> tuple[int, str, str]:
    """`orbitrig <args>` run to its end in this process (cli_helpers.orbitrig_here, this thread: the
    command's own `asyncio.run` and signal handlers), the drives served from another thread
    (`threaded_*`): (exit status, standard output, standard error)."""
    done = orbitrig_here(*args)
    return done.returncode, done.stdout, done.stderr


class DriveLines(logging.Handler):
    """Every record of the drives' loggers, at DEBUG too: (level, message)."""

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.lines: list[tuple[int, str]] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append((record.levelno, record.getMessage()))

    def said(self, level: int, *words: str) -> list[str]:
        return [m for lv, m in self.lines if lv == level and all(w in m for w in words)]


@contextlib.contextmanager
def drive_lines() -> Iterator[DriveLines]:
    """The drives' loggers' records (DriveLines) while inside, at DEBUG; their level as before after."""
    lines, drives_log = DriveLines(), logging.getLogger("drives")
    drives_log.addHandler(lines)
    old_level, drives_log.level = drives_log.level, logging.DEBUG
    try:
        yield lines
    finally:
        drives_log.removeHandler(lines)
        drives_log.setLevel(old_level)
