"""A flood of the run's warnings through a real `RigService` and a real mosquitto (shipped ACL and
accounts): 40 warnings said at once from the engine's thread reach a real subscriber on
`<prefix>/note` as 10 (note_budget.BURST, QoS 1), the service's log says once that not all were
published, the routine notes none; once the window has passed, the next warning says the 30
withheld. The budget's clock is the test's (the window is 60 s of wall time)."""

from __future__ import annotations

import asyncio
import logging
import threading

from orbitrig.run.events import NoteEvent, Severity
from orbitrig.service.note_budget import BURST, WINDOW_S, NoteBudget
from orbitrig.service.rig_service import RigService
from support.mqtt_helpers import Watcher, broker_fixture, engineless_service, serving
from support.polling import until

bound = broker_fixture(bind_ids=True)
RUN = "SAC-DS-1@2026-12-05T12:00:00.000Z"


class Clock:
    t = 0.0

    def __call__(self) -> float:
        return self.t


def said_from_the_engine(service: RigService, events: list[NoteEvent]) -> None:
    """``events`` said as the run engine says them: from a thread of its own."""
    engine = threading.Thread(target=lambda: [service._on_event(e) for e in events])
    engine.start()
    engine.join()


async def test_a_flood_of_warnings_is_capped_at_the_broker(bound, tmp_path, caplog):
    service = engineless_service(bound.service_url, tmp_path, "noted")
    clock = Clock()
    service._notes = NoteBudget(clock=clock)  # as _cmd_start makes one for each run, for its run id
    service._run_id = RUN
    notes = await asyncio.to_thread(Watcher, bound, "orbitrig/noted/note")
    try:
        async with serving(service):
            flood = [NoteEvent(RUN, Severity.WARNING, f"point 0000 [{i:02d}_fwd]: A/D link dropped") for i in range(40)]
            routine = [NoteEvent(RUN, Severity.INFO, "speeds set: spin 1000 rpm")] * 5
            with caplog.at_level(logging.WARNING, "orbitrig.service"):
                await asyncio.to_thread(said_from_the_engine, service, routine + flood)
                await until(lambda: len(notes.on("note")) >= BURST, 10, "the first warnings")
                await asyncio.sleep(1.0)  # nothing more comes
                got = [m.json() for m in notes.on("note")]
                assert len(got) == BURST and all(m.qos == 1 and not m.retain for m in notes.on("note"))
                assert [g["message"] for g in got] == [e.message for e in flood[:BURST]]  # in order, the first ten
                assert {g["severity"] for g in got} == {"warning"} and all("withheld" not in g for g in got)
                over = [r for r in caplog.records if "not all published" in r.getMessage()]
                assert len(over) == 1, caplog.text
                clock.t += WINDOW_S
                await asyncio.to_thread(said_from_the_engine, service, flood[:1])
                await until(lambda: len(notes.on("note")) == BURST + 1, 10, "the warning after the window")
            assert notes.on("note")[-1].json()["withheld"] == 40 - BURST
    finally:
        await asyncio.to_thread(notes.close)
