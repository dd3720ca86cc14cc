"""The fits' warnings of a whole run, each distinct warning once per fit family.

A fit family is one model, frequency dependence and method ("kc7 none ols") over the
load measuring systems (piezo, strain). Two warnings are the same when they differ only
in their numbers ("bad fit: chi2 = 412 ..." and "bad fit: chi2 = 97 ..."). Pure: the
terminal's closing summary and the MQTT closing result show the groups; run.log, run.h5
and the report keep every warning.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass

from orbitrig.load_systems import LoadSystem
from orbitrig.store.layout import point_name

SEE_MOST = 2  # fit families named after "see"
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")


@dataclass(frozen=True)
class FitWarnings:
    """One fit at one point: `warnings` empty for a fit without any."""

    point: int
    lms: LoadSystem
    fit: str  # "model freq_dep method"
    warnings: tuple[str, ...]


@dataclass(frozen=True)
class WarningGroup:
    fit: str
    systems: tuple[LoadSystem, ...]  # the load measuring systems that gave it
    head: str  # "bad fit"
    why: str  # the explanation without its numbers' clause
    points: tuple[int, ...]  # the points concerned, ascending
    total: int  # points with this fit family
    see: tuple[str, ...]  # fit families without this warning at any of these points

    def text(self, all_systems: tuple[LoadSystem, ...]) -> str:
        who = (
            "both systems"
            if len(all_systems) == 2 and set(self.systems) == set(all_systems)
            else ", ".join(self.systems)
        )
        line = (
            f"{self.fit}, {who}: {self.head} at {len(self.points)} of {self.total} points ({point_ranges(self.points)})"
        )
        if self.why:
            line += f" - {self.why}"
        if self.see:
            line += f"; see {', '.join(self.see)}"
        return line


def warning_kind(text: str) -> tuple[str, str]:
    """(head, explanation) of a warning: the head is the text before the first ':', the
    explanation what follows a closing '): ' (the numbers' clause left out), else the rest."""
    head, _, rest = text.partition(":")
    if not rest:
        return text.strip(), ""
    why = rest.rsplit("): ", 1)[1] if "): " in rest else rest
    return head.strip(), why.strip()


def _key(text: str) -> str:
    return _NUMBER.sub("#", text)


def group_warnings(fits: Iterable[FitWarnings]) -> list[WarningGroup]:
    """Each distinct warning (numbers aside) of each fit family once, with the points it
    concerns; ordered by fit family, then by how many points it concerns (most first)."""
    fits = list(fits)
    family_points: dict[str, set[int]] = {}
    warned: dict[tuple[str, str], dict] = {}
    for f in fits:
        family_points.setdefault(f.fit, set()).add(f.point)
        for w in f.warnings:
            g = warned.setdefault((f.fit, _key(w)), {"text": w, "points": set(), "systems": set()})
            g["points"].add(f.point)
            g["systems"].add(f.lms)
    out = []
    for (fit, _key_text), g in warned.items():
        clean = {other for other in family_points if other != fit and g["points"] <= family_points[other]}
        for f in fits:
            if f.fit in clean and f.point in g["points"] and any(_head(w) == _head(g["text"]) for w in f.warnings):
                clean.discard(f.fit)
        head, why = warning_kind(g["text"])
        out.append(
            WarningGroup(
                fit,
                tuple(sorted(g["systems"])),
                head,
                why,
                tuple(sorted(g["points"])),
                len(family_points[fit]),
                tuple(sorted(clean))[:SEE_MOST],
            )
        )
    return sorted(out, key=lambda g: (g.fit, -len(g.points), g.head))


def _head(text: str) -> str:
    return warning_kind(text)[0]


def point_ranges(points: Iterable[int], most: int = 8) -> str:
    """'0000-0003, 0007' for points 0, 1, 2, 3, 7; beyond `most` ranges: '... (N more)'."""
    ranges: list[list[int]] = []
    for p in sorted(set(points)):
        if ranges and p == ranges[-1][1] + 1:
            ranges[-1][1] = p
        else:
            ranges.append([p, p])
    parts = [point_name(a) if a == b else f"{point_name(a)}-{point_name(b)}" for a, b in ranges]
    if len(parts) > most:
        parts = parts[:most] + [f"... ({len(parts) - most} more)"]
    return ", ".join(parts)


def warning_lines(fits: Iterable[FitWarnings]) -> list[str]:
    """The grouped warnings as lines of text (the terminal, the MQTT closing result)."""
    fits = list(fits)
    systems = tuple(sorted({f.lms for f in fits}))
    return [g.text(systems) for g in group_warnings(fits)]
