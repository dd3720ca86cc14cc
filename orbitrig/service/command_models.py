"""The commands of ``<prefix>/cmd`` and ``<prefix>/abort`` (docs/protocols/mqtt.md, "Commands"):
their names (:data:`CommandName`), their fields as strict pydantic models, and
:func:`parse_command`, which reads a payload into a validated :class:`Command` or refuses it
with the reply's reason. Part of the MQTT contract (orbitrig.service.protocol names it all);
no I/O."""

from __future__ import annotations

import re
from dataclasses import dataclass
from enum import StrEnum
from typing import Annotated, Any, Literal, Union, get_args

from pydantic_core import ErrorDetails
from pydantic import BaseModel, ConfigDict, Field, StringConstraints, TypeAdapter, ValidationError, field_validator

from orbitrig.run.states import RunCommand
from orbitrig.service.command_json import (
    MAX_ID_CHARS,
    STOP_OR_ABORT,
    CommandError,
    echoable_id,
    id_problems,
    read_object,
    stop_word,
    cmd_problem,
    not_a_string,
)

_MATRIX_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")
_STEP_ID = re.compile(r"[^\x00-\x1f]{1,128}")


class Query(StrEnum):
    """The command that changes nothing: the service answers it (the status again)."""

    STATUS = "status"


#: A command's name: one that changes a run (orbitrig.run.states.RunCommand) or the query;
#: on the wire the lowercase word of its value.
CommandName = RunCommand | Query


@dataclass(frozen=True)
class Command:
    """A validated command. ``matrix`` is set for ``start``, ``step`` for ``confirm``."""

    cmd: CommandName
    id: str | None  # None only for a stop/abort whose id could not be read
    matrix: str | None = None
    step: str | None = None
    ignored: tuple[str, ...] = ()  # stop/abort: the problems that were overlooked
    by: str | None = None  # who sent it, as the command says (None: not said)
    id_note: str | None = None  # stop/abort: why the id sent is not echoed (for the reply)


def is_matrix_name(name: str) -> bool:
    """True if ``name`` is a bare matrix name (no path, no ``..``, no leading dot)."""
    return bool(_MATRIX_NAME.fullmatch(name)) and ".." not in name


#: commands carried out even when their payload has wrong fields (docs/protocols/mqtt.md)
ALWAYS_ACCEPTED = STOP_OR_ABORT

