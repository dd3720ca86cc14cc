"""The Run card's state badge follows the rig's status, in a real chromium on a real authenticated
mosquitto. The test publishes the statuses the rig service does (as orbitrig-service, in its words:
orbitrig.run.control): an interlock's suspension is told from an operator's pause at a glance
("suspended: interlock" in the alarm colour)."""

from __future__ import annotations

import pytest
from support.dash_helpers import Page, dashboard_running, publish_as_service
from support.mqtt_helpers import ACCOUNTS

RUN = "sim-rig@2026-12-07T04:00:00.000Z"
CAN = "suspended by interlock: CAN sensor node lost (no heartbeat for 1.5 s)"
ALARM_RED, PAUSE_YELLOW = "rgb(198, 40, 40)", "rgb(249, 168, 37)"


@pytest.fixture(scope="module")
def dashboard(relay, tmp_path_factory):
    """The dashboard alone on the broker, through a relay the test can cut."""
    with dashboard_running(relay.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


@pytest.fixture
def page(browsers, dashboard) -> Page:
    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in("operator", ACCOUNTS["operator"])
    page.signed_in()
    page.wait_text("link", "online")
    return page


def status(broker, state: str, message: str, since: str, run_id: str | None = RUN) -> None:
    body = {"state": state, "run_id": run_id, "since": since, "message": message}
    publish_as_service(broker, "status", body, retain=True)


def badge(page: Page) -> tuple[str, str]:
    """The badge's text and background colour."""
    return page.d.execute_script(
        "const b = document.getElementById('state'); return [b.textContent, getComputedStyle(b).backgroundColor];"
    )


def test_the_badge_tells_an_interlocks_suspension_from_an_operators_pause(broker, page):
    status(broker, "running", "measuring point 1 of 2: w1000rpm (point 0000)", "2026-12-07T04:00:01.000Z")
    page.wait(lambda: badge(page)[0] == "running", 10, "running")
    status(broker, "paused", "paused at a safe point (by ada)", "2026-12-07T04:00:02.000Z")
    page.wait(lambda: badge(page) == ["paused", PAUSE_YELLOW], 10, "the operator's pause")
    status(broker, "paused", CAN, "2026-12-07T04:00:03.000Z")
    page.wait(lambda: badge(page) == ["suspended: interlock", ALARM_RED], 10, "the suspension")
    assert page.text("message") == CAN  # the message says the cause, whole
    status(broker, "running", "interlock cleared (can_heartbeat): settling", "2026-12-07T04:00:04.000Z")
    page.wait(lambda: badge(page)[0] == "running", 10, "running again")
