"""Designed orbit-frequency lists by name.

A matrix's ``[orbit] design = "NAME"`` takes its ratios and directions from
``config/designs/NAME.toml`` of the source tree (what ``orbitrig design --save NAME``
writes); ``design = "FILE.toml"`` names a file, relative to the matrix's folder. The design
file holds ``ratios`` (Omega/omega) and ``directions``; its other keys (model, spin,
revolutions) say what it was designed for and are not used by the matrix.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

DESIGNS_DIR = Path(__file__).resolve().parents[2] / "config" / "designs"
_SPEC_KEYS = ("ratios", "ratio_start", "ratio_stop", "count")


def design_path(name: str, matrix_file: str) -> Path:
    """The design file a matrix names: NAME -> config/designs/NAME.toml; a name ending in
    .toml is a file relative to the matrix's folder."""
    if name.endswith(".toml"):
        p = Path(name)
        return p if p.is_absolute() else Path(matrix_file).parent / p
    return DESIGNS_DIR / f"{name}.toml"


def _read_design(path: Path) -> tuple[dict | None, str | None]:
    try:
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
    except FileNotFoundError:
        known = sorted(p.stem for p in DESIGNS_DIR.glob("*.toml")) if DESIGNS_DIR.is_dir() else []
        return None, f"no design file {path}" + (f" (designs: {', '.join(known)})" if known else
                                                 "; write one with `orbitrig design ... --save NAME`")
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, RecursionError) as err:
        return None, f"design file {path} cannot be read: {err}"
    ratios = data.get("ratios")
    if not isinstance(ratios, list) or not ratios or not all(isinstance(r, (int, float)) and r > 0 for r in ratios):
        return None, f"design file {path}: 'ratios' must be a non-empty list of numbers > 0"
    return data, None


def apply_design(data: dict, file: str) -> list[str]:
    """Replace a matrix's ``[orbit] design`` by the design's ratios and directions (in
    ``data``, before validation); the problems, each naming the key."""
    orbit = data.get("orbit")
    if not isinstance(orbit, dict) or "design" not in orbit:
        return []
    name = orbit["design"]
    if not isinstance(name, str) or not name.strip():
        return ["key 'orbit.design': a design name (config/designs/NAME.toml) or FILE.toml"]
    if any(k in orbit for k in _SPEC_KEYS):
        return ["key 'orbit': give 'design' or the ratios ('ratios', or 'ratio_start', 'ratio_stop', 'count'), not both"]
    design, problem = _read_design(design_path(name, file))
    if problem:
        return [f"key 'orbit.design': {problem}"]
    orbit["ratios"] = [float(r) for r in design["ratios"]]
    if "directions" in design and "directions" not in orbit:
        orbit["directions"] = design["directions"]
    return []
