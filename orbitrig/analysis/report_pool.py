"""Drawing a report's points in parallel.

:func:`draw_points` hands each operating point to a pool of worker processes (forked, so each
worker starts with the run already read and the figure style set) and reports progress as
points finish; one worker, one point or a platform without fork draws in this process.
:func:`settle` keeps the garbage collector's full passes off what a drawing process keeps.
"""

from __future__ import annotations

import gc
import multiprocessing
import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any

#: (points done, points in all, figures drawn so far: not those kept from an earlier report) after each point
Progress = Callable[[int, int, int], None]

_JOB: dict[str, Any] = {}  # what a forked worker draws: {"points": [...], "draw": callable}

#: points a process draws between two full garbage collections of :func:`settle`
COLLECT_EVERY = 8
_BEGUN: dict[int, int] = {}  # process id -> the points it began drawing (a forked worker starts at 0)


def settle() -> None:
    """Call before a point's figures are drawn. After this process's first point, and every
    COLLECT_EVERY points after, a full garbage collection, and what survives it frozen
    (``gc.freeze``): matplotlib, its fonts, the text caches and the reused figures (about 300,000
    objects after a point), which each of the collector's full passes (one or two a point, about
    0.2 s each) walked again; they walk what was made since. Cyclic garbage among the frozen
    objects is freed by the next of these collections."""
    begun = _BEGUN.get(os.getpid(), 0)
    _BEGUN[os.getpid()] = begun + 1
    if begun and (begun - 1) % COLLECT_EVERY == 0:
        gc.unfreeze()
        gc.collect()
        gc.freeze()


def _draw(k: int):
    return _JOB["draw"](_JOB["points"][k])


def _drawn(pr) -> int:
    """The figures a point's report drew (none when it kept an earlier report's)."""
    return 0 if pr.reused else len(pr.plots)


def draw_points(points: list, draw: Callable, *, workers: int = 1, progress: Progress | None = None) -> list:
    """``draw(point)`` (returning a PointReport) for every point, with up to `workers` processes;
    results in the order of `points`."""
    done, figures = 0, 0
    results: list[Any] = [None] * len(points)
    serial = workers <= 1 or len(points) < 2 or "fork" not in multiprocessing.get_all_start_methods()
    if serial:
        for k, point in enumerate(points):
            results[k] = draw(point)
            done, figures = done + 1, figures + _drawn(results[k])
            if progress:
                progress(done, len(points), figures)
        return results
    _JOB.update(points=points, draw=draw)
    try:
        with ProcessPoolExecutor(min(workers, len(points)), mp_context=multiprocessing.get_context("fork")) as pool:
            futures = {pool.submit(_draw, k): k for k in range(len(points))}
            for future in as_completed(futures):
                k = futures[future]
                results[k] = future.result()
                done, figures = done + 1, figures + _drawn(results[k])
                if progress:
                    progress(done, len(points), figures)
    finally:
        _JOB.clear()
    return results
