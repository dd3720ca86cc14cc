"""Counters of one acquisition block: frames, bytes, revolutions and why any were dropped.

Drop reasons (``drop_reasons`` keys) used by :mod:`daq.revolutions` and :mod:`daq.adc`:

``corrupt``          bytes were skipped before a frame of the revolution (bad CRC,
                     garbage, a damaged header): part of it never arrived intact
``seq_gap``          a frame counter jump inside the revolution (frame lost)
``overrun``          a frame of the revolution carries the OVERRUN flag
``missing_trigger``  frames of a revolution without its TRIGGER frame
``incomplete``       a new TRIGGER frame arrived before all 360 slots
``rev_mismatch``     the revolution counter changed inside the revolution
``slot_gap``         slots not contiguous although the frame counter is
``mode_mismatch``    frame mode / samples per slot differ from the configured scan
``link_drop``        the link dropped while the revolution was arriving
``bad_clock``        the board clock (t_us) stalled or jumped during the revolution,
                     or the orbit speed changed by more than 5 % within it
``off_speed``        the revolution's measured orbit speed is off the set one by more
                     than the averaging rule's tolerance (daq.averaging_rule.AveragingRule)

Frame errors (``frame_errors`` keys, from :mod:`daq.frames`): ``crc``, ``version``,
``header`` (reserved flag bits, slot or length fields outside the spec).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass
class AcquisitionStats:
    frames_good: int = 0
    frames_bad: int = 0
    bytes_skipped: int = 0
    revolutions_used: int = 0
    revolutions_dropped: int = 0
    drop_reasons: dict[str, int] = field(default_factory=dict)
    frame_errors: dict[str, int] = field(default_factory=dict)
    link_drops: int = 0
    frames_lost: int = 0  # frames missing from the stream (frame counter jumps): lost, dropped or unreadable

    def copy(self) -> "AcquisitionStats":
        return AcquisitionStats(
            self.frames_good,
            self.frames_bad,
            self.bytes_skipped,
            self.revolutions_used,
            self.revolutions_dropped,
            dict(self.drop_reasons),
            dict(self.frame_errors),
            self.link_drops,
            self.frames_lost,
        )

    def since(self, earlier: "AcquisitionStats") -> "AcquisitionStats":
        """Counts accumulated after the snapshot ``earlier`` (a block's own statistics)."""

        def sub(a: dict[str, int], b: dict[str, int]) -> dict[str, int]:
            return {k: v - b.get(k, 0) for k, v in a.items() if v - b.get(k, 0)}

        return AcquisitionStats(
            self.frames_good - earlier.frames_good,
            self.frames_bad - earlier.frames_bad,
            self.bytes_skipped - earlier.bytes_skipped,
            self.revolutions_used - earlier.revolutions_used,
            self.revolutions_dropped - earlier.revolutions_dropped,
            sub(self.drop_reasons, earlier.drop_reasons),
            sub(self.frame_errors, earlier.frame_errors),
            self.link_drops - earlier.link_drops,
            self.frames_lost - earlier.frames_lost,
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "frames_good": self.frames_good,
            "frames_bad": self.frames_bad,
            "bytes_skipped": self.bytes_skipped,
            "revolutions_used": self.revolutions_used,
            "revolutions_dropped": self.revolutions_dropped,
            "drop_reasons": dict(self.drop_reasons),
            "frame_errors": dict(self.frame_errors),
            "link_drops": self.link_drops,
            "frames_lost": self.frames_lost,
        }


#: each drop reason as an operator reads it, of the revolutions it dropped
DROP_WORDS = {
    "corrupt": "with corrupt data (bytes skipped)",
    "seq_gap": "with a frame lost",
    "overrun": "with an A/D overrun",
    "missing_trigger": "without their trigger frame",
    "incomplete": "incomplete (a new trigger before all 360 slots)",
    "rev_mismatch": "with the revolution counter changing inside",
    "slot_gap": "with slots missing",
    "mode_mismatch": "in another A/D mode than the one configured",
    "link_drop": "cut by a link drop",
    "bad_clock": "with the board clock stalled or jumping, or the orbit speed unsteady",
    "off_speed": "at an orbit speed off the set one",
}


def dropped_words(stats: AcquisitionStats) -> str:
    """The revolutions ``stats`` dropped, in words, most frequent reason first: "4 revolutions
    dropped: 3 at an orbit speed off the set one, 1 with a frame lost" ("no revolution dropped")."""
    n = stats.revolutions_dropped
    if not n:
        return "no revolution dropped"
    reasons = sorted(stats.drop_reasons.items(), key=lambda kv: (-kv[1], kv[0]))
    why = ", ".join(f"{k} {DROP_WORDS.get(reason, reason)}" for reason, k in reasons)
    return f"{n} revolution{'s' if n != 1 else ''} dropped" + (f": {why}" if why else "")


def count(reasons: dict[str, int], reason: str, n: int = 1) -> None:
    """Add ``n`` to ``reasons[reason]``."""
    reasons[reason] = reasons.get(reason, 0) + n
