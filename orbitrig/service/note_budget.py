"""How many of the run's warnings the rig service publishes on ``<prefix>/note``: at most
``BURST`` in any ``WINDOW_S`` s. The engine says a warning at most once per block, but a run of
short blocks (or a speed-up) could say many; each one is a QoS 1 message that the broker queues for
every subscriber whose link is down (a dashboard's session: up to ``max_queued_messages`` per
client, beyond which mosquitto drops messages silently). At 10 a minute a dashboard's 600 s
catch-up (its session expiry) holds at most 100 of them. A warning beyond the budget is not published (run.log and
run.h5 keep it); the next one published says how many were withheld before it, and of which
kinds (orbitrig.run.events.NoteKind); those still withheld when the run ends are said by its closing note, and the
run's totals by its closing status (docs/protocols/mqtt.md)."""

from __future__ import annotations

import collections
import time
from collections.abc import Callable

from orbitrig.run.events import NoteKind

BURST = 10  # warnings published at most in any WINDOW_S
WINDOW_S = 60.0  # s


class NoteBudget:
    """The sliding window of the warnings published (``clock``: s, monotonic), and the run's counts:
    ``said`` (every warning), ``withheld_total`` (those not published, by kind in ``totals``) and, since the last one
    published, ``withheld`` and ``withheld_kinds`` (kind -> count); the counts are the kinds' sums."""

    def __init__(self, burst: int = BURST, window_s: float = WINDOW_S, clock: Callable[[], float] = time.monotonic):
        self.burst, self.window_s, self._clock = burst, window_s, clock
        self._sent: collections.deque[float] = collections.deque()
        self.said = 0
        self.withheld_kinds: collections.Counter[NoteKind] = collections.Counter()  # since the last one published
        self._withheld_by_kind: collections.Counter[NoteKind] = collections.Counter()  # the run's
        self.closed = False  # the run's closing note said: nothing more goes out
        self.released_kinds: dict[str, int] = {}  # the kinds of those the last take_withheld returned

    def admit(self, kind: NoteKind = NoteKind.OTHER) -> int | None:
        """None when the next warning (of ``kind``) is over the budget (counted as withheld); else how
        many were withheld before it (then reset; their kinds in ``released_kinds``)."""
        now = self._clock()
        self.said += 1
        while self._sent and now - self._sent[0] >= self.window_s:
            self._sent.popleft()
        if len(self._sent) >= self.burst:
            self.withheld_kinds[kind] += 1
            self._withheld_by_kind[kind] += 1
            return None
        self._sent.append(now)
        return self.take_withheld()[0]

    def take_withheld(self) -> tuple[int, dict[str, int]]:
        """(how many, by kind) withheld since the last warning published, then forgotten (said once);
        ``released_kinds`` keeps the kinds (those of the warning ``admit`` last let through)."""
        self.released_kinds = _by_kind(self.withheld_kinds)
        out = (self.withheld, self.released_kinds)
        self.withheld_kinds = collections.Counter()
        return out

    @property
    def withheld(self) -> int:
        """Warnings not published since the last one that was."""
        return self.withheld_kinds.total()

    @property
    def withheld_total(self) -> int:
        """The run's warnings not published."""
        return self._withheld_by_kind.total()

    def totals(self) -> dict[str, object]:
        """The run's counts for its closing status: ``said``, ``published``, ``withheld`` and
        ``withheld_kinds`` (kind -> count)."""
        return {
            "said": self.said,
            "published": self.said - self.withheld_total,
            "withheld": self.withheld_total,
            "withheld_kinds": _by_kind(self._withheld_by_kind),
        }


def _by_kind(counts: collections.Counter[NoteKind]) -> dict[str, int]:
    """kind's words -> count, in the order of the words (as the payloads carry them)."""
    return {kind.value: n for kind, n in sorted(counts.items())}
