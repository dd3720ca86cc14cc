"""What the run says about the A/D board's link: the drops inside a block and between blocks, and a
board gone silent."""

from __future__ import annotations

from typing import TYPE_CHECKING

from daq.stats import AcquisitionStats
from orbitrig.store.layout import point_name

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