CorrelationId = Annotated[str, StringConstraints(min_length=1, max_length=MAX_ID_CHARS)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


class _Sent(_Strict):
    """What every command may carry: ``by``, who sent it (the dashboard: its signed-in user),
    recorded with the command in the run (orbitrig.run.provenance)."""

    by: Annotated[str, Field(min_length=1, max_length=64)] | None = None


class StartCommand(_Sent):
    """``start``: run the named matrix of the service's matrix folder."""

    cmd: Literal[RunCommand.START]
    id: CorrelationId
    matrix: str

    @field_validator("matrix")
    @classmethod
    def _bare_name(cls, v: str) -> str:
        if not is_matrix_name(v):
            raise ValueError(
                f"field 'matrix' must be a matrix name from the matrix folder, not a path: {v!r} "
                "(letters, digits, '_', '-', '.'; no '/', no '..', no leading '.')"
            )
        return v


class ConfirmCommand(_Sent):
    """``confirm``: the operator confirms the manual setting ``step``."""

    cmd: Literal[RunCommand.CONFIRM]
    id: CorrelationId
    step: str

    @field_validator("step")
    @classmethod
    def _printable(cls, v: str) -> str:
        if not _STEP_ID.fullmatch(v):
            raise ValueError("field 'step' must be 1 to 128 printable characters")
        return v


class BareCommand(_Sent):
    """Commands without arguments."""

    cmd: Literal[RunCommand.PAUSE, RunCommand.RESUME, RunCommand.STOP, RunCommand.ABORT, Query.STATUS]
    id: CorrelationId


CommandModel = Annotated[Union[StartCommand, ConfirmCommand, BareCommand], Field(discriminator="cmd")]
_COMMANDS: TypeAdapter = TypeAdapter(CommandModel)

#: Commands and the fields each takes besides ``cmd`` and ``id`` (from the models).
COMMAND_FIELDS: dict[CommandName, tuple[str, ...]] = {
    name: tuple(f for f in model.model_fields if f not in ("cmd", "id", "by"))
    for model in (StartCommand, ConfirmCommand, BareCommand)
    for name in get_args(model.model_fields["cmd"].annotation)
}
#: Each command by its word on the wire ("start" -> RunCommand.START).
COMMAND_WORDS: dict[str, CommandName] = {name.value: name for name in COMMAND_FIELDS}


def _field_problem(err: ErrorDetails, name: str) -> str | None:
    """One pydantic error of a command's fields as the reply's words (None: an
    id problem, reported once by the correlation check)."""
    field = str(err["loc"][-1]) if err["loc"] else "?"
    kind = err["type"]
    if field == "id" and kind != "extra_forbidden":
        return None
    if kind == "missing":
        return f"missing field {field!r} for command {name!r}"
    if kind == "extra_forbidden":
        return f"unexpected field {field!r} for command {name!r}"
    if kind == "string_type":
        return not_a_string(field, err.get("input"))
    said = err["msg"].removeprefix("Value error, ")
    return said if said.startswith(f"field {field!r}") else f"field {field!r} of command {name!r}: {said}"


def parse_command(payload: bytes | bytearray | str) -> Command:
    """Parse and validate one ``<prefix>/cmd`` payload with the command models.

    Raises :class:`CommandError` with a precise reason (and the correlation
    id when it can be echoed) for a payload that is not UTF-8 JSON, not an
    object, lacks ``cmd`` or ``id``, names an unknown command, or has a
    missing, extra or wrongly typed field, a key given twice with different
    values or text that cannot be encoded as UTF-8 (such an ``id``, or one over
    ``MAX_ID_CHARS``, is not echoed: the reply's id is null), or is over the size
    or nesting limits. Exception: ``stop`` and ``abort`` are always accepted once
    ``cmd`` names them unambiguously, in any letter case and with blanks around
    (command_json.read_object reads them beyond the limits); their overlooked
    problems are listed in ``Command.ignored``.
    """
    found = read_object(payload)
    obj = found.fields
    cid = echoable_id(found)
    problems = found.problems() + ([] if "id" in found.unencodable else id_problems(obj))
    if "cmd" in found.duplicates:
        raise CommandError("; ".join(problems), cid)  # which command was meant cannot be told
    name = obj.get("cmd")
    problem = cmd_problem(obj)
    if problem is not None:
        raise CommandError("; ".join([problem, *problems]), cid)
    word = stop_word(name)
    if word is not None and word != name:  # "STOP", " abort": still the stop asked for
        problems.append(f"field 'cmd' {name!r} read as {word.value!r}")
        name, obj = word.value, {**obj, "cmd": word.value}
    if name not in COMMAND_FIELDS:
        known = ", ".join(sorted(COMMAND_FIELDS))
        raise CommandError("; ".join([f"unknown command {name!r} (known: {known})", *problems]), cid)
    try:
        model = _COMMANDS.validate_python(obj)
    except ValidationError as err:
        field_problems = (_field_problem(e, name) for e in err.errors(include_url=False))
        problems += [p for p in field_problems if p is not None]
    if problems and word is not None:  # (so: a stop or an abort, ALWAYS_ACCEPTED)
        # "stop and abort are always accepted": a stray field or a bad id must
        # never keep spinning machinery from stopping. The problems are logged.
        by = obj.get("by") if isinstance(obj.get("by"), str) else None
        note = f"the id sent is not echoed: {_id_trouble(found)}" if "id" in obj and cid is None else None
        return Command(cmd=word, id=cid, ignored=tuple(problems), by=by[:64] if by else None, id_note=note)
    if problems:
        raise CommandError("; ".join(problems), cid)
    return Command(
        cmd=model.cmd,
        id=model.id,
        matrix=model.matrix if isinstance(model, StartCommand) else None,
        step=model.step if isinstance(model, ConfirmCommand) else None,
        by=model.by,
    )


def _id_trouble(found: Any) -> str:
    """Why an ``id`` that was sent cannot be echoed."""
    cid = found.fields["id"]
    if "id" in found.duplicates:
        return "key 'id' given more than once with different values"
    if "id" in found.unencodable:
        return "it cannot be encoded as UTF-8"
    if isinstance(cid, str) and len(cid) > MAX_ID_CHARS:
        return f"it has {len(cid)} characters (at most {MAX_ID_CHARS})"
    return id_problems(found.fields)[0]
