"""The run's warnings at its end and for a late subscriber, through a real `RigService` running the
simulator's rig and a real mosquitto (shipped ACL and accounts): 14 warnings said at once from the
engine's thread (two kinds, alternating) go out as 10 (note_budget.BURST); the 4 withheld, said by
no later warning, are said by one closing note (how many, of which kinds) ahead of the closing
`idle` status, which carries the run's counts. Each note is retained: a subscriber that comes later
sees the latest one (with the run's count so far), after the run its closing note; the next run's
start clears it. A warning of the store's own (the run's journal.jsonl really deleted while the run
writes its blocks, found by the storage thread) is published too, once."""

from __future__ import annotations

import asyncio
import threading

import pytest

from orbitrig.run.events import NoteEvent, NoteKind, Severity
from orbitrig.run.states import RunState
from orbitrig.service.note_budget import BURST
from orbitrig.service.rig_service import RigService
from support.mqtt_helpers import RigClient, retained, serving_unsupervised, wait
from support.polling import until

pytestmark = pytest.mark.timeout(240)

RIG = "noted-run"
NOTE, STATUS = f"orbitrig/{RIG}/note", f"orbitrig/{RIG}/status"


def said_from_the_engine(service: RigService, events: list[NoteEvent]) -> None:
    """``events`` said as the run engine says them: from a thread of its own."""
    engine = threading.Thread(target=lambda: [service._on_event(e) for e in events])
    engine.start()
    engine.join()


def said(rc: RigClient, start: int = 0) -> list:
    """The warnings on <prefix>/note from message ``start`` on (not the empty messages that clear it)."""
    return [m for m in rc.watch.on("note", start) if m.payload]


def warnings(run_id: str) -> list[NoteEvent]:
    """14 warnings, an A/D link drop and a retried acquisition in turn."""
    drop = "point 0000 [{:02d}_fwd]: A/D link dropped once during the block: 3 frames lost"
    retry = "point 0000 [{:02d}_fwd]: acquisition failed: the A/D board has sent nothing for 1.2 s"
    said = ((drop, NoteKind.ADC_LINK_DROP), (retry, NoteKind.ACQUISITION_RETRIED))
    return [NoteEvent(run_id, Severity.WARNING, said[i % 2][0].format(i), said[i % 2][1]) for i in range(14)]


async def test_withheld_warnings_are_said_at_the_end_and_a_late_subscriber_sees_the_latest(broker, tmp_path):
    async with serving_unsupervised(broker, tmp_path, RIG, "keep") as (service, _sim):
        rc = await asyncio.to_thread(RigClient, broker, RIG)
        try:
            assert (await wait(rc.command, {"cmd": "start", "matrix": "long", "by": "ada"}))["ok"] is True
            run_id = (await wait(rc.status, "running"))["run_id"]
            assert rc.watch.on("note") == []  # nothing on note at the start: every message there is a warning
            flood = warnings(run_id)
            await asyncio.to_thread(said_from_the_engine, service, flood)
            await until(lambda: len(said(rc)) >= BURST, 10, "the first warnings")
            await asyncio.sleep(0.5)  # nothing more comes while the run goes on
            got = [m.json() for m in said(rc)]
            assert [g["message"] for g in got] == [e.message for e in flood[:BURST]]
            assert [g["said"] for g in got] == list(range(1, BURST + 1)) and all("withheld" not in g for g in got)

            late = await asyncio.to_thread(retained, broker, NOTE)  # a subscriber coming now
            assert late is not None and late.retain and late.qos == 1
            assert late.json() == got[-1]  # the latest warning, with the run's count then

            mark = rc.watch.mark()
            assert (await wait(rc.command, {"cmd": "stop", "by": "ada"}))["ok"] is True
            idle = await wait(rc.status, lambda s: s["state"] == "idle" and s["run_id"] == run_id, 120)
            kinds = {"A/D link drop": 2, "acquisition retried": 2}
            assert idle["notes"] == {"said": 14, "published": BURST, "withheld": 4, "withheld_kinds": kinds}
            closing = said(rc, mark)
            assert len(closing) == 1, [m.payload for m in closing]
            note = closing[0].json()
            assert note["run_id"] == run_id and note["severity"] == "warning"
            assert (note["withheld"], note["withheld_kinds"], note["said"], note["closing"]) == (4, kinds, 14, True)
            assert note["message"] == (
                "the run ended with 4 warnings not published here (at most 10 in 60 s): "
                "A/D link drop 2, acquisition retried 2; run.log has them"
            )
            ended = [m for m in rc.watch.messages[mark:] if m.topic == STATUS and m.json()["state"] == "idle"]
            assert rc.watch.messages.index(closing[0]) < rc.watch.messages.index(ended[0])  # the note first

            after = rc.watch.mark()  # a warning of the ended run said late, from another thread
            await asyncio.to_thread(said_from_the_engine, service, warnings(run_id)[:1])
            await asyncio.sleep(0.5)
            assert said(rc, after) == []  # not published: the closing note stays the run's last word
            late = await asyncio.to_thread(retained, broker, NOTE)  # a subscriber coming after the run
            assert late is not None and late.json() == note
            status = await asyncio.to_thread(retained, broker, STATUS)
            assert status is not None and status.json()["notes"] == idle["notes"]

            assert (await wait(rc.command, {"cmd": "start", "matrix": "quick", "by": "ada"}))["ok"] is True
            second = await wait(rc.status, lambda s: s["state"] == "running" and s["run_id"] != run_id)
            kept = await asyncio.to_thread(retained, broker, NOTE)  # the last warning said, naming its run
            assert kept is not None and kept.json() == note and note["run_id"] != second["run_id"]
            assert "notes" not in second
            done = await wait(rc.status, lambda s: s["state"] == "idle" and s["run_id"] == second["run_id"], 120)
            assert done["notes"] == {"said": 0, "published": 0, "withheld": 0, "withheld_kinds": {}}
            assert (await asyncio.to_thread(retained, broker, NOTE)).json() == note  # the new run said none
        finally:
            await asyncio.to_thread(rc.close)


