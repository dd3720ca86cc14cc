"""Designed orbit-frequency lists by name.

A matrix's ``[orbit] design = "NAME"`` takes its ratios and directions from
``designs/NAME.toml`` next to the matrix's folder (a lab configuration's or the source
tree's config/), else of the lab configuration or the shipped defaults (orbitrig.config.home;
what ``orbitrig design --save NAME`` writes); ``design = "FILE.toml"`` names a file, relative to the matrix's folder. The design
file holds ``ratios`` (Omega/omega) and ``directions``, and optionally, one per ratio in the
order of ``ratios``, ``revolutions`` (the block's count), ``target_pct`` (its adaptive
target, percent) and ``whirl`` (the directions it runs in: "forward", "backward" or "both";
``orbitrig design --per-direction`` writes it, and a ratio may then be there twice). The
matrix takes each of these unless it sets it itself: ``directions``, ``whirl`` and
``revolutions`` / ``target_pct`` in [orbit]; a top-level ``revolutions`` also keeps the
design's counts out, and an [averaging] ``target_pct`` the design's targets (which are used
only with an [averaging] table). Its other keys (model, spin) say what it was designed for.

The design file's name, path, SHA-256 and text become the matrix's ``design_used`` (RECORD),
which a run stores with the matrix's text (``with_design``); a matrix text holding that
table takes its design from it, never from the file, so a resume measures with the design
the run started with (``resume_note`` says when the file has changed since).
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import TYPE_CHECKING

from orbitrig.config.home import DESIGNS, known_names, named_file
from orbitrig.config.record_seal import digest
from orbitrig.config.messages import bom_problem
from orbitrig.config.toml_out import render
from reduction.whirl import Directions

if TYPE_CHECKING:
    from orbitrig.config.matrix import DesignUsed, MatrixConfig

_SPEC_KEYS = ("ratios", "ratio_start", "ratio_stop", "count")
#: the matrix table of the design it used: name, file, sha256, text (orbitrig.config.matrix.DesignUsed)
RECORD = "design_used"
_RECORD_KEYS = ("name", "file", "sha256", "text")


def design_path(name: str, matrix_file: str) -> Path:
    """The design file a matrix names: NAME -> designs/NAME.toml beside the matrix's folder,
    else of the lab configuration or shipped; a name ending in .toml is a file relative to
    the matrix's folder."""
    if name.endswith(".toml"):
        p = Path(name)
        return p if p.is_absolute() else Path(matrix_file).parent / p
    beside = Path(matrix_file).parent.parent / DESIGNS / f"{name}.toml"
    return beside if beside.is_file() else named_file(DESIGNS, name)


def _read_file(name: str, path: Path) -> tuple[dict | None, str | None]:
    """The RECORD of the design file ``path`` (of the design ``name``), or the problem."""
    try:
        text = path.read_bytes().decode("utf-8")
    except FileNotFoundError:
        known = known_names(DESIGNS)
        return None, f"no design file {path}" + (
            f" (designs: {', '.join(known)})" if known else "; write one with `orbitrig design ... --save NAME`"
        )
    except (OSError, UnicodeDecodeError) as err:
        return None, f"design file {path} cannot be read: {err}"
    bom = bom_problem(text)
    if bom is not None:
        return None, f"design file {path}: {bom}"
    return {"name": name, "file": str(path.resolve()), "sha256": digest(text), "text": text}, None


def _stored_record(record, name: str) -> str | None:
    """The problem of a matrix's RECORD table (a run's stored design), None when it is sound."""
    if not isinstance(record, dict) or not all(isinstance(record.get(k), str) for k in _RECORD_KEYS):
        return f"key '{RECORD}': a table of the texts {', '.join(_RECORD_KEYS)} (the design a run stored)"
    if record["name"] != name:
        return f"key '{RECORD}.name': {record['name']!r} is not the design [orbit] names ({name!r})"
    if digest(record["text"]) != record["sha256"]:
        return f"key '{RECORD}.sha256': not the SHA-256 of '{RECORD}.text' (the stored design was altered)"
    return None


def _check_design(text: str, where: str) -> tuple[dict | None, str | None]:
    """The design's data from its TOML ``text`` (``where``: 'design file PATH'), or the problem."""
    try:
        data = tomllib.loads(text)
    except (tomllib.TOMLDecodeError, RecursionError) as err:
        return None, f"{where} cannot be read: {err}"
    ratios = data.get("ratios")
    if not isinstance(ratios, list) or not ratios or not all(_number(r) and r > 0 for r in ratios):
        return None, f"{where}: 'ratios' must be a non-empty list of numbers > 0"
    for key, ok, what in _PER_RATIO:
        values = data.get(key)
        if values is not None and not (
            isinstance(values, list) and len(values) == len(ratios) and all(ok(v) for v in values)
        ):
            return None, (
                f"{where}: '{key}' must be a list of {len(ratios)} {what}, "
                f"one per entry of 'ratios' (got {values!r:.60})"
            )
    return data, None


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


