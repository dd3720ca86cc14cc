"""SimRig: the whole software rig behind real protocols, in the running event loop.

    async with SimRig(speedup=10) as rig:
        rig.local_control(spin=200.0, orbit=-60.0)      # rad/s, orbit signed
        ... read rig.adc_url / rig.adc_pty_path, talk Modbus to rig.modbus_url ...
        rig.true_impedance(200.0, -60.0)      # 2x2 complex, the truth per frequency

The orbit spindle angle is integrated from the orbit drive's actual speed; every
slot edge it passes is converted (sequential: channel s mod C; simultaneous:
all channels), quantised and framed, and whole frames go to the TCP serial
device server and the pty. Physics and the board clock run in simulated time
(SimClock, `speedup` x wall time, slower when the board cannot keep up: it never trails the
drives by more than its lead, sim.slot_stream.LEAD_S); the CAN periods stay in wall time, the drives'
comm-loss watchdog in wall time without this process's own stalls (AwakeClock, ticked by the
Modbus servers). The slot edges and their conversions are sim/slot_stream.py's.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math

import numpy as np

from sim.adc_board import AdcBoard
from sim.adc_server import AdcServer
from sim.can_node import CanNode
from sim.chain import calibration_errors
from sim.clock import AwakeClock, SimClock
from sim.config import SimConfig
from sim.fits import constant_fit, power_fit
from sim.injection import inject
from sim.physics import RigPhysics
from sim.streams import Purpose
from sim.slot_stream import LEAD_S, SlotStream

log = logging.getLogger(__name__)

RPM = 2.0 * math.pi / 60.0  # rad/s per rpm


class SimRig:
    """The simulated rig (async context manager); see docs/interfaces.md (sim/) and docs/simulator.md."""

    def __init__(
        self,
        config: SimConfig | None = None,
        *,
        speedup: float | None = None,
        modbus_port: int = 0,
        adc_port: int = 0,
        adc_pty: bool = True,
        modbus_rtu_pty: bool = False,
        can_channel: str | None = "orbitrig-sim",
        control_port: int | None = None,
        can_interface: str = "virtual",
        can_node_id: int | None = None,
        tick: float = 0.01,
        max_slots_per_tick: int = 400_000,
        lead: float = LEAD_S,
    ):
        self.config = config or SimConfig()
        self.clock = SimClock(speedup if speedup is not None else self.config.speedup)
        self.physics = RigPhysics(self.config)
        adc = self.config.adc
        self.board = AdcBoard(
            channels=len(adc.channels),
            mode=adc.mode,
            frame_slots=adc.frame_slots,
            gains=adc.gains,
            offsets=adc.offsets,
            rng=self.physics.streams.generator(Purpose.BIT_ERRORS),
        )
        self._modbus_port, self._adc_port, self._control_port = modbus_port, adc_port, control_port
        self._adc_pty, self._modbus_rtu_pty = adc_pty, modbus_rtu_pty
        self._can_interface = can_interface
        #: the CAN node's node id (its frames 0x180 + id ...): `can_node_id`, else the scenario's [can] node_id
        self.can_node_id = self.config.can.node_id if can_node_id is None else can_node_id
        self._tick_period = tick
        self.can_channel = can_channel
        self.modbus_url = ""
        self.modbus_rtu_path: str | None = None
        self.adc_url = ""
        self.control_url: str | None = None
        self.drives: dict = {}
        self.adc_server = AdcServer()
        self.can_node: CanNode | None = None
        self.modbus_servers: list = []  # the Modbus/TCP server and the RTU pty server, when open
        self._control: asyncio.Server | None = None
        self._tasks: set[asyncio.Task] = set()
        self.stream = SlotStream(
            self.clock, self.physics, self.board, self.adc_server, self.shaft_profile, max_slots_per_tick, lead
        )
        self.orbit_reversed = False  # the fault orbit_wired_reversed: the orbit motor's phases swapped

    # ------------------------------------------------------------ lifecycle
    async def __aenter__(self) -> SimRig:
        try:
            await self._start()
        except BaseException:
            await self.aclose()
            raise
        return self

    async def __aexit__(self, *exc) -> None:
        await self.aclose()

    async def _start(self) -> None:
        from sim.drive_model import DriveModel
        from sim.modbus_server import serve_modbus_rtu_pty, serve_modbus_tcp

        awake = AwakeClock()  # the drives' watchdog time: wall time without this process's stalls
        self.drives = {  # the Modbus servers tick it; the masters are other processes
            i: DriveModel(i, clock=self.clock.now, bidirectional=i == 2, wall_clock=awake, speed_error=error)
            for i, error in ((1, self.config.drives.spin_speed_error), (2, self.config.drives.orbit_speed_error))
        }
        tcp = await serve_modbus_tcp(self.drives, host="127.0.0.1", port=self._modbus_port)
        self.modbus_servers.append(tcp)
        self.modbus_url = tcp.url
        if self._modbus_rtu_pty:
            rtu = await serve_modbus_rtu_pty(self.drives)
            self.modbus_servers.append(rtu)
            self.modbus_rtu_path = rtu.path
        await self.adc_server.start(port=self._adc_port, pty=self._adc_pty)
        self.adc_url = self.adc_server.url
        if self._control_port is not None:
            from sim.control import serve_control

            self._control = await serve_control(self, port=self._control_port)
            self.control_url = f"tcp://127.0.0.1:{self._control.sockets[0].getsockname()[1]}"
        self.stream.start()
        self._spawn(self._run_board(), "sim-adc-board")
        if self.can_channel is not None:
            self.can_node = CanNode(
                self.can_channel, self.aux_state, interface=self._can_interface, node_id=self.can_node_id
            )
            self.can_node.open()
            self._spawn(self.can_node.run(), "sim-can-node")

    def _spawn(self, coro, name: str) -> None:
        task = asyncio.get_running_loop().create_task(coro, name=name)
        self._tasks.add(task)
        task.add_done_callback(self._task_done)

    def _task_done(self, task: asyncio.Task) -> None:
        self._tasks.discard(task)
        if not task.cancelled() and task.exception() is not None:
            log.error("simulator task %s failed", task.get_name(), exc_info=task.exception())

    async def aclose(self) -> None:
        """Stop every task and server (idempotent)."""
        tasks = list(self._tasks)
        for t in tasks:
            t.cancel()
        for t in tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await t
        self.clock.hold(math.inf)  # no board to wait for
        if self.can_node is not None:
            self.can_node.close()
        if self._control is not None:
            self._control.close()
            self._control = None
        for ep in self.modbus_servers:
            with contextlib.suppress(Exception):
                await ep.aclose()
        self.modbus_servers.clear()
        await self.adc_server.aclose()

    # ------------------------------------------------------------ properties
    @property
    def adc_pty_path(self) -> str | None:
        return self.adc_server.pty_path

    @property
    def speedup(self) -> float:
        """Simulated time / wall time."""
        return self.clock.speedup

    @property
    def speeds(self) -> tuple[float, float]:
        """(spin, orbit) actual speeds in rad/s (orbit signed) now: the drives integrated to the
        present, as a Modbus read of ACT would find them (the last tick may be older)."""
        self.advance_drives()
        spin = self.drives[1].actual_rpm * RPM if 1 in self.drives else 0.0
        orbit = self.drives[2].actual_rpm * RPM if 2 in self.drives else 0.0
        return spin, orbit

    @property
    def shaft_speeds(self) -> tuple[float, float]:
        """(spin, orbit) rad/s the spindles turn at: the drives' speeds, the orbit's sign turned
        when its motor is wired reversed (the drive reads as commanded, the orbit whirls the other way)."""
        spin, orbit = self.speeds
        return spin, -orbit if self.orbit_reversed else orbit

    def shaft_profile(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(times, spin, orbit) of the spindles from simulated t0 to t1 (s, both included, the
        drives' speed knots between; rad/s, linear between the times; orbit as `shaft_speeds`)."""
        self.advance_drives()
        drives = [self.drives[i] for i in (1, 2) if i in self.drives]
        times = np.unique(np.clip(np.concatenate([[t0, t1], *(d.trace.times() for d in drives)]), t0, t1))
        spin, orbit = (self.drives[i].trace.at(times) * RPM if i in self.drives else 0 * times for i in (1, 2))
        return times, spin, -orbit if self.orbit_reversed else orbit

    def advance_drives(self) -> None:
        """Integrate every drive's ramps and state to the present."""
        for d in self.drives.values():
            d.advance()

    def endpoints(self) -> dict:
        """The endpoints JSON object printed by `orbitrig sim`."""
        return {
            "modbus": self.modbus_url,
            "adc": self.adc_url,
            "adc_pty": self.adc_pty_path,
            "control": self.control_url,
            "can": self.can_channel,
            "can_node_id": self.can_node_id if self.can_channel is not None else None,
            "modbus_rtu": self.modbus_rtu_path,
        }

    # ------------------------------------------------------------ operator
    def local_control(self, *, spin: float, orbit: float, hand_back: bool = False) -> None:
        """Both spindles from the keypads (rad/s, signed; the spin drive refuses spin < 0). The
        keypads hold control (control words refused) unless `hand_back`: then they give it back at
        once, the drives turning on until the network's next control word takes them."""
        for dev, speed in ((1, spin), (2, orbit)):
            self.keypad(dev, speed)
            if hand_back:
                self.drives[dev].hand_back()

    def keypad(self, drive: int, speed: float | None) -> None:
        """Drive `drive` (1 spin, 2 orbit) taken to its keypad and run at `speed` (rad/s, signed);
        None: its keypad gives control back to the network (DriveModel.hand_back)."""
        if drive not in self.drives:
            raise ValueError(f"no drive {drive}; the drives are {sorted(self.drives)}")
        if speed is None:
            self.drives[drive].hand_back()
        else:
            self.drives[drive].local_control(speed / RPM)

    def set_manual(
        self, *, orbit_radius=None, static_eccentricity=None, recess_pressure=None, pressure_ratio=None
    ) -> None:
        """Manual settings: orbit radius (m), static eccentricity eps_s (-),
        recess supply pressure (Pa), pressure ratio beta (-)."""
        self.physics.set_manual(
            orbit_radius=orbit_radius,
            static_eccentricity=static_eccentricity,
            recess_pressure=recess_pressure,
            pressure_ratio=pressure_ratio,
        )

    def true_impedance(self, spin: float, orbit: float) -> np.ndarray:
        """True Z (2x2 complex) of the linearised bearing at spin and orbit (rad/s, orbit
        signed; Z depends on |orbit| only): f_bar = -Z d_bar, Z = K + i|Omega| C - Omega^2 D."""
        return self.physics.impedance(spin, orbit)

    def true_impedances(self, spin: float, orbits) -> np.ndarray:
        """True Z (n, 2, 2) complex at each orbit speed (rad/s)."""
        return self.physics.impedances(spin, orbits)

    def apparent_impedance(self, spin: float, orbit: float, lms: str = "piezo") -> np.ndarray:
        """True Z seen through the calibration errors of ``lms`` and the probes (RigPhysics)."""
        return self.physics.apparent_impedance(spin, orbit, lms)

    def reference_orbits(self, spin: float) -> np.ndarray:
        """The reference band of truth(): bearing.reference_ratios x spin (rad/s)."""
        return np.asarray(self.config.bearing.reference_ratios) * abs(float(spin))

    def reference_fits(self, spin: float, orbits=None, exponents=(1, 1, 1)) -> dict:
        """Best fits of the true Z over ``orbits`` (rad/s; default the reference band):
        {"constant": {"K","C","D"}, "power": {"K0","Km","C0","Cn","D0","Dp","exponents","absorbed","determined"}}
        (sim.fits.power_fit)."""
        w = self.reference_orbits(spin) if orbits is None else np.abs(np.asarray(orbits, dtype=float))
        Z = self.true_impedances(spin, w)
        return {"constant": constant_fit(w, Z), "power": power_fit(w, Z, exponents)}

    def truth(self, spin: float, orbit: float) -> dict:
        """{"K", "C", "D"} (2x2, SI): constant best fit of the true Z over the reference band
        at this spin (``orbit`` does not change it). The exact truth: true_impedance."""
        w = self.reference_orbits(spin)
        return constant_fit(w, self.true_impedances(spin, w))

    def calibration_errors(self) -> dict:
        """The calibration errors the scenario injects (see sim.chain.calibration_errors)."""
        return calibration_errors(self.config)

    def true_phasors(self, spin: float, orbit: float) -> dict[str, complex]:
        """Noise-free fundamental phasor per channel name (engineering units, chain in)."""
        return self.physics.true_phasors(spin, orbit)

    def aux_state(self) -> dict:
        return self.physics.aux_state(*self.stream.last_speeds)

    def state(self) -> dict:
        m = self.physics.manual
        return {
            "sim_time": self.clock.now(),
            "sim_time_lost": self.clock.lost,
            "speedup": self.clock.speedup,
            **dict(zip(("spin", "orbit"), self.speeds)),
            "manual": {
                "orbit_radius": m.orbit_radius,
                "static_eccentricity": m.static_eccentricity,
                "recess_pressure": m.recess_pressure,
                "pressure_ratio": m.pressure_ratio,
            },
            "board": {
                "seq": self.board.seq,
                "rev": self.board.rev,
                "frames_sent": self.board.frames_sent,
                "frames_lost": self.board.frames_lost,
                "lag": self.stream.lag.last,
                "longest_lag": self.stream.lag.longest,
            },
            "endpoints": self.endpoints(),
        }

    def inject(self, fault: str, **kw) -> None:
        """Inject one of the faults sim.injection.SimFault names (see sim.injection.inject)."""
        inject(self, fault, **kw)

    # ------------------------------------------------------------ the board
    async def _run_board(self) -> None:
        while True:
            try:
                await self.stream.step()
            except Exception:  # keep the rig alive; the log says what broke
                log.exception("A/D board step failed")
            await asyncio.sleep(self.stream.tick_period(self._tick_period))
