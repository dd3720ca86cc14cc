"""The page opened before the rig service ever connected to the broker (no retained status), in a
real chromium on a real authenticated mosquitto: the Run card says that no status came yet, not a
blank card, until the service's first status replaces it."""

from __future__ import annotations

import pytest
from support.dash_helpers import Page, dashboard_running, publish_as_service
from support.mqtt_helpers import ACCOUNTS

NO_STATUS = "no status from the rig service yet: it has not connected to the broker"


@pytest.fixture(scope="module")
def dashboard(broker, tmp_path_factory):
    """The dashboard alone on the module's own broker: no rig service has published a status on it."""
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


def test_the_run_card_says_no_status_came_until_the_first_one(broker, dashboard, browsers):
    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in("operator", ACCOUNTS["operator"])
    page.signed_in()
    page.wait_text("link", "online", 20)
    assert page.text("state") == "—"
    assert page.text("message") == NO_STATUS  # was blank: nothing told the operator why
    ready = {"state": "idle", "run_id": None, "since": "2026-01-05T13:00:00.000Z", "message": "service ready"}
    publish_as_service(broker, "status", ready)
    page.wait_text("message", "service ready", 10)
    page.wait_state("idle", 5)
