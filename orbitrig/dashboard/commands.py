"""The page's commands as the dashboard server takes them, and the words of their outcomes.

A command from the page names the rig the page shows (``rig``: its topic prefix); the server
refuses it when the session watches another rig by now (another tab of the same browser
chose one), so a command never goes to a rig the person is not looking at. Stop and abort are
the exception (an abort always gets through): they go to the rig the page shows, when it is
one the dashboard knows (:func:`rig_for`); their outcome names that rig.

What the outcome of a command says is only what is known (docs/dashboard.md):

- "refused: not authorised" only when the broker said so (the PUBACK's reason code 135,
  MQTT 5: the ACL refused the publish);
- without the service's reply in time, the outcome is *unknown*: the command may have been
  carried out (a slow or hung service) or not (a service gone). The text says what the page
  should do, and the status change seen since the click, if any.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import orbitrig.service.protocol as proto
from orbitrig.dashboard.link_lost import LOST_IN_OUTAGE, RUN_MAY_GO_ON, SERVICE_LINK_LOST

#: Commands the page may send (every command of the contract) and the fields each takes besides
#: ``cmd`` and ``rig``.
PAGE_COMMANDS = proto.COMMAND_FIELDS
NOT_AUTHORISED = "refused: not authorised"
#: the words of the refusals and outcomes the page says too, before or without asking the server (its copies:
#: static/words.js Refusal, checked by tests/dashboard/test_dashboard_words.py): the rig service whose status
#: says offline; what is left to do against drives that may turn; what to do when an outcome is not known;
#: a request the dashboard cannot send for want of its broker link
SERVICE_OFFLINE = "the rig service is offline"
EMERGENCY_STOP = "use the rig's emergency stop"
EMERGENCY = f"if it is still running {EMERGENCY_STOP}"
CHECK_STATE = "check the rig's state"
OUTCOME_UNKNOWN = "the outcome is unknown"
NO_BROKER = "no connection to the broker: try again when it is back"
#: a command other than stop and abort while the rig's service is offline: the broker would keep it
#: for the service, which would carry it out when it is back (drives moving with nobody expecting it)
NOT_SENT_OFFLINE = f"not sent: {SERVICE_OFFLINE}"


def service_words(lost: bool) -> str:
    """The rig service whose status says offline, as known: SERVICE_OFFLINE, or, its last will that came
    with a broker outage (``lost``: orbitrig.dashboard.link_lost), that its state is not known
    ('the rig service's state is unknown — link lost'), as the page's badge says it."""
    return SERVICE_LINK_LOST if lost else SERVICE_OFFLINE


def not_sent_offline(lost: bool) -> str:
    """A command other than stop and abort refused while the rig's service is offline (NOT_SENT_OFFLINE),
    or while its state is not known (``lost``): the broker would keep it until the service is back."""
    if not lost:
        return NOT_SENT_OFFLINE
    return f"not sent: {service_words(True)} (its {LOST_IN_OUTAGE}; {RUN_MAY_GO_ON}): try again when it reconnects"


#: a stop or abort of a page showing a rig the dashboard does not know (no rig of its listing)
UNKNOWN_RIG = f"reload the page; {EMERGENCY}"


def rig_mismatch(shown: Any, watched: str) -> str | None:
    """Why a request of a page showing rig ``shown`` must not go to the rig watched now (None: it may)."""
    if not isinstance(shown, str) or not shown:
        return "the page did not say which rig it shows: reload the page"
    if shown != watched:
        return f"not sent: this page shows rig {shown} but the session now watches {watched}: reload the page"
    return None


def rig_for(name: str, shown: Any, watched: str, known: Callable[[str], bool]) -> tuple[str, str | None]:
    """The rig (topic prefix) command ``name`` of a page showing ``shown`` goes to, or why it is not sent:
    the rig watched; for a stop or abort also the rig the page shows, when ``known`` (the dashboard's)."""
    wrong_rig = rig_mismatch(shown, watched)
    if wrong_rig is None:
        return watched, None
    if name not in proto.ALWAYS_ACCEPTED or not isinstance(shown, str) or not shown:
        return "", wrong_rig
    if not known(shown):
        return "", f"not sent: this page shows rig {shown}, which this dashboard does not know: {UNKNOWN_RIG}"
    return shown, None


def command_body(
    request: dict, user: str, watched: str, known: Callable[[str], bool]
) -> tuple[dict[str, str], str, str | None]:
    """The command to publish for a page's request and the rig (topic prefix) it goes to (rig_for), or the
    reason it is refused (then ``{}``)."""
    name = request.get("cmd")
    cmd = proto.COMMAND_WORDS.get(name) if isinstance(name, str) else None
    if cmd is None:
        return {}, "", f"unknown command {name!r}"
    prefix, wrong_rig = rig_for(cmd, request.get("rig"), watched, known)
    if wrong_rig is not None:
        return {}, "", wrong_rig
    body: dict[str, str] = {"cmd": cmd, "by": user}  # the signed-in user, recorded in the run
    for field in PAGE_COMMANDS[cmd]:
        value = request.get(field)
        if not isinstance(value, str) or not value:
            return {}, "", f"field {field!r} is missing"
        body[field] = value
    return body, prefix, None


def refused(user: str, what: str) -> str:
    """The broker refused the publish (its ACL): ``what`` the user may not do."""
    return f"{NOT_AUTHORISED} — user {user!r} may not {what} (the broker refused it)"


def offline_now(name: str, lost: bool = False) -> str:
    """A stop or abort while the rig's service is offline (``lost``: its state not known, `service_words`):
    nothing will carry it out."""
    article = "an" if name == proto.RunCommand.ABORT else "a"
    return f"{service_words(lost)}: the broker does not keep {article} {name} for it; {EMERGENCY_STOP}"


def urgent_no_broker(name: str) -> str:
    """A stop or abort while the dashboard itself has no broker connection: nothing went."""
    return f"{name.upper()} NOT SENT: the dashboard has no connection to the broker; {EMERGENCY_STOP}"


def late_reply(name: str, reply: dict, after_s: float, rig: str | None = None) -> dict:
    """The outcome of a stop or abort whose reply came ``after_s`` s after the click, past the reply
    timeout (its earlier outcome said unknown): kept and shown as an outcome of its own (``rig``: the
    rig it went to, when the session watched another)."""
    late = f"late reply, {after_s:.0f} s after the click"
    error, detail = reply.get("error"), reply.get("detail")
    outcome: dict[str, Any] = {"cmd": name, "ok": bool(reply.get("ok")), "late": True, "at": proto.iso8601()}
    if rig:
        outcome["rig"] = rig
    if outcome["ok"]:
        outcome.update(error=None, detail=f"{late}" + (f": {detail}" if detail else ""))
    else:
        outcome["error"] = f"{late}: {error or 'failed'}"
    return outcome


def unknown(name: str, why: str, change: str | None) -> str:
    """No answer: the outcome of ``name`` is unknown (``why``: what did not come)."""
    advice = f"{CHECK_STATE}; {EMERGENCY}" if name in proto.ALWAYS_ACCEPTED else CHECK_STATE
    seen = f" ({change})" if change else ""
    return f"{why}: {OUTCOME_UNKNOWN}{seen} — {advice}"


def status_change(before: dict | None, after: dict | None) -> str | None:
    """The status change seen between the click (``before``) and now, in words (None: none)."""
    if after is None or after is before:
        return None
    state = after.get("state")
    if before is None or before.get("state") != state:
        return f"since the click the status went to {state}"
    message = str(after.get("message") or "")[:120]
    return f"since the click a new status came: {state}" + (f", {message}" if message else "")
