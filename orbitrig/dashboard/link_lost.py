"""A rig service's `offline` status whose truth is not known: its last will that came with a broker
outage this dashboard saw. The broker publishes a service's last will as it stops and keeps it
until the service reconnects (seconds after the restart), while the run goes on on the rig; the
service's link to the broker was lost, not necessarily the service. The page says such an offline
as LINK_LOST (static/app.js offlineUnknown, its badge and rig selector), and the dashboard
server's refusals say it the same way (orbitrig.dashboard.commands.service_words).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import orbitrig.service.protocol as proto

#: the words for a rig service whose status says offline while that is not known true (the page's too:
#: static/words.js, checked by tests/dashboard/test_dashboard_words.py)
LINK_LOST = "unknown — link lost"
#: s before a broker outage began or after it ended within which a last will heard came with it
#: (static/app.js WILL_NEAR_OUTAGE_MS)
WILL_NEAR_OUTAGE_S = 10.0


@dataclass
class Outage:
    """A broker outage a session saw: monotonic s its link went down, and came back (None: not yet)."""

    start: float
    end: float | None = None


def link_lost(status: dict[str, Any] | None, heard_at: float | None, outage: Outage | None) -> bool:
    """Whether ``status`` (heard at monotonic ``heard_at``) is a last will that came with ``outage``."""
    if status is None or status.get("state") != proto.OFFLINE or not status.get("last_will"):
        return False
    if outage is None or heard_at is None:
        return False
    return heard_at >= outage.start - WILL_NEAR_OUTAGE_S and (
        outage.end is None or heard_at <= outage.end + WILL_NEAR_OUTAGE_S
    )
