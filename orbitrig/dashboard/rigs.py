"""The rigs on one broker, for choosing which one a session watches.

Every rig service retains its status on ``orbitrig/<rig-id>/status`` (``offline`` once
it has gone: its own goodbye or its last will), so one subscription to
``orbitrig/+/status`` lists every rig whose service has ever connected to the broker,
with its state. A dashboard started with a custom ``--prefix`` watches that one tree
and lists no other rig. At most ``limit`` rigs are kept (a broker's retained
statuses are not a bound the dashboard controls).
"""

from __future__ import annotations

from typing import Any

import orbitrig.service.protocol as proto


class RigDirectory:
    """Rig id -> latest state, from the retained statuses under ``orbitrig/``."""

    def __init__(self, prefix: str, limit: int = 256):
        root, _, rig_id = prefix.rpartition("/")
        self.root = root if root == proto.DEFAULT_PREFIX_ROOT and rig_id else None
        self.limit = limit
        self.states: dict[str, str] = {}

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

    def on_status(self, rig_id: str, status: dict[str, Any]) -> bool:
        """Note a rig's state; True when the listing changed."""
        state = str(status.get("state") or "unknown")[:32]
        if self.states.get(rig_id) == state or (rig_id not in self.states and len(self.states) >= self.limit):
            return False
        self.states[rig_id] = state
        return True

    def listing(self) -> dict[str, str]:
        return dict(sorted(self.states.items()))

    def state_of(self, prefix: str) -> str | None:
        """The state of the listed rig whose topic prefix is ``prefix`` (None: not a rig of the listing)."""
        root, _, rig_id = prefix.rpartition("/")
        return self.states.get(rig_id) if self.root is not None and root == self.root else None