async def test_a_failed_runs_final_status_counts_its_warnings(broker, tmp_path):
    """A run the engine ended as faulted (a drive's trip): its faulted status is said again with the
    run's counts, after the closing note of the warnings still withheld; the service's state stays
    the RunState, not the word read back from the status."""
    async with serving_unsupervised(broker, tmp_path, RIG, "keep") as (service, sim):
        rc = await asyncio.to_thread(RigClient, broker, RIG)
        try:
            assert (await wait(rc.command, {"cmd": "start", "matrix": "long", "by": "ada"}))["ok"] is True
            run_id = (await wait(rc.status, "running"))["run_id"]
            await asyncio.to_thread(said_from_the_engine, service, warnings(run_id)[:12])
            await until(lambda: len(said(rc)) >= BURST, 10, "the first warnings")
            mark = rc.watch.mark()
            sim.inject("drive_trip", drive=1, code=2310)
            faulted = await wait(rc.status, lambda s: s["state"] == "faulted" and "notes" in s, 120, mark)
            kinds = {"A/D link drop": 1, "acquisition retried": 1}
            assert faulted["run_id"] == run_id
            assert faulted["notes"] == {"said": 12, "published": BURST, "withheld": 2, "withheld_kinds": kinds}
            first = await wait(rc.status, "faulted", 1, mark)  # the engine's, then the same with the counts
            assert {k: v for k, v in faulted.items() if k != "notes"} == first, (first, faulted)
            # the closing note once (a warning the trip itself raises may be said beside it)
            closing = [m for m in said(rc, mark) if m.json().get("closing")]
            assert len(closing) == 1 and closing[0].json()["withheld_kinds"] == kinds, closing
            status = await asyncio.to_thread(retained, broker, STATUS)
            assert status is not None and status.json() == faulted
            assert service.state is RunState.FAULTED  # the word read back is kept as the enum
        finally:
            await asyncio.to_thread(rc.close)


DELETED = "was deleted while the run was being written (found missing at "


async def test_a_journal_deleted_during_the_run_is_said_on_note(broker, tmp_path):
    """The store's warning (said on its storage thread) reaches <prefix>/note as the run's warning,
    once, in run.log's words; the closing status counts it. (A rig of its own: no note retained.)"""
    async with serving_unsupervised(broker, tmp_path, "journal-run", "keep") as (_service, _sim):
        rc = await asyncio.to_thread(RigClient, broker, "journal-run")
        try:
            mark = rc.watch.mark()
            assert (await wait(rc.command, {"cmd": "start", "matrix": "long", "by": "ada"}))["ok"] is True
            run_id = (await wait(rc.status, "running", 30, mark))["run_id"]
            blocks = tmp_path / "runs"
            await until(lambda: any(blocks.glob("*/points/0000/*.h5")), 60, "the run's first block written")
            (journal,) = blocks.glob("*/journal.jsonl")
            journal.unlink()  # the next block's journal line finds it gone
            await until(lambda: said(rc, mark), 30, "a warning on note")
            (note,) = [m.json() for m in said(rc, mark)]
            assert note["run_id"] == run_id and note["severity"] == "warning" and note["said"] == 1, note
            assert note["message"].startswith(f"{journal} {DELETED}"), note
            assert note["message"].endswith("a new journal.jsonl continues it from there"), note
            assert (await wait(rc.command, {"cmd": "stop", "by": "ada"}))["ok"] is True
            idle = await wait(rc.status, lambda s: s["state"] == "idle" and s["run_id"] == run_id, 120, mark)
            assert idle["notes"] == {"said": 1, "published": 1, "withheld": 0, "withheld_kinds": {}}
            assert [m.json() for m in said(rc, mark)] == [note]  # once
            log = (journal.parent / "run.log").read_text()
            assert log.count(f"warning: {note['message']}") == 1, log  # the same words, once
        finally:
            await asyncio.to_thread(rc.close)
