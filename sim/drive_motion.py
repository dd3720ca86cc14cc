"""The emulated drive's motor side run in time: the command it follows (the accepted control
word and reference, or the keypad's speed), the state machine of `sim/drive_states.py` driven
by it, the ramps, coasting and torque, and what a trip or an expired comm-loss watchdog does to
them. Pure logic, no I/O; `sim/drive_model.py` puts the register map in front of it.

Timing (simulated ramps, a wall-clock watchdog), coasting and torque: docs/simulator.md, "Drives".
"""

from __future__ import annotations

import time
from collections.abc import Callable

from . import drive_registers as R
from .clock import AwakeClock
from .drive_faults import CommWatchdog, FaultLatch
from .drive_states import (
    EMERGENCY_FACTOR,
    ENABLED,
    FAULTED,
    INHIBITED,
    OFF1_ACTIVE,
    OFF3_ACTIVE,
    READY,
    modulating,
    motion,
    ramp_phase,
    settle,
)
from .speed_trace import SpeedTrace


class DriveMotion:
    """One drive's spindle run in time: state, speed, ramps, faults, watchdog (see DriveModel)."""

    def __init__(
        self,
        device_id: int,
        *,
        clock: Callable[[], float],
        bidirectional: bool,
        wall_clock: Callable[[], float] | None = None,
        coast_decel: float = 150.0,
        rated_rpm: float = 3000.0,
        starting_time: float = 1.0,
        friction: float = 0.05,
        speed_error: float = 0.0,
    ) -> None:
        if coast_decel <= 0 or rated_rpm <= 0 or starting_time <= 0:
            raise ValueError("coast_decel, rated_rpm and starting_time must be > 0")
        self.device_id = device_id
        self.bidirectional = bidirectional
        self._clock = clock
        if wall_clock is None:  # plain wall time, as a real drive's; the simulator passes AwakeClocks
            wall_clock = time.monotonic
        #: the watchdog's clock when it is an AwakeClock: the Modbus servers tick it (sim/modbus_server.py)
        self.awake = wall_clock if isinstance(wall_clock, AwakeClock) else None
        self._wall = wall_clock
        self._coast_decel = float(coast_decel)
        self._a_nom = rated_rpm / starting_time
        self._rated_rpm = float(rated_rpm)
        self._friction = float(friction)
        self._speed_error = float(speed_error)

        self._params = dict(R.PARAMETER_DEFAULTS)
        self._cw = 0  # last accepted CW (REMOTE = 1)
        self._ref = 0  # last accepted REF, int16
        self._local = False  # under the keypad's command (local control)
        self._local_rpm = 0.0  # the keypad's speed, rpm signed

        self._state = INHIBITED
        self._speed = 0.0  # rpm, signed
        self._alpha = 0.0  # rpm/s, current ramp acceleration (powered)
        self._faults = FaultLatch()
        self._fault_ramp = False  # 7510 ramp stop in progress
        self.comm_lost_after: float | None = None  # wall time of the last request before a 7510 trip
        self._fault_ramp_factor = 1.0  # x DECEL rate (EMERGENCY_FACTOR if OFF3 was active)
        # a ramp stop word during the emergency ramp resumes the slower ramp stop (sim/drive_states.py)
        self.off1_yields = False

        self._t = float(clock())
        self.trace = SpeedTrace(self._t)  # the speed over simulated time, for the spindles (sim.slot_stream)
        self._w = float(self._wall())
        self._w_wall = self._wall_time()  # the same moment in wall time (an AwakeClock's stalls included)
        self._watchdog = CommWatchdog(self._w, self._w_wall)

    # ------------------------------------------------------------------ API
    @property
    def actual_rpm(self) -> float:
        """Actual speed in rpm, signed, as of the last `advance()`."""
        return self._speed

    @property
    def running(self) -> bool:
        """Operation enabled (RDY_REF): running and following the reference."""
        return self._state == ENABLED

    @property
    def state(self) -> str:
        """State name of the drive-profile state machine."""
        return self._state

    @property
    def fault_code(self) -> int:
        """Active fault code (first latched), 0 = none."""
        return self._faults.code

    @property
    def faults(self) -> tuple[int, ...]:
        """All latched fault codes in order of occurrence."""
        return tuple(self._faults.latched)

    @property
    def torque(self) -> float:
        """Actual torque as a fraction of nominal (1.0 = 100 %)."""
        if not self._powered():
            return 0.0
        return self._alpha / self._a_nom + self._friction * self._speed / self._rated_rpm

    @property
    def reference_rpm(self) -> float:
        """The reference the ramp follows, rpm signed, after limiting."""
        return self._limited_reference()[0]

    def parameter(self, address: int) -> int:
        """Current value of parameter `address` (100..105)."""
        return self._params[address]

    def advance(self) -> None:
        """Integrate ramps and state up to `clock()`; run the watchdog (wall time)."""
        t_now = max(float(self._clock()), self._t)
        w_now = float(self._wall())
        frac = None
        if R.COMM_LOSS_FAULT not in self._faults.latched:
            frac = self._watchdog.expired(self._params[R.COMM_LOSS_TIMEOUT], self._w, w_now)
        if frac is not None:
            self.comm_lost_after = self._watchdog.heard
            self._integrate_to(self._t + frac * (t_now - self._t))
            self._trip(R.COMM_LOSS_FAULT)
            self._faults.causes.add(R.COMM_LOSS_FAULT)
        self._integrate_to(t_now)
        self._w = max(w_now, self._w)
        self._w_wall = self._wall_time()

    @property
    def last_request(self) -> float:
        """Wall time (s, time.monotonic) of the last valid request addressed to this drive."""
        return self._watchdog.heard

    def note_request(self) -> None:
        """A valid request addressed to this drive arrived: feed the watchdog."""
        self.advance()
        self._watchdog.feed(self._w, self._w_wall)
        self._faults.causes.discard(R.COMM_LOSS_FAULT)

    def clear_fault_cause(self, code: int | None = None) -> None:
        """Remove the cause of fault `code` (all causes if None); a RESET edge still
        has to clear the latched fault."""
        self._faults.clear_cause(code)

    def _wall_time(self) -> float:
        """Wall time now (s): the watchdog's clock with the stalls it leaves out."""
        return self.awake.wall() if self.awake is not None else float(self._wall())

    # -------------------------------------------------------- state machine
    def _limited_reference(self) -> tuple[float, bool]:
        """(reference rpm after limiting, whether it was limited)."""
        if self._local:
            return self._local_rpm, False
        return R.limit_reference(self._ref, self._params[R.SPEED_SCALE], self._params[R.MAX_SPEED], self.bidirectional)

    def _evaluate(self) -> None:
        """Apply the accepted control word to the state (until stable)."""
        self._state = settle(self._state, self._cw, self._speed, off1_yields=self.off1_yields)

    def _trip(self, code: int) -> None:
        was_powered = self._powered()
        self._faults.latch(code)
        if R.FAULT_REACTIONS[code] == "coast":
            self._fault_ramp = False
        elif self._state != FAULTED:
            self._fault_ramp = was_powered and self._speed != 0.0
            # an emergency stop already under way keeps its faster ramp
            self._fault_ramp_factor = EMERGENCY_FACTOR if self._state == OFF3_ACTIVE else 1.0
        self._state = FAULTED

    def _modulating(self) -> bool:
        """Producing torque: parameters are locked."""
        return modulating(self._state, self._fault_ramp)

    def _powered(self) -> bool:
        return self._modulating()

    # ------------------------------------------------------------- dynamics
    def _motion(self) -> tuple[float | None, float, float]:
        """(target rpm or None = hold, accel rate, decel rate) for the current state."""
        scale = float(self._params[R.SPEED_SCALE])
        return motion(
            self._state,
            self._cw,
            reference=R.turning_speed(
                self._limited_reference()[0], self._speed_error, self._params[R.SPEED_SCALE], self._params[R.MAX_SPEED]
            ),
            accel=scale / (0.1 * self._params[R.ACCEL_TIME]),
            decel=scale / (0.1 * self._params[R.DECEL_TIME]),
            coast_decel=self._coast_decel,
            fault_ramp=self._fault_ramp,
            fault_ramp_factor=self._fault_ramp_factor,
        )

    def _integrate_to(self, t_end: float) -> None:
        remaining = t_end - self._t
        self._t = max(self._t, t_end)
        for _ in range(16):  # a few phases at most: zero crossing, stop, state change
            target, up, down = self._motion()
            if target is None or self._speed == target:
                self._alpha = 0.0
                if self._standstill_transition():
                    continue
                break
            self._speed, self._alpha, left = ramp_phase(self._speed, target, up, down, remaining)
            if left is None:
                break
            self.trace.add(self._t - left, self._speed)  # the phase's end: the slope changes
            remaining = left
            self._standstill_transition()
        self.trace.add(self._t, self._speed)

    def _standstill_transition(self) -> bool:
        """Finish a stop that reached zero speed; True if the state changed."""
        if self._speed != 0.0:
            return False
        if self._state == OFF1_ACTIVE:
            self._state = READY
            self._evaluate()
            return True
        if self._state == OFF3_ACTIVE:
            self._state = INHIBITED
            self._evaluate()
            return True
        if self._state == FAULTED and self._fault_ramp:
            self._fault_ramp = False
            return True
        return False
