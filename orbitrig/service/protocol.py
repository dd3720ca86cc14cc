"""The MQTT contract of docs/protocols/mqtt.md as pure code (no I/O).

Topic names under the prefix ``orbitrig/<rig_id>``, the commands (parsed by
pydantic models with precise reasons in orbitrig.service.command_models, named here too),
and the payload builders for status, progress, result and reply. Payloads are UTF-8 JSON objects.

| topic               | QoS | retained | builder            |
|---------------------|-----|----------|--------------------|
| ``<prefix>/status`` | 1   | yes      | :func:`status_payload` (also the last will, state ``offline``; a run's names its latest progress: this project's extension) |
| ``<prefix>/progress`` | 0 | no       | :func:`progress_payload` |
| ``<prefix>/result`` | 1   | no       | :func:`result_payload` |
| ``<prefix>/cmd``    | 1   | no       | parsed by :func:`parse_command` (orbitrig.service.command_models) |
| ``<prefix>/abort``  | 1 (subscribed at 0) | no | stop and abort only, parsed alike |
| ``<prefix>/reply``  | 1   | no       | :func:`reply_ok`, :func:`reply_error` |
| ``<prefix>/note``   | 1   | yes      | :func:`note_payload` (the run's warnings; this project's extension) |
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import numbers
from dataclasses import dataclass
from typing import Any, Final, Literal

from orbitrig.run.events import ProgressEvent
from orbitrig.run.states import CLEARED, PAUSE_REQUESTED, SUSPENDED, RunState  # noqa: F401 - the status words
from orbitrig.store.layout import point_name
from orbitrig.service.command_json import MAX_COMMAND_BYTES, CommandError  # noqa: F401 - part of this contract's names
from orbitrig.service.command_models import (  # noqa: F401 - part of this contract's names
    ALWAYS_ACCEPTED,
    COMMAND_FIELDS,
    COMMAND_WORDS,
    BareCommand,
    Command,
    CommandName,
    ConfirmCommand,
    Query,
    RunCommand,
    StartCommand,
    is_matrix_name,
    parse_command,
)
from rigunits import utc_iso

DEFAULT_PREFIX_ROOT = "orbitrig"

#: States of ``<prefix>/status`` (docs/protocols/mqtt.md): the engine's, and ``offline``
#: (the last will, or the service leaving).
OFFLINE: Final = "offline"
STATES = (*RunState, OFFLINE)
#: The state a status says, as the service keeps it: a RunState, or OFFLINE.
StatusState = RunState | Literal["offline"]
#: a run has ended in these states (its statuses name no progress; a dashboard forgets its view)
ENDED: Final = (RunState.IDLE, RunState.FAULTED)

#: QoS and retain flag of each topic (docs/protocols/mqtt.md).
QOS_STATUS, QOS_PROGRESS, QOS_RESULT, QOS_REPLY, QOS_CMD = 1, 0, 1, 1, 1
QOS_LIVE = 0  # <prefix>/live, built by orbitrig.service.live
QOS_NOTE = 1  # <prefix>/note: the run's warnings (this project's extension)
#: The service subscribes to <prefix>/abort at QoS 0: the broker then passes such a
#: message on at once instead of queueing it behind the QoS 1 commands waiting for
#: the service (docs/protocols/mqtt.md, "Stop and abort under load").
QOS_ABORT_SUBSCRIPTION = 0

#: what comes before each of the run's grouped warnings in its closing status's message
#: (``run completed; warning: ...; warning: ...``)
GROUPED_WARNING: Final = "; warning: "

_TOPIC_LEVEL_FORBIDDEN = set("/+#\x00")


# -- topics -------------------------------------------------------------------


@dataclass(frozen=True)
class Topics:
    """The topic tree of one rig service."""

    prefix: str

    @property
    def status(self) -> str:
        return f"{self.prefix}/status"

    @property
    def progress(self) -> str:
        return f"{self.prefix}/progress"

    @property
    def result(self) -> str:
        return f"{self.prefix}/result"

    @property
    def live(self) -> str:
        return f"{self.prefix}/live"

    @property
    def cmd(self) -> str:
        return f"{self.prefix}/cmd"

    @property
    def ack(self) -> str:
        """Acknowledgements of latched alarms (dashboards, operators): docs/protocols/mqtt.md."""
        return f"{self.prefix}/ack"

    @property
    def abort(self) -> str:
        """stop and abort only, subscribed at QoS 0: never queued behind other commands."""
        return f"{self.prefix}/abort"

    @property
    def reply(self) -> str:
        return f"{self.prefix}/reply"

    @property
    def note(self) -> str:
        """The run's warnings, one message each (this project's extension): docs/protocols/mqtt.md."""
        return f"{self.prefix}/note"


def validate_rig_id(rig_id: str) -> str:
    """Return ``rig_id`` if it is usable as one topic level, else raise ValueError."""
    if not isinstance(rig_id, str) or not rig_id:
        raise ValueError("rig id must be a non-empty string")
    bad = sorted(_TOPIC_LEVEL_FORBIDDEN.intersection(rig_id))
    if bad:
        raise ValueError(f"rig id {rig_id!r} contains characters not allowed in a topic level: {bad}")
    if len(rig_id) > 64:
        raise ValueError(f"rig id {rig_id!r} is longer than 64 characters")
    return rig_id


def topics(rig_id: str, prefix: str | None = None) -> Topics:
    """Topics under ``prefix`` (default ``orbitrig/<rig_id>``).

    A custom prefix may have several levels but no wildcard and no empty level.
    """
    if prefix is None:
        return Topics(f"{DEFAULT_PREFIX_ROOT}/{validate_rig_id(rig_id)}")
    levels = prefix.split("/")
    if not prefix or any(not lv or set(lv) & set("+#\x00") for lv in levels):
        raise ValueError(f"topic prefix {prefix!r} must be non-empty levels without wildcards")
    return Topics(prefix)


# -- payloads -----------------------------------------------------------------


def iso8601(when: _dt.datetime | float | str | None = None) -> str:
    """ISO-8601 UTC text for a datetime, a POSIX time (s) or now; text passes through."""
    return when if isinstance(when, str) else utc_iso(when)


def _jsonable(value: Any) -> Any:
    """Plain JSON values: numpy scalars and arrays to numbers and lists,
    non-finite floats to null, complex to ``[re, im]``, datetimes to the timestamp text of
    ``rigunits.utc_iso`` (as ``since``), paths to text."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, bool) or value is None or isinstance(value, (int, str)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, complex):
        return [_jsonable(value.real), _jsonable(value.imag)]
    tolist = getattr(value, "tolist", None)  # numpy scalar or array
    if callable(tolist):
        return _jsonable(tolist())
    if isinstance(value, _dt.datetime):
        return utc_iso(value)  # the house timestamp (a naive datetime is local time)
    if isinstance(value, _dt.date):
        return value.isoformat()
    return str(value)


