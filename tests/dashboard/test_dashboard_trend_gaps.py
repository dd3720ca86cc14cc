"""Trend charts leave a silence blank, in a real chromium on a real authenticated mosquitto: live
samples before and after 8 s without any (no run, the broker link down) are drawn as two pieces
of line, not joined by a line across a time nobody measured; while none comes the window moves on with
the clock. The test publishes what the rig
service would (as orbitrig-service)."""

from __future__ import annotations

import json
import time

import pytest
from support.dash_helpers import Page, RIG, dashboard_running
from support.mqtt_helpers import ACCOUNTS


@pytest.fixture(scope="module")
def dashboard(broker, tmp_path_factory):
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


def live(spin_rpm: float) -> dict:
    drive = {"reference_rpm": spin_rpm, "actual_rpm": spin_rpm, "torque_pct": 10.0, "state": "running"}
    aux = {"p_supply": 2.0e6, "t_supply": 313.15, "flow": 2.5e-5, "node_lost": False}
    return {"run_id": "r-gap", "point": 1, "spin_rpm": spin_rpm, "drives": {"spin": drive, "orbit": drive}, "aux": aux}


def publish_samples(broker, spin_rpm: float, count: int) -> None:
    for _ in range(count):  # the dashboard takes one trend sample a second
        done = broker.pub(f"orbitrig/{RIG}/live", json.dumps(live(spin_rpm)), user="orbitrig-service", qos=0)
        assert done.returncode == 0, done.stderr
        time.sleep(1.3)


def viewer_of_a_run(broker, dashboard, browsers, run_id: str) -> Page:
    """A viewer's page signed in while the service says run `run_id` is running."""
    status = {"state": "running", "run_id": run_id, "since": "2026-12-05T01:00:00.000Z", "message": "run started"}
    broker.pub(f"orbitrig/{RIG}/status", json.dumps(status), user="orbitrig-service", retain=True)
    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in("viewer", ACCOUNTS["viewer"])
    page.signed_in()
    page.wait_state("running", 15)
    return page


def speed_chart(page) -> dict[str, str]:
    return page.d.execute_script("return Object.assign({}, document.getElementById('trend-speed').dataset)")


def test_a_silence_in_the_samples_is_not_bridged_by_a_line(broker, dashboard, browsers):
    page = viewer_of_a_run(broker, dashboard, browsers, "r-gap")
    publish_samples(broker, 1000.0, 3)
    page.wait(lambda: int(speed_chart(page).get("samples", 0)) >= 3 * 4, 10, "3 samples of each speed")
    assert speed_chart(page)["pieces"] == "1,1,1,1"  # spin, spin set, orbit, orbit set: one line each
    time.sleep(8)  # nothing published: longer than 5 s and three 1 s steps
    publish_samples(broker, 1200.0, 3)
    page.wait(lambda: int(speed_chart(page).get("samples", 0)) >= 6 * 4, 10, "3 more samples of each speed")
    assert speed_chart(page)["pieces"] == "2,2,2,2", speed_chart(page)


def test_the_window_follows_the_clock_while_no_sample_comes(broker, dashboard, browsers):
    """A service that hangs (or a run that ended) sends no sample: the charts still move on with the clock
    (redrawn every 2 s), so the last samples leave the right edge instead of standing there as the present."""
    page = viewer_of_a_run(broker, dashboard, browsers, "r-clock")
    publish_samples(broker, 1000.0, 2)
    page.wait(lambda: int(speed_chart(page).get("samples", 0)) >= 2 * 4, 10, "2 samples of each speed")
    until, seen = float(speed_chart(page)["until"]), time.time()
    time.sleep(6)  # nothing published
    moved = float(speed_chart(page)["until"]) - until
    assert 3 <= moved <= time.time() - seen + 2.5, moved  # each read at most 2 s after its redraw (1 s margin)


def test_the_axes_are_those_of_the_samples_the_window_shows(broker, dashboard, browsers):
    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in("viewer", ACCOUNTS["viewer"])
    page.signed_in()
    page.wait_text("link", "online")
    # a sample 11 min old (outside the 10 min window) at 5000 rpm, one of now at 1000 rpm
    page.d.execute_script(
        "trends.trendClear(); const now = Date.now() / 1000;"
        "trends.trendSample({t: now - 660, spin_rpm: 5000, torque_spin: 90}, 'r-old');"
        "trends.trendSample({t: now - 2, spin_rpm: 1000}, 'r-old'); trends.drawTrends();"
    )
    speed = speed_chart(page)
    assert speed["series"] == "spin" and max(float(t) for t in speed["ticks"].split()) < 2000, speed
    torque = page.d.execute_script("return Object.assign({}, document.getElementById('trend-torque').dataset)")
    assert torque["series"] == "", torque  # no torque in the window: no legend of an old one
