"""The emulated drive's protection: latched faults and the communication-loss
watchdog. Small state holders; `sim/drive_model.py` decides what a trip does
to the state machine and the speed.

Faults
------
2310, 4210, 7301: coast stop. 7510 (communication loss): ramp stop along
DECEL_TIME if the drive was under torque (a coasting drive keeps coasting; an
OFF3 emergency stop under way keeps its 10 x faster ramp).
Faults latch in order of occurrence. `inject_fault(code)` sets the cause and
trips; `clear_fault_cause()` removes the cause (the fault stays latched until
a RESET edge). The cause of 7510 is gone as soon as a valid request arrives.

Watchdog
--------
Armed while the drive is under network control (a control word with
REMOTE = 1 was accepted) and COMM_LOSS_TIMEOUT > 0; it trips 7510 when no
valid request addressed to this drive arrived for COMM_LOSS_TIMEOUT * 0.1 s of
wall time, also when the drive is stopped; the simulator's own stalls do not count
(sim.clock.AwakeClock, docs/simulator.md "A starved simulator"). Requests answered with an exception
count as valid (the link is alive); requests to another device id do not.
Only the local keypad disarms it.
"""

from __future__ import annotations

__all__ = ["CommWatchdog", "FaultLatch"]


class FaultLatch:
    """Latched fault codes in order of occurrence, and the causes still present."""

    def __init__(self) -> None:
        self.latched: list[int] = []
        self.causes: set[int] = set()

    @property
    def code(self) -> int:
        """Active fault code (first latched), 0 = none."""
        return self.latched[0] if self.latched else 0

    def latch(self, code: int) -> None:
        if code not in self.latched:
            self.latched.append(code)

    def clear_cause(self, code: int | None) -> None:
        """Remove the cause of fault `code` (all causes if None)."""
        if code is None:
            self.causes.clear()
        else:
            self.causes.discard(code)

    def reset(self) -> bool:
        """A RESET edge: unlatch every fault whose cause is gone; True if none is left."""
        self.latched = [f for f in self.latched if f in self.causes]
        return not self.latched


class CommWatchdog:
    """Communication-loss watchdog in the drive's watchdog time (seconds: wall time, less the
    simulator's own stalls on an AwakeClock); `heard` is the same moment in wall time."""

    def __init__(self, now: float, wall: float) -> None:
        self.armed = False  # armed by network control, disarmed only by the keypad
        self.last_request = now
        self.heard = wall  # wall time (s, time.monotonic) of the last request or arming

    def arm(self, now: float, wall: float) -> None:
        """Network control taken; arming starts a fresh timeout."""
        if not self.armed:
            self.armed = True
            self.feed(now, wall)

    def feed(self, now: float, wall: float) -> None:
        """A valid request arrived (or a new timeout starts counting)."""
        self.last_request, self.heard = now, wall

    def expired(self, timeout: int, w_prev: float, w_now: float) -> float | None:
        """Where in the wall-time step (w_prev, w_now] the watchdog tripped, as a
        fraction 0..1 of the step; None if it did not trip (or is disarmed).

        `timeout` is COMM_LOSS_TIMEOUT in 0.1 s (0 = off).
        """
        if not self.armed or timeout == 0:
            return None
        expiry = self.last_request + 0.1 * timeout
        if expiry > w_now:
            return None
        if w_now > w_prev:
            return min(1.0, max(0.0, (expiry - w_prev) / (w_now - w_prev)))
        return 1.0
