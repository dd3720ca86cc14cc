"""A point's result is published after the results of the points measured before it, also when
it was identified first (a loaded computer: the earlier point's identification held up until the
later one's is done). The MQTT results topic, the dashboard's table and the catalog's completed
points follow the run's point order.

A machine that identifies one point more slowly than the next cannot be produced on demand: the
first identification is held (injected) until the second has returned."""

import asyncio
import threading

import pytest

import orbitrig.run.point_record as point_record
from orbitrig.run.engine import ResultEvent
from support.sweep_helpers import running, small_matrix

pytestmark = pytest.mark.timeout(120)


async def test_a_point_identified_first_waits_for_the_earlier_points_result(tmp_path, monkeypatch):
    real = point_record.identify_operating_point
    second_done = threading.Event()
    calls: list[float] = []
    lock = threading.Lock()

    def out_of_order(spin, *args, **kw):
        with lock:
            first = not calls
            calls.append(spin)
        if first:
            assert second_done.wait(60), "the second point was never identified"
            return real(spin, *args, **kw)
        result = real(spin, *args, **kw)
        second_done.set()
        return result

    monkeypatch.setattr(point_record, "identify_operating_point", out_of_order)
    async with running(tmp_path, small_matrix(spin_rpm=[1000.0, 2000.0])) as (sim, eng, rec, run):
        outcome = await asyncio.wait_for(asyncio.shield(run), 100)
    assert outcome.status == "completed", outcome.message
    assert calls[0] < calls[1]  # point 0 (1000 rpm) was held, point 1 identified first
    published = [e.payload["point"] for e in rec.events if isinstance(e, ResultEvent)]
    assert published == [0, 1]
