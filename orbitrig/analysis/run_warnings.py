"""The grouped fit warnings of a stored run (orbitrig.analysis.warning_groups), read from
its results only (no blocks), for the closing summary on the terminal and over MQTT."""

from __future__ import annotations

import logging
from pathlib import Path

from orbitrig.analysis.warning_groups import FitWarnings, warning_lines
from orbitrig.store.reader import RunDirError, read_run
from orbitrig.store.stored_run import Point

log = logging.getLogger(__name__)


def fit_warnings(points: list[Point]) -> list[FitWarnings]:
    """The warnings of every fit that gave coefficients."""
    return [
        FitWarnings(int(p.name), i.lms, f"{i.model} {i.freq_dep} {i.method}", tuple(i.result.get("warnings") or []))
        for p in points
        for i in p.identifications
        if i.result is not None  # i.ok, narrowing i.result
    ]


def result_fit_warnings(payload: dict) -> list[FitWarnings]:
    """The warnings of every fit of a published point result (orbitrig.run.point_report)."""
    return [
        FitWarnings(
            int(payload["point"]),
            r["lms"],
            f"{r['model']} {r['freq_dep']} {r['method']}",
            tuple(r.get("warnings") or []),
        )
        for r in payload["identification"]
        if "error" not in r
    ]


def run_warning_lines(directory: Path) -> list[str]:
    """Each distinct warning of the run's complete points once per fit family."""
    return warning_lines(fit_warnings(read_run(directory, blocks=False).complete_points))


def closing_warnings(directory: Path) -> list[str]:
    """`run_warning_lines` of a finished run; [] (and a log line) when it cannot be read."""
    try:
        return run_warning_lines(directory)
    except (RunDirError, OSError, TypeError) as err:
        log.warning("no warning summary for %s: %s", directory, err)
        return []
