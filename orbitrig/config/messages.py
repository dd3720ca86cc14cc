"""Validation errors as the operator reads them: one line per problem, with
the file's line number and the key path (``drives.max_spin_rpm``,
``channels[3].gain``); warnings of a validator (:class:`ConfigWarning`) shown at the
line of the file they concern."""

from __future__ import annotations

import re
import warnings
from collections.abc import Iterable

from pydantic import BaseModel, ValidationError


def _allowed_keys(model: type[BaseModel], loc: tuple) -> list[str] | None:
    """Field names of the model that holds the key at `loc` (for unknown-key messages)."""
    cls: object = model
    for part in loc[:-1]:
        if isinstance(part, int):
            continue
        if not (isinstance(cls, type) and issubclass(cls, BaseModel)) or part not in cls.model_fields:
            return None
        ann = cls.model_fields[part].annotation
        cls = _model_in(ann)
    if isinstance(cls, type) and issubclass(cls, BaseModel):
        return list(cls.model_fields)
    return None


def _model_in(ann) -> object:
    if isinstance(ann, type) and issubclass(ann, BaseModel):
        return ann
    for arg in getattr(ann, "__args__", ()) or ():
        found = _model_in(arg)
        if found is not None:
            return found
    return None


def _key_path(loc: tuple) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif not _skipped(part):
            out += ("." if out else "") + str(part)
    return out or "(top level)"


_LOC_SKIP_PREFIXES = ("function-", "literal[", "list[", "nullable[")
_LOC_SKIP_NAMES = frozenset({"float", "int", "str", "bool", "none"})


def _skipped(part) -> bool:
    """A pydantic location part that names a validator or type, not a key."""
    text = str(part)
    return text in _LOC_SKIP_NAMES or text.startswith(_LOC_SKIP_PREFIXES)


_HEADER = re.compile(r"^\s*(\[\[?)\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(r"^\s*([A-Za-z0-9_\-\"']+)\s*=")


def key_line(text: str, loc: tuple) -> int | None:
    """1-based line of the key (or table header) at a pydantic location, None if not found."""
    want = tuple(p for p in loc if isinstance(p, int) or not _skipped(p))
    if not want or not text:
        return None
    best, best_len = None, 0
    table: tuple = ()
    counts: dict[tuple, int] = {}
    for n, line in enumerate(text.splitlines(), 1):
        m = _HEADER.match(line)
        if m:
            path = tuple(part.strip().strip('"') for part in m.group(2).split("."))
            if m.group(1) == "[[":
                if want == path and best is None:  # the array of tables itself: its first header
                    best, best_len = n, len(path)
                i = counts.get(path, 0)
                counts[path] = i + 1
                path = path + (i,)
            table, here = path, path
        else:
            k = _KEY.match(line)
            if not k:
                continue
            here = table + (k.group(1).strip("\"'"),)
        if len(here) > best_len and want[: len(here)] == here:
            best, best_len = n, len(here)
    return best


def _got(value) -> str:
    """A short rendering of the offending value (whole tables are not repeated)."""
    if isinstance(value, dict) or value is None:  # a table, or a key that is absent (TOML has no null)
        return ""
    text = repr(value)
    return f" (got {text if len(text) <= 60 else text[:57] + '...'})"


class KeyProblems(ValueError):
    """A model validator's problems, each at the key it concerns (``loc`` below the model's, as
    pydantic's: ``("channels", 6, "index")``), so that each is shown at that key's line."""

    def __init__(self, problems: list[tuple[tuple, str]]):
        super().__init__("; ".join(message for _, message in problems))
        self.problems = problems


def problem_lines(err: ValidationError, model: type[BaseModel], text: str = "") -> list[str]:
    """One message per problem of ``err``, each at the line of ``text`` holding its key
    ('line 83: key 'channels[7].index': ...'): an unknown key with the keys allowed there."""
    out = []
    for e in err.errors(include_url=False):
        loc = tuple(e["loc"])
        cause = (e.get("ctx") or {}).get("error")
        if isinstance(cause, KeyProblems):  # one line per key it names
            out += [_at(text, loc + at, message) for at, message in cause.problems]
            continue
        if e["type"] == "extra_forbidden":
            allowed = _allowed_keys(model, loc)
            hint = f"; allowed keys here: {', '.join(allowed)}" if allowed else ""
            out.append(_at(text, loc, f"unknown key{hint}"))
        elif e["type"] == "missing":
            out.append(_at(text, loc, "required key is missing"))
        else:
            msg = e["msg"].removeprefix("Value error, ")
            out.append(_at(text, loc, f"{msg}{_got(e.get('input'))}"))
    return out


def _at(text: str, loc: tuple, message: str) -> str:
    """'line 83: key 'channels[7].index': message' (no line when the key is not found in `text`)."""
    return key_message(key_line(text, loc), _key_path(loc), message)


def key_message(line: int | None, key: str, message: str) -> str:
    """'line 83: key 'channels[7].index': message' at a line found otherwise (a missing key: its
    table's header); no line when None."""
    return f"{f'line {line}: ' if line else ''}key '{key}': {message}"


class ConfigWarning(UserWarning):
    """A setting allowed but unwise; ``loc``: its key path (``("drives", "link_loss_polls")``).
    Raised by a validator; shown at the file and line of that key (:func:`reissue`)."""

    def __init__(self, message: str, loc: tuple):
        super().__init__(message)
        self.loc = loc


def reissue(caught: Iterable[warnings.WarningMessage], file: str, text: str) -> None:
    """Warn again what validating ``file`` (its ``text``) warned: a ConfigWarning at the line of its
    key (else of its table, else line 1), any other warning where it came from."""
    for w in caught:
        if isinstance(w.message, ConfigWarning):
            line = key_line(text, w.message.loc) or 1
            warnings.warn_explicit(w.message, w.category, file, line)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


#: what a configuration file's first bytes EF BB BF (Windows editors' "UTF-8 with BOM") are said to be:
#: TOML forbids them, and its parser only says "Invalid statement (at line 1, column 1)" of an invisible character
BOM_PROBLEM = (
    "line 1: starts with a byte order mark (BOM, bytes EF BB BF), which TOML does not allow: "
    "save the file as UTF-8 without BOM"
)


def bom_problem(text: str) -> str | None:
    """BOM_PROBLEM when the decoded ``text`` starts with a byte order mark, else None."""
    return BOM_PROBLEM if text.startswith("\ufeff") else None
