"""Designed orbit-frequency lists by name.

A matrix's ``[orbit] design = "NAME"`` takes its ratios and directions from
``designs/NAME.toml`` next to the matrix's folder (a lab configuration's or the source
tree's config/), else of the lab configuration or the shipped defaults (orbitrig.config.home;
what ``orbitrig design --save NAME`` writes); ``design = "FILE.toml"`` names a file, relative to the matrix's folder. The design
file holds ``ratios`` (Omega/omega) and ``directions``, and optionally, one per ratio in the
order of ``ratios``, ``revolutions`` (the block's count) and ``target_pct`` (its adaptive
target, percent). The matrix takes each of these unless it sets it itself: ``directions``
and ``revolutions`` / ``target_pct`` in [orbit]; a top-level ``revolutions`` also keeps the
design's counts out, and an [averaging] ``target_pct`` the design's targets (which are used
only with an [averaging] table). Its other keys (model, spin) say what it was designed for.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

from orbitrig.config.home import DESIGNS, known_names, named_file

_SPEC_KEYS = ("ratios", "ratio_start", "ratio_stop", "count")


def design_path(name: str, matrix_file: str) -> Path:
    """The design file a matrix names: NAME -> designs/NAME.toml beside the matrix's folder,
    else of the lab configuration or shipped; a name ending in .toml is a file relative to
    the matrix's folder."""
    if name.endswith(".toml"):
        p = Path(name)
        return p if p.is_absolute() else Path(matrix_file).parent / p
    beside = Path(matrix_file).parent.parent / DESIGNS / f"{name}.toml"
    return beside if beside.is_file() else named_file(DESIGNS, name)


def _read_design(path: Path) -> tuple[dict | None, str | None]:
    try:
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
    except FileNotFoundError:
        known = known_names(DESIGNS)
        return None, f"no design file {path}" + (
            f" (designs: {', '.join(known)})" if known else "; write one with `orbitrig design ... --save NAME`"
        )
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, RecursionError) as err:
        return None, f"design file {path} cannot be read: {err}"
    ratios = data.get("ratios")
    if not isinstance(ratios, list) or not ratios or not all(_number(r) and r > 0 for r in ratios):
        return None, f"design file {path}: 'ratios' must be a non-empty list of numbers > 0"
    for key, ok, what in _PER_RATIO:
        values = data.get(key)
        if values is not None and not (
            isinstance(values, list) and len(values) == len(ratios) and all(ok(v) for v in values)
        ):
            return None, (
                f"design file {path}: '{key}' must be a list of {len(ratios)} {what}, "
                f"one per entry of 'ratios' (got {values!r:.60})"
            )
    return data, None


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


#: per-ratio keys of a design file: (key, check of one value, what the values must be)
_PER_RATIO = (
    (
        "revolutions",
        lambda v: isinstance(v, int) and not isinstance(v, bool) and 2 <= v <= 10_000,
        "whole numbers 2..10000",
    ),
    ("target_pct", lambda v: _number(v) and 0 < v < 100, "numbers between 0 and 100 (percent)"),
)


def apply_design(data: dict, file: str) -> list[str]:
    """Replace a matrix's ``[orbit] design`` by the design's ratios, directions and per-ratio
    revolutions / targets (in ``data``, before validation; see the module doc for which the
    matrix keeps); the problems, each naming the key."""
    orbit = data.get("orbit")
    if not isinstance(orbit, dict) or "design" not in orbit:
        return []
    name = orbit["design"]
    if not isinstance(name, str) or not name.strip():
        return ["key 'orbit.design': a design name (config/designs/NAME.toml) or FILE.toml"]
    if any(k in orbit for k in _SPEC_KEYS):
        return [
            "key 'orbit': give 'design' or the ratios ('ratios', or 'ratio_start', 'ratio_stop', 'count'), not both"
        ]
    design, problem = _read_design(design_path(name, file))
    if problem:
        return [f"key 'orbit.design': {problem}"]
    orbit["ratios"] = [float(r) for r in design["ratios"]]
    if "directions" in design and "directions" not in orbit:
        orbit["directions"] = design["directions"]
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
    return []