def dumps(obj: dict[str, Any]) -> bytes:
    """Compact UTF-8 JSON of ``obj`` (made JSON-safe first)."""
    return json.dumps(_jsonable(obj), separators=(",", ":"), ensure_ascii=False, allow_nan=False).encode("utf-8")


def status_payload(
    state: str,
    run_id: str | None = None,
    since: _dt.datetime | float | str | None = None,
    message: str | None = None,
    extra: dict[str, Any] | None = None,
    progress: ProgressEvent | None = None,
) -> bytes:
    """``{"state", "run_id", "since", "message"}`` for ``<prefix>/status``, plus ``extra``
    (while ``waiting``: ``step`` and ``settings``, see orbitrig.service.live) and, given ``progress``
    (the run's latest), ``"progress"``: the object of its progress message (:func:`progress_fields`;
    this project's extension: a subscriber that comes later learns where the run is)."""
    if state not in STATES:
        raise ValueError(f"unknown state {state!r} (one of {', '.join(STATES)})")
    return dumps(
        {
            "state": state,
            "run_id": run_id,
            "since": iso8601(since),
            "message": "" if message is None else str(message),
            **(extra or {}),
            **({} if progress is None else {"progress": progress_fields(progress)}),
        }
    )


def progress_fields(event: ProgressEvent) -> dict[str, Any]:
    """``{"run_id", "point", "points", "frequency", "frequencies", "revolutions", "eta_s",
    "point_label", "block_revolutions", "fraction"}`` of the run engine's progress (``eta_s`` in s,
    null when unknown); extensions: ``point_label``, the operating point's label, as its result's
    ``label``; ``block_revolutions``, the block's target revolutions (0 before the point's first
    block); ``fraction``, how much of the run's points is measured (0 to 1, the event's: a block
    acquired counts whole). The payload of ``<prefix>/progress`` and a run's status's ``progress``."""
    return {
        "run_id": event.run_id,
        "point": event.point,
        "points": event.points,
        "frequency": event.frequency,
        "frequencies": event.frequencies,
        "revolutions": event.revolutions,
        "eta_s": event.eta_s,
        "point_label": event.point_label,
        "block_revolutions": event.block_revolutions,
        "fraction": round(event.fraction, 4),
    }


