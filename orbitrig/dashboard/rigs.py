"""The rigs on one broker, for choosing which one a session watches.

Every rig service retains its status on ``orbitrig/<rig-id>/status`` (``offline`` once
it has gone: its own goodbye or its last will), so one subscription to
``orbitrig/+/status`` lists every rig whose service has ever connected to the broker,
with its state, message and whether it is a last will (the page words each as the Run card's state badge does:
static/buttons.js, stateBadge.word). A dashboard started with a custom ``--prefix`` watches that one tree
and lists no other rig. At most ``limit`` rigs are kept (a broker's retained
statuses are not a bound the dashboard controls), a rig's latest status whole only up to LATEST_KEPT bytes. A
rig whose retained status is cleared (an empty retained payload) is forgotten.
"""

from __future__ import annotations

import time
from typing import Any

import orbitrig.service.protocol as proto

#: characters of a rig's status message kept in the listing (its state is cut to 32)
MESSAGE_KEPT = 256

#: bytes of JSON text of a rig's latest status kept whole (``RigDirectory.latest``, read by a session as the status
#: of a rig chosen until its own subscription is confirmed); a larger one is not kept (the rig chosen waits for its
#: own retained status: a stand-in without run_id or since would be read as its status): 256 rigs, 64 sessions at
#: most keep 64 MB, not 256 × 64 statuses as large as the broker allows
LATEST_KEPT = 4096


class RigDirectory:
    """Rig id -> its latest status's state and message, from the retained statuses under ``orbitrig/``."""

    def __init__(self, prefix: str, limit: int = 256):
        root, _, rig_id = prefix.rpartition("/")
        self.root = root if root == proto.DEFAULT_PREFIX_ROOT and rig_id else None
        self.limit = limit
        self.statuses: dict[str, dict[str, Any]] = {}
        self.heard_at: dict[str, float] = {}  # rig id -> time.monotonic() its status as listed was heard
        #: rig id -> its latest status whole: what a session reads of a rig chosen until its own subscription is
        #: confirmed (orbitrig.dashboard.session.Session._resubscribe)
        self.latest: dict[str, dict[str, Any]] = {}
        #: rig id -> the fields of its latest status kept that came as NaN or infinity (orbitrig.dashboard.finite)
        self.latest_non_finite: dict[str, list[str]] = {}

    @property
    def pattern(self) -> str | None:
        """The subscription that lists the rigs (None: a custom prefix, one rig only)."""
        return None if self.root is None else f"{self.root}/+/status"

    def rig_of(self, topic: str) -> str | None:
        """The rig id of a status topic of the directory, else None."""
        if self.root is None:
            return None
        levels = topic.split("/")
        return levels[1] if len(levels) == 3 and levels[0] == self.root and levels[2] == "status" else None

    def on_status(
        self, rig_id: str, status: dict[str, Any], size: int = 0, non_finite: list[str] | None = None
    ) -> bool:
        """Note a rig's state, message and whether it is its last will (``size``: bytes of the status's JSON text;
        ``non_finite``: its fields that came as NaN or infinity); True when the listing changed."""
        seen = {
            "state": str(status.get("state") or "unknown")[:32],
            "message": str(status.get("message") or "")[:MESSAGE_KEPT],
            "last_will": bool(status.get("last_will")),
        }
        if rig_id not in self.statuses and len(self.statuses) >= self.limit:
            return False
        if size <= LATEST_KEPT:
            self.latest[rig_id], self.latest_non_finite[rig_id] = status, non_finite or []
        else:
            self.latest.pop(rig_id, None)
            self.latest_non_finite.pop(rig_id, None)
        if self.statuses.get(rig_id) == seen:
            return False
        self.statuses[rig_id], self.heard_at[rig_id] = seen, time.monotonic()
        return True

    def forget(self, rig_id: str) -> bool:
        """A rig whose retained status was cleared is no more listed; True when it was."""
        self.latest.pop(rig_id, None)
        self.latest_non_finite.pop(rig_id, None)
        self.heard_at.pop(rig_id, None)
        return self.statuses.pop(rig_id, None) is not None

    def listing(self) -> dict[str, dict[str, Any]]:
        """Rig id -> {"state": ..., "message": ..., "last_will": ...} of its latest status, by id."""
        return {rig_id: dict(seen) for rig_id, seen in sorted(self.statuses.items())}

    def state_of(self, prefix: str) -> str | None:
        """The state of the listed rig whose topic prefix is ``prefix`` (None: not a rig of the listing)."""
        seen, _ = self.heard(prefix)
        return None if seen is None else str(seen["state"])

    def heard(self, prefix: str) -> tuple[dict[str, Any] | None, float | None]:
        """The listed status (state, message, last_will) of the rig whose topic prefix is ``prefix`` and when
        it was heard (time.monotonic()); (None, None): not a rig of the listing."""
        root, _, rig_id = prefix.rpartition("/")
        if self.root is None or root != self.root or rig_id not in self.statuses:
            return None, None
        return self.statuses[rig_id], self.heard_at[rig_id]
