"""The dashboard's times (s) and limits by default, as `orbitrig dashboard` offers them and
DashboardSettings (session.py) and ThrottlePolicy (throttle.py) take them: no imports, so that
the command line reads them at its start without loading the server."""

from __future__ import annotations

IDLE_TIMEOUT_S = 1800.0  # s without activity that end a session
REPLY_TIMEOUT_S = 3.0  # s a command waits for the service's reply before its outcome is unknown
#: s without a message to a page after which a tick goes (--tick; the page calls its view stale
#: after 7/3 of it, ~7 s, and gives its feed up after 4 of it, 12 s)
TICK_S = 3.0
REQUEST_TIMEOUT_S = 10.0  # s a request's head and body must arrive within
SESSIONS_PER_USER = 4  # sessions one broker user may hold; a new sign-in ends the oldest
MAX_SESSIONS = 64  # sessions of the server, all users together (also the most --sessions-per-user takes)
SIGNIN_DELAY_S = 0.25  # s before the next sign-in after a refused one (doubles with every refusal)
LOCK_AFTER = 5  # refused sign-ins that lock a user name out
LOCKOUT_S = 300.0  # s a lockout lasts
