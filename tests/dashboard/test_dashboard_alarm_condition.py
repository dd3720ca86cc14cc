"""The condition of a latched interlock alarm follows what the rig's statuses show, in a real
chromium on a real authenticated mosquitto, with two people watching the rig (two sessions
hand the dashboard's one alarm book every status). The test publishes the statuses the rig
service does (as orbitrig-service, its words: orbitrig.run.control): a run that fails by an
interlock leaves its trips "unknown" (nobody tells the condition after the run), not "active"
for ever; a later completed run clears them; a run stopped while suspended does not clear its
trip; a later run suspended by the same condition makes it active again, and its clearing
clears it."""

from __future__ import annotations

import json

import pytest
from support.dash_helpers import Page, RIG, dashboard_running
from support.mqtt_helpers import ACCOUNTS

CAN = "CAN sensor node lost (no heartbeat 0x701 for 1.5 s)"
UNKNOWN = "unknown: not known since the run ended"


@pytest.fixture(scope="module")
def dashboard(broker, tmp_path_factory):
    """The dashboard alone on the broker: the test publishes what the rig service would."""
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


def status(broker, state: str, run_id: str, message: str, since: str) -> None:
    """A status as the rig service publishes it (retained, QoS 1)."""
    body = {"state": state, "run_id": run_id, "since": since, "message": message}
    done = broker.pub(f"orbitrig/{RIG}/status", json.dumps(body), user="orbitrig-service", retain=True)
    assert done.returncode == 0, done.stderr


def watching(browsers, dashboard) -> list[Page]:
    """An operator's and a viewer's page, both online."""
    pages = []
    for user in ("operator", "viewer"):
        page = Page(browsers(), dashboard.url, dashboard)
        page.sign_in(user, ACCOUNTS[user])
        page.signed_in()
        page.wait_text("link", "online")
        pages.append(page)
    return pages


def conditions(page: Page) -> dict[str, str]:
    """{alarm id: its condition cell}."""
    return page.d.execute_script(
        "const out = {}; document.querySelectorAll('#alarms tr').forEach("
        "r => { out[r.dataset.alarm] = r.children[3].innerText; }); return out;"
    )


def wait_conditions(pages: list[Page], expected: dict[str, str]) -> None:
    for page in pages:
        page.wait(lambda p=page: expected.items() <= conditions(p).items(), 15, f"alarm conditions {expected}")


def test_a_failed_runs_trips_are_unknown_until_a_later_run_completes(broker, dashboard, browsers):
    pages = watching(browsers, dashboard)
    status(broker, "running", "r-cond-1", "run r-cond-1 started", "2026-01-06T08:00:00.000Z")
    status(broker, "paused", "r-cond-1", f"suspended by interlock: {CAN}", "2026-01-06T08:00:10.000Z")
    trip, failed = "r-cond-1@2026-01-06T08:00:10.000Z", "r-cond-1@2026-01-06T08:00:45.000Z"
    wait_conditions(pages, {trip: "active"})

    # the condition lasted: the run failed by it. Nobody tells the condition after the run: not "active"
    status(
        broker,
        "faulted",
        "r-cond-1",
        f"run of 'quick' failed: interlock: {CAN} for more than 30 s",
        "2026-01-06T08:00:45.000Z",
    )
    wait_conditions(pages, {trip: UNKNOWN, failed: UNKNOWN})

    # the CAN node is back: a new run completes, so no interlock is in force any more
    status(broker, "running", "r-cond-2", "run r-cond-2 started", "2026-01-06T08:05:00.000Z")
    status(broker, "idle", "r-cond-2", "run completed", "2026-01-06T08:06:00.000Z")
    cleared = "cleared: run r-cond-2 completed since"
    wait_conditions(pages, {trip: cleared, failed: cleared})
    for page in pages:
        assert "active" not in conditions(page).values()


def test_a_run_stopped_while_suspended_does_not_clear_its_trip(broker, dashboard, browsers):
    pages = watching(browsers, dashboard)
    status(broker, "running", "r-cond-3", "run r-cond-3 started", "2026-01-06T09:00:00.000Z")
    status(broker, "paused", "r-cond-3", f"suspended by interlock: {CAN}", "2026-01-06T09:00:10.000Z")
    trip = "r-cond-3@2026-01-06T09:00:10.000Z"
    wait_conditions(pages, {trip: "active"})
    status(broker, "stopping", "r-cond-3", "stop requested by operator", "2026-01-06T09:00:20.000Z")
    status(broker, "idle", "r-cond-3", "run stopped: stopped by operator", "2026-01-06T09:00:21.000Z")
    wait_conditions(pages, {trip: UNKNOWN})  # the heartbeat was still lost: "cleared" would be wrong

    # the next run is suspended by the same condition: it is there again, and clears with that run's trip
    status(broker, "running", "r-cond-4", "run r-cond-4 started", "2026-01-06T09:10:00.000Z")
    status(broker, "paused", "r-cond-4", f"suspended by interlock: {CAN}", "2026-01-06T09:10:05.000Z")
    again = "r-cond-4@2026-01-06T09:10:05.000Z"
    wait_conditions(pages, {trip: "active: again in run r-cond-4", again: "active"})
    cleared = "interlock cleared (can_heartbeat): settling and acquiring the block again"
    status(broker, "running", "r-cond-4", cleared, "2026-01-06T09:10:30.000Z")
    wait_conditions(pages, {trip: "cleared: in run r-cond-4", again: "cleared"})
    for page in pages:
        row = page.d.execute_script(
            "return [...document.querySelectorAll('#alarms tr')].find(r => r.dataset.alarm === arguments[0])"
            ".children[3].className",
            trip,
        )
        assert row == ""  # neither red (active) nor orange (unknown)
    status(broker, "idle", "r-cond-4", "run stopped: stopped by operator", "2026-01-06T09:11:00.000Z")
