"""What the run says about the A/D board's link: the drops inside a block and between blocks, and a
board gone silent."""

from __future__ import annotations

from typing import TYPE_CHECKING

from daq.stats import AcquisitionStats
from orbitrig.store.layout import point_name
from rigunits import rpm_text

if TYPE_CHECKING:
    from daq.adc import AdcReader

#: wall s without a byte from the A/D board: a failed acquisition is said as the board's silence
SILENT_AFTER_S = 1.0


def _times(n: int) -> str:
    return "once" if n == 1 else f"{n} times"


def block_link_line(point: int, tag: str, stats: AcquisitionStats) -> str | None:
    """One line for a block whose A/D link dropped while it was measured (None: the link held):
    how often, the frames missing from the stream and the revolutions dropped (by reason)."""
    if not stats.link_drops:
        return None
    reasons = ", ".join(f"{why} {n}" for why, n in sorted(stats.drop_reasons.items()))
    return (
        f"point {point_name(point)} [{tag}]: A/D link dropped {_times(stats.link_drops)} during the block: "
        f"{stats.frames_lost} frames lost, {stats.revolutions_dropped} revolutions dropped"
        + (f" ({reasons})" if reasons else "")
        + f"; the block averaged {stats.revolutions_used} good revolutions"
    )


def between_blocks_line(point: int, tag: str, drops: int) -> str:
    """One line for `drops` A/D link drops since the block before (or the rig's opening), said as
    the block `tag` starts: no data of a block was lost."""
    return (
        f"point {point_name(point)} [{tag}]: A/D link dropped {_times(drops)} before the block "
        "(no block under way: no data lost)"
    )


def abandoned_attempt_line(point: int, tag: str, stats: AcquisitionStats) -> str | None:
    """One line for an attempt at the block `tag` that a suspension abandoned while the A/D link
    dropped in it (None: the link held): its data is discarded and the block measured again after
    the suspension, so the drop is said here or never (the counts are those seen until then)."""
    if not stats.link_drops:
        return None
    return (
        f"point {point_name(point)} [{tag}]: A/D link dropped {_times(stats.link_drops)} during an attempt "
        f"at the block that the suspension abandoned: {stats.frames_lost} frames lost, "
        f"{stats.revolutions_dropped} revolutions dropped until then; the block is measured again"
    )


def board_silence(adc: AdcReader | None) -> str | None:
    """What a silent A/D board looks like now (no byte for SILENT_AFTER_S and more), or None:
    how long, and whether its link is down (its error, the reconnect attempts so far)."""
    return None if adc is None or adc.silent_s < SILENT_AFTER_S else adc.silence()


#: fraction: an orbit measured this close to the spin's set speed turns at it; the swap is asked of
#: only when the block's own orbit speed is more than twice that from the spin's (the plan refuses
#: ratios within 0.01 of 1 but runs 0.98..0.99 and 1.01..1.02, where a lagging orbit drive reads so)
SAME_SPEED = 0.01


def orbit_off_hint(measured: float | None, spin: float, orbit: float, spin_id: int, orbit_id: int) -> str:
    """What to check when revolutions came at an orbit speed off the set one (`measured`, rad/s, by
    the timing disk; `spin`, `orbit`: the point's and the block's set speeds, rad/s): at the spin's speed,
    far from the block's own, the two drives' device ids are swapped in rig.toml, else the orbit
    drive is not at the speed it was given; "" without a measured speed."""
    if measured is None:
        return ""
    ids = f"[drives] spin_id = {spin_id}, orbit_id = {orbit_id} in rig.toml"
    at_spin = spin > 0 and abs(measured / spin - 1) <= SAME_SPEED
    if at_spin and abs(abs(orbit) / spin - 1) > 2 * SAME_SPEED:
        return (
            f"; the orbit spindle turns at the spin's set speed ({rpm_text(spin)}): are the drives' device ids "
            f"swapped ({ids})? check which drive answers at which id (the drive's own parameter)"
        )
    return f"; the orbit spindle is not at the speed its drive was given: is {ids} the orbit drive's id?"


def acquisition_hint(heard: bool) -> str:
    """The end of an acquisition failure's line after the error's own words: where to look when
    nothing came from the board (`heard` False), else ""."""
    return "" if heard else "; orbit trigger lost or A/D link down?"
