"""The operator at the dashboard sees the run's warnings: the A/D link dropped mid-block (the
simulator's close_adc_link, through its control API, while a real `orbitrig serve --sim` runs the
demo matrix) reaches a real subscriber on `<prefix>/note` (QoS 1, once, in run.log's words,
time-stamped) and the events list of a real chromium as a warning in words, with its time; it is
listed again, once, after the page is reloaded, and by a dashboard started after it was said (the
retained warning); once the service has restarted, a dashboard started then lists that retained
warning as an earlier run's, with its date."""

from __future__ import annotations

import json
import re
import sys
import time

import pytest
from orbitrig.cli.simulated_rig import SimulatorLink
from support.dash_helpers import RIG, Page, ServiceHolder, dashboard_running, idle_page, publish_as_service
from support.mqtt_helpers import ACCOUNTS, RigClient, Watcher
from support.paths import ROOT

pytestmark = pytest.mark.timeout(180)

SPY = ROOT / "tests" / "support" / "sim_endpoints_spy.py"
STAMP = re.compile(r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z$")  # rigunits.utc_iso
LINK_LINE = re.compile(r"\] (point 0000 \[\w+\]: A/D link dropped once (?:during|before) the block[^\n]*)$")


@pytest.fixture(scope="module")
def service(broker, tmp_path_factory):
    """The module's `serve --sim`, its simulator's endpoints written to sim.json (sim_endpoints_spy)."""
    work = tmp_path_factory.mktemp("serve")
    holder = ServiceHolder(broker, work, (sys.executable, str(SPY), str(work / "sim.json")))
    yield holder
    holder.proc.stop()


def simulator(service: ServiceHolder, timeout: float = 60.0) -> SimulatorLink:
    endpoints = service.work / "sim.json"
    deadline = time.monotonic() + timeout
    while not endpoints.exists():
        assert service.proc.proc.poll() is None, service.text()
        assert time.monotonic() < deadline, "the simulator announced no endpoints"
        time.sleep(0.05)
    return SimulatorLink(json.loads(endpoints.read_text())["control"])


def run_log(service: ServiceHolder) -> str:
    logs = list((service.work / "runs").glob("*/run.log"))  # the latest run's
    return max(logs, key=lambda p: p.stat().st_mtime).read_text() if logs else ""


def wait_run_log(service: ServiceHolder, what: str, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while what not in run_log(service):
        assert time.monotonic() < deadline, f"no {what!r} in run.log:\n{run_log(service)}\n{service.text()}"
        time.sleep(0.01)


def events(page) -> list[str]:
    return page.d.execute_script("return [...document.querySelectorAll('#events li')].map(li => li.textContent)")


def test_an_adc_link_drop_reaches_mqtt_and_the_dashboards_events(broker, service, dashboard, browsers, tmp_path):
    page = idle_page(browsers, dashboard)
    notes = Watcher(broker, f"orbitrig/{RIG}/note")
    rig = RigClient(broker, RIG, service.proc)
    running: dict = {}
    try:
        assert rig.command({"cmd": "start", "matrix": "demo", "id": "warn-1"})["ok"]
        running = rig.status("running")
        waiting = rig.status("waiting")  # the demo matrix's manual settings
        assert rig.command({"cmd": "confirm", "step": waiting["step"], "id": "warn-2"})["ok"]
        sim = simulator(service)
        wait_run_log(service, "[running] speeds set: spin")
        sim.call("inject", fault="close_adc_link", reopen_after=0.2)
        wait_run_log(service, "A/D link dropped")
        sim.close()
        said = [m.group(1) for line in run_log(service).splitlines() if (m := LINK_LINE.search(line))]
        assert len(said) == 1, run_log(service)

        msg = notes.wait_for(lambda m: m.topic.endswith("/note"), 15, what="a warning on <prefix>/note")
        note = msg.json()
        assert (msg.qos, msg.retain) == (1, False)
        assert note["severity"] == "warning" and note["message"] == said[0], note
        assert note["run_id"] == running["run_id"] and STAMP.match(note["at"]), note
        assert "withheld" not in note and note["said"] == 1

        words = f"⚠ warning: run {note['run_id']}: {said[0]}"
        page.wait(lambda: any(words in e for e in events(page)), 15, "the warning in the events list")
        clock = next(e for e in events(page) if words in e).removesuffix(words).strip()
        assert re.fullmatch(r"\d\d:\d\d:\d\d", clock), clock  # its time, as every event's
        # the Run card counts the run's warnings: seen without scrolling to the list
        counted = f"⚠ 1 warning in this run, the latest at {clock}: listed under Warnings and refusals"
        assert page.text("run-warnings") == counted
        assert page.d.execute_script(
            "return [...document.querySelectorAll('#events li.warn')].some(li => li.textContent.includes(arguments[0]))",
            words,
        )

        page.d.refresh()  # the session's snapshot brings it back, once
        page.signed_in()
        page.wait(lambda: any(words in e for e in events(page)), 15, "the warning after a reload")
        time.sleep(1.0)
        assert sum(words in e for e in events(page)) == 1, events(page)
        assert [m.payload for m in notes.on("note")] == [msg.payload]  # said once, the only message on note

        (tmp_path / "late").mkdir()
        with dashboard_running(broker.url, tmp_path / "late") as late:  # a dashboard started after it
            page = Page(browsers(), late.url, late)
            page.sign_in("operator", ACCOUNTS["operator"])
            page.signed_in()
            page.wait(lambda: any(words in e for e in events(page)), 15, "the retained warning")
            assert [e.endswith(words) for e in events(page) if words in e] == [True], events(page)  # the run's own
            assert page.text("run-warnings") == counted  # the retained note's count of the run so far
    finally:
        rig.command({"cmd": "stop", "id": "warn-stop"})
        rig.status(lambda s: s["state"] == "idle" and s["run_id"] == running.get("run_id"), 60)
        rig.close()
        notes.close()

    # the service restarts: its status names no run, the broker still holds the run's warning
    assert service.proc.stop() == 0, service.text()[-3000:]
    service.restart()
    rig = RigClient(broker, RIG, service.proc)
    try:
        rig.status(lambda s: s["state"] == "idle" and s["run_id"] is None, 60)
        (tmp_path / "later").mkdir()
        with dashboard_running(broker.url, tmp_path / "later") as later:
            page = Page(browsers(), later.url, later)
            page.sign_in("operator", ACCOUNTS["operator"])
            page.signed_in()
            page.wait_state("idle")
            page.wait(lambda: any(words in e for e in events(page)), 15, "the retained warning after the restart")
            said_on = page.d.execute_script("return orbitPlots.dateTimeOf(arguments[0])", note["at"])
            assert re.fullmatch(r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d", said_on), said_on
            old = f"{words} (an earlier run's warning, said {said_on}: no run since the service started)"
            assert [e for e in events(page) if words in e] == [f"{clock} {old}"], events(page)
            assert page.text("run-warnings") == "—"  # not counted for a run: the status names none
    finally:
        rig.close()


def test_a_warning_after_withheld_ones_names_how_many_and_their_kinds(broker, dashboard, browsers):
    page = idle_page(browsers, dashboard)
    note = {
        "run_id": f"{RIG}@2026-12-05T12:00:00.000Z",
        "severity": "warning",
        "message": "point 0003 [02_bwd]: A/D link dropped once before the block (no block under way: no data lost)",
        "at": "2026-12-05T12:31:13.442Z",
        "said": 15,
        "withheld": 4,
        "withheld_kinds": {"A/D link drop": 3, "acquisition retried": 1},
    }
    publish_as_service(broker, "note", note)
    words = (
        f"⚠ warning: run {note['run_id']}: {note['message']} (4 earlier warnings not published: "
        "A/D link drop 3, acquisition retried 1; see the run's run.log)"
    )
    page.wait(lambda: any(words in e for e in events(page)), 15, "the warning with the withheld ones")


def test_an_earlier_runs_warning_with_an_unreadable_time_says_that_text_not_null(broker, dashboard, browsers):
    """A retained warning of another run whose `at` the browser cannot read keeps its text as sent."""
    page = idle_page(browsers, dashboard)
    note = {
        "run_id": f"{RIG}@2026-12-04T08:00:00.000Z",
        "severity": "warning",
        "message": "point 0002 [01_fwd]: film temperature near its interlock limit",
        "at": "yesterday at noon",
        "said": 1,
    }
    publish_as_service(broker, "note", note)
    words = f"(an earlier run's warning, said {note['at']}: no run since the service started)"
    page.wait(lambda: any(words in e for e in events(page)), 15, "the earlier run's warning with its own time text")
    assert not any("said null" in e for e in events(page)), events(page)


def test_the_closing_note_is_listed_once_without_its_counts_said_again(broker, dashboard, browsers):
    """The run's closing note names the warnings still withheld in its message; the page lists it as
    it is, not with "(N earlier warnings not published ...)" added (they are those it names, not earlier)."""
    page = idle_page(browsers, dashboard)
    note = {
        "run_id": f"{RIG}@2026-12-05T12:00:00.000Z",
        "severity": "warning",
        "message": "the run ended with 4 warnings not published here (at most 10 in 60 s): A/D link drop 2, "
        "acquisition retried 2; run.log has them",
        "at": "2026-12-05T12:41:13.442Z",
        "said": 14,
        "withheld": 4,
        "withheld_kinds": {"A/D link drop": 2, "acquisition retried": 2},
        "closing": True,
    }
    publish_as_service(broker, "note", note)
    words = f"⚠ warning: run {note['run_id']}: {note['message']}"
    page.wait(lambda: any(words in e for e in events(page)), 15, "the closing note")
    listed = [e for e in events(page) if words in e]
    assert len(listed) == 1 and "earlier warnings" not in listed[0], listed