_DIRECTIONS = frozenset(d.value for d in Directions)
_DIRECTION_WORDS = ", ".join(f'"{d}"' for d in list(Directions)[:-1]) + f' or "{list(Directions)[-1]}"'

#: per-ratio keys of a design file: (key, check of one value, what the values must be)
_PER_RATIO = (
    (
        "revolutions",
        lambda v: isinstance(v, int) and not isinstance(v, bool) and 2 <= v <= 10_000,
        "whole numbers 2..10000",
    ),
    ("target_pct", lambda v: _number(v) and 0 < v < 100, "numbers between 0 and 100 (percent)"),
    ("whirl", lambda v: v in _DIRECTIONS, f"directions {_DIRECTION_WORDS}"),
)


def apply_design(data: dict, file: str) -> list[str]:
    """Replace a matrix's ``[orbit] design`` by the design's ratios, directions and per-ratio
    revolutions / targets / whirl (in ``data``, before validation; see the module doc for which the
    matrix keeps) and set its RECORD: the one ``data`` holds (a run's stored matrix), else the
    design file's. The problems, each naming the key."""
    orbit = data.get("orbit")
    if not isinstance(orbit, dict) or "design" not in orbit:
        return [f"key '{RECORD}': a stored design, but [orbit] names no 'design'"] if RECORD in data else []
    name = orbit["design"]
    if not isinstance(name, str) or not name.strip():
        return ["key 'orbit.design': a design name (config/designs/NAME.toml) or FILE.toml"]
    if any(k in orbit for k in _SPEC_KEYS):
        return [
            "key 'orbit': give 'design' or the ratios ('ratios', or 'ratio_start', 'ratio_stop', 'count'), not both"
        ]
    if RECORD in data:  # a run's stored matrix: its design as the run started, the file is not read
        record, problem = data[RECORD], _stored_record(data[RECORD], name)
        if problem:
            return [problem]
        where = f"key '{RECORD}.text': the design {name!r} stored"
    else:
        path = design_path(name, file)
        record, problem = _read_file(name, path)
        if record is None:
            return [f"key 'orbit.design': {problem}"]
        where = f"key 'orbit.design': design file {path}"
    design, problem = _check_design(record["text"], where)
    if design is None:
        return [str(problem)]
    data[RECORD] = record
    _fill(data, orbit, design)
    return []


def _fill(data: dict, orbit: dict, design: dict) -> None:
    """The design's values in [orbit] (those the matrix does not set itself)."""
    orbit["ratios"] = [float(r) for r in design["ratios"]]
    if "directions" in design and "directions" not in orbit:
        orbit["directions"] = design["directions"]
    if "whirl" in design and "whirl" not in orbit:
        orbit["whirl"] = list(design["whirl"])
    if "revolutions" in design and "revolutions" not in orbit and "revolutions" not in data:
        orbit["revolutions"] = list(design["revolutions"])
    averaging = data.get("averaging")
    if (
        "target_pct" in design
        and "target_pct" not in orbit
        and isinstance(averaging, dict)
        and "target_pct" not in averaging
    ):
        orbit["target_pct"] = [float(v) for v in design["target_pct"]]


def with_design(text: str, design: DesignUsed | None) -> str:
    """A matrix's ``text`` as a run stores it: with its RECORD table ``design`` appended, unless
    the text holds one already (or the matrix names no design)."""
    try:
        held = RECORD in tomllib.loads(text)
    except (tomllib.TOMLDecodeError, RecursionError):
        return text  # reported where it is parsed as a matrix
    if design is None or held:
        return text
    note = "the design of [orbit] design as read when the run started: a resume measures with it"
    end = "\n" if text and not text.endswith("\n") else ""
    return f"{text}{end}\n{render({RECORD: design.model_dump()}, note)}"


def resume_note(matrix: MatrixConfig) -> str | None:
    """One line for a resume of a run with the stored ``matrix`` (None: nothing to say): its
    stored design's file has changed or is gone since (the stored design is used), or, for a
    run that stored only the design's name, that the design was read again from its file."""
    design = matrix.design_used
    if design is None:
        return None
    if not matrix.design_stored:
        return (
            f"warning: {matrix.file}: the run stored only the name of its design {design.name!r} (a run made "
            f"before designs were stored): the design was read again from {design.file}, as it is now "
            f"(sha256 {design.sha256[:12]}); the points measured before may have used another"
        )
    try:
        now = digest(Path(design.file).read_bytes().decode("utf-8"))
        what = f"has changed since the run started (sha256 now {now[:12]})"
    except FileNotFoundError:
        now, what = "", "no longer exists"
    except (OSError, UnicodeDecodeError) as err:
        now, what = "", f"cannot be read ({err})"
    if now == design.sha256:
        return None
    return (
        f"warning: design file {design.file} {what}: the remaining points use the design {design.name!r} "
        f"the run stored (sha256 {design.sha256[:12]})"
    )
