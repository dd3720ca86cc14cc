"""A drawing process collects its garbage in full after its first point and every
COLLECT_EVERY points after, and freezes what survives (report_pool.settle): the collector's
full passes, one or two a point, no longer walk matplotlib, its caches and the reused figures
again, and cyclic garbage still goes at the next of these collections."""

from __future__ import annotations

import gc
import weakref

import pytest

from orbitrig.analysis import report_pool


class _Cycle:
    def __init__(self) -> None:
        self.me = self


@pytest.fixture
def fresh(monkeypatch):
    """This process as a drawing process that has drawn nothing; nothing left frozen after."""
    monkeypatch.setattr(report_pool, "_BEGUN", {})
    gc.unfreeze()
    yield
    gc.unfreeze()


def test_first_point_draws_unfrozen_the_second_after_a_full_collection_and_freeze(fresh):
    report_pool.settle()
    assert gc.get_freeze_count() == 0
    garbage = _Cycle()
    gone = weakref.ref(garbage)
    del garbage
    report_pool.settle()  # the second point
    assert gone() is None  # a cycle of the first point collected
    frozen = gc.get_freeze_count()
    assert frozen > 1000  # the test process's modules, at least
    kept = _Cycle()
    for _ in range(report_pool.COLLECT_EVERY - 1):  # no collection until COLLECT_EVERY points later
        report_pool.settle()
        assert gc.get_freeze_count() == frozen
    left = weakref.ref(kept)
    gc.freeze()  # `kept` frozen as a point's objects are, then garbage
    del kept
    gc.collect()
    assert left() is not None  # a frozen cycle: not walked by the collector
    report_pool.settle()  # the first point after COLLECT_EVERY more
    assert left() is None
    assert gc.get_freeze_count() > 0
