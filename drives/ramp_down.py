"""How long a drive takes to stop: its ramp from a speed (`ramp_down_time`, the emergency ramp's
EMERGENCY_RAMP_FACTOR times shorter), and the default wait for standstill after a stop."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from drives.drive import Drive, DriveParameters, DriveStatus


def standstill_wait(
    drives: Sequence[tuple[Drive, DriveStatus | None]], *, emergency: bool, poll_interval: float
) -> float:
    """Default wait (s) for standstill after a stop of `drives` (each with its latest status, None
    if unread): the drives' own ramp from the present speed (DECEL_TIME, a tenth of it for the
    emergency stop), with margin; a tripped drive coasts at a rate nobody knows: a minute more."""
    worst = 0.0
    for d, st in drives:
        if d.params is None or st is None:
            continue
        t = ramp_down_time(d.params, st.actual, emergency=emergency)
        worst = max(worst, t + (60.0 if st.tripped else 0.0))
    return 1.5 * worst + 2.0 + 4 * poll_interval


#: how many times faster a drive's emergency ramp (OFF3) is than its ramp stop (OFF1, DECEL_TIME)
EMERGENCY_RAMP_FACTOR = 10


def ramp_down_time(params: DriveParameters, speed: float, *, emergency: bool = False) -> float:
    """s a drive's ramp stop takes from `speed` (rad/s) to zero: DECEL_TIME x |speed| / SPEED_SCALE;
    `emergency`: its emergency ramp's (OFF3), EMERGENCY_RAMP_FACTOR times shorter."""
    t = params.decel_time * abs(speed) / params.speed_scale
    return t / EMERGENCY_RAMP_FACTOR if emergency else t