def progress_payload(event: ProgressEvent) -> bytes:
    """:func:`progress_fields` for ``<prefix>/progress``."""
    return dumps(progress_fields(event))


def result_payload(run_id: str | None, payload: dict[str, Any]) -> bytes:
    """One completed operating point (its settings and identified coefficients)
    for ``<prefix>/result``; ``run_id`` is added when the payload lacks it, and ``point_name``,
    the name of its 0-based ``index`` (or ``point``) in the run files (point_name: 3 -> '0003')."""
    out = {"run_id": run_id, **payload} if "run_id" not in payload else dict(payload)
    index = next((out[k] for k in ("index", "point") if k in out), None)
    if isinstance(index, numbers.Integral) and not isinstance(index, bool):
        out["point_name"] = point_name(int(index))
    return dumps(out)


def note_payload(
    run_id: str | None,
    severity: str,
    message: str,
    at: str,
    withheld: int = 0,
    kinds: dict[str, int] | None = None,
    said: int | None = None,
    closing: bool = False,
) -> bytes:
    """``{"run_id", "severity", "message", "at"}`` for ``<prefix>/note`` (published retained); with
    ``"said"``: the run's warnings so far, this one and those withheld included; with ``"withheld"``
    and ``"withheld_kinds"`` (``kinds``, kind -> count): how many warnings before this one the service
    did not publish, and of which kinds (orbitrig.service.note_budget); with ``"closing": true``: the
    run's closing note, whose message says those it counts (none follows it in the run)."""
    out: dict[str, Any] = {"run_id": run_id, "severity": severity, "message": message, "at": at}
    if said is not None:
        out["said"] = said
    if withheld:
        out["withheld"] = withheld
        if kinds:
            out["withheld_kinds"] = kinds
    if closing:
        out["closing"] = True
    return dumps(out)


def reply_ok(cid: str | None, detail: str | None = None) -> bytes:
    """``{"id", "ok": true}`` for ``<prefix>/reply``; with ``"detail"``: what the command did,
    when the reply says it (an abort that no run carried out; when a pause takes effect)."""
    return dumps({"id": cid, "ok": True} if detail is None else {"id": cid, "ok": True, "detail": detail})


def reply_error(cid: str | None, error: str) -> bytes:
    """``{"id", "ok": false, "error"}`` for ``<prefix>/reply``."""
    return dumps({"id": cid, "ok": False, "error": str(error)})
