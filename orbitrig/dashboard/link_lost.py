"""A rig service's `offline` status whose truth is not known: its last will that came with a broker
outage this dashboard saw. The broker publishes a service's last will as it stops and keeps it
until the service reconnects (seconds after the restart), while the run goes on on the rig; the
service's link to the broker was lost, not necessarily the service. Until WILL_NEAR_OUTAGE_S after
the dashboard's own link is back: a service still away then (its status still the will) is read
as the contract reads a will, `offline`, its message the will's reason. The session decides
(orbitrig.dashboard.incoming: each status and rig listed sent with ``link_lost``, sent again as
the outage begins, ends and its grace ends); the page says such an offline as LINK_LOST (static/app.js
offlineUnknown, its badge and rig selector), and the dashboard server's refusals say it the same
way (orbitrig.dashboard.commands.service_words).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import orbitrig.service.protocol as proto

#: the words for a rig service whose status says offline while that is not known true (the page's too:
#: static/words.js, checked by tests/dashboard/test_dashboard_words.py)
LINK_LOST = "unknown — link lost"
#: s before a broker outage began within which a last will heard came with it, and s after it ended
#: (the dashboard's link back) until which such a will is read as LINK_LOST: time for the service to
#: reconnect; a will still the status then is read `offline`
WILL_NEAR_OUTAGE_S = 10.0
#: the rig service whose offline is read LINK_LOST, why, and what that leaves possible: the words of the page
#: (static/words.js: its badge's tooltip, message, banner, buttons' tooltips) and of the dashboard server's
#: refusals (orbitrig.dashboard.commands), checked alike by tests/dashboard/test_dashboard_words.py
SERVICE_LINK_LOST = f"the rig service's state is {LINK_LOST}"
LOST_IN_OUTAGE = "link to the broker was lost in a broker outage"
RUN_MAY_GO_ON = "the run may go on on the rig"


@dataclass
class Outage:
    """A broker outage a session saw: monotonic s its link went down, and came back (None: not yet)."""

    start: float
    end: float | None = None


def link_lost(
    status: dict[str, Any] | None, heard_at: float | None, outage: Outage | None, now: float | None = None
) -> bool:
    """Whether ``status`` (heard at monotonic ``heard_at``) is a last will that came with ``outage`` and is
    read so at monotonic ``now`` (default: the present): until WILL_NEAR_OUTAGE_S after the outage ended."""
    if status is None or status.get("state") != proto.OFFLINE or not status.get("last_will"):
        return False
    if outage is None or heard_at is None:
        return False
    now = time.monotonic() if now is None else now
    return heard_at >= outage.start - WILL_NEAR_OUTAGE_S and (
        outage.end is None or max(heard_at, now) <= outage.end + WILL_NEAR_OUTAGE_S
    )
