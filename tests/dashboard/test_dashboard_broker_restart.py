"""A broker restart with its persistence on (as config/mosquitto/mosquitto.conf has it), in a real
chromium on a real authenticated mosquitto: the dashboard's session outlives the restart, so a
result published while the dashboard's link was down (cut by a relay) comes when it is back, and
the page says the results caught up, with no gap row. mosquitto 2.0 saves to its persistence only
the sessions not begun with a clean start. The test publishes what the rig service would."""

from __future__ import annotations


import pytest
from support.dash_helpers import dashboard_running, idle_page, publish_as_service
from support.mqtt_helpers import Broker

RUN = "r-restart"


@pytest.fixture(scope="module")
def broker(tmp_path_factory):
    """The shipped client-id binding and persistence: sessions and retained statuses survive a restart."""
    with Broker(tmp_path_factory.mktemp("broker"), bind_ids=True, persist=True) as b:
        yield b


@pytest.fixture(scope="module")
def dashboard(relay, tmp_path_factory):
    with dashboard_running(relay.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


def a_result(index: int) -> dict:
    fit = {
        "lms": "piezo",
        "model": "kc7",
        "freq_dep": "none",
        "method": "ols",
        "coefficients": {"Kxx": 1.5e7},
        "expanded_uncertainty": {"k": 2, "basis": "statistical", "values": {"Kxx": 2e5}},
        "units": {"Kxx": "N/m"},
    }
    return {"run_id": RUN, "index": index, "point": index, "label": "w1000rpm", "identification": [fit]}


def result_rows(page) -> list[dict]:
    script = "return [...document.querySelectorAll('#results tr')].map(r => ({cls: r.className, text: r.innerText}))"
    return page.d.execute_script(script)


def test_the_session_outlives_a_broker_restart_with_persistence(broker, relay, dashboard, browsers):
    status = {"state": "idle", "run_id": None, "since": "2026-12-05T01:00:00.000Z", "message": "service ready"}
    publish_as_service(broker, "status", status, retain=True)
    page = idle_page(browsers, dashboard)
    running = {"state": "running", "run_id": RUN, "since": "2026-12-05T01:00:01.000Z", "message": "run started"}
    publish_as_service(broker, "status", running, retain=True)
    page.wait_state("running", 15)

    relay.cut()  # the dashboard's link is down across the restart and after it
    page.wait_text("link", "broker unreachable", 15)
    broker.stop()
    broker.start()
    publish_as_service(broker, "result", a_result(0))  # kept for the dashboard's session, if the broker kept it
    relay.restore()
    page.wait_text("link", "online", 30)
    page.wait(lambda: "Kxx" in " ".join(r["text"] for r in result_rows(page)), 15, "the result published meanwhile")
    assert not [r for r in result_rows(page) if "gap-row" in r["cls"]]
    page.wait_text("events", lambda t: "results caught up" in t, 5)
    assert "may be missing" not in page.text("events")
