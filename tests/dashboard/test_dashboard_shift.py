"""The dashboard for a shift in a real chromium. Trends: live payloads published on the real broker as the rig
service would (known values) become the speed, pressure, temperature, flow and torque
trends, with nice ticks, the service's bands, and a window of the last N minutes or the run."""

from __future__ import annotations

import json
import time

from dash_helpers import RIG, Page
from mqtt_helpers import ACCOUNTS


def live_payload(k: int) -> dict:
    """A live payload of run r-trend: spin 1000 rpm, orbit 600 rpm, pressures and temperatures."""
    return {"run_id": "r-trend", "point": 1, "frequency": 1, "direction": "forward", "revolutions": k,
            "orbit_hz": 10.0, "spin_rpm": 1000.0,
            "drives": {"link_ok": True,
                       "spin": {"reference_rpm": 1000.0, "actual_rpm": 998.0 + k, "torque_pct": 20.0, "state": "running"},
                       "orbit": {"reference_rpm": 600.0, "actual_rpm": 600.0, "torque_pct": 5.0, "state": "running"}},
            "aux": {"p_supply": 2.0e6, "p_recess_1": 0.47e6, "p_recess_2": 0.48e6, "p_recess_3": 0.49e6,
                    "p_recess_4": 0.50e6, "t_supply": 313.15, "t_recess": 318.15, "t_groove": 320.15,
                    "flow": 2.5e-5, "beta": 0.40, "node_lost": False},
            "waveforms": {}, "units": {}, "bands": {"p_supply": [0.2e6, 8.0e6], "p_recess": [0.432e6, 0.528e6],
                                                    "beta": [0.35, 0.45]}}


def canvas(page: Page, element_id: str) -> dict[str, str]:
    return page.d.execute_script("return Object.assign({}, document.getElementById(arguments[0]).dataset)", element_id)


def test_trends_draw_the_live_samples_with_bands_and_nice_ticks(broker, dashboard, browsers):
    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in("viewer", ACCOUNTS["viewer"])
    page.signed_in()
    page.wait_text("link", "online")
    for k in range(4):  # the dashboard takes one trend sample a second
        done = broker.pub(f"orbitrig/{RIG}/live", json.dumps(live_payload(k)), user="orbitrig-service", qos=0)
        assert done.returncode == 0, done.stderr
        time.sleep(1.05)
    page.wait(lambda: int(canvas(page, "trend-speed").get("samples", 0)) >= 4 * 4, 10, "4 speed samples")

    speed = canvas(page, "trend-speed")
    assert speed["series"] == "spin,spin set,orbit,orbit set"
    ticks = [float(t) for t in speed["ticks"].split()]
    assert ticks[0] <= 600 and ticks[-1] >= 1001 and len(ticks) <= 7
    steps = {round(b - a, 6) for a, b in zip(ticks, ticks[1:])}
    assert len(steps) == 1 and steps.pop() in (100.0, 200.0, 250.0, 500.0)  # a round step, no raw extremes
    supply = canvas(page, "trend-supply")
    assert supply["band"] == "0.2,8" and supply["ticks"] == "0 2 4 6 8"  # MPa: the interlock band shown
    recess = canvas(page, "trend-recess")
    assert recess["series"] == "recess 1,recess 2,recess 3,recess 4"
    assert [round(float(v), 3) for v in recess["band"].split(",")] == [0.432, 0.528]
    assert canvas(page, "trend-temperature")["series"] == "supply,recess,groove"
    temps = [float(t) for t in canvas(page, "trend-temperature")["ticks"].split()]
    assert temps[0] <= 40.0 and temps[-1] >= 47.0  # °C, not K
    flow = [float(t) for t in canvas(page, "trend-flow")["ticks"].split()]
    assert flow[0] <= 1.5 <= flow[-1] < 3.0  # 2.5e-5 m^3/s = 1.5 l/min
    assert canvas(page, "trend-torque")["series"] == "spin,orbit"

    # the whole run's view: the same samples; a page opened later gets the history at once
    page.d.execute_script("const s = document.getElementById('trend-window'); s.value = 'run';"
                          "s.dispatchEvent(new Event('change'))")
    assert int(canvas(page, "trend-speed")["samples"]) >= 16
    late = Page(browsers(), dashboard.url, dashboard)
    late.sign_in("operator", ACCOUNTS["operator"])
    late.signed_in()
    late.wait(lambda: int(canvas(late, "trend-speed").get("samples", 0)) >= 16, 10, "the history on sign-in")


def publish_status(broker, state: str, message: str, since: str, run_id: str = "r-alarm") -> None:
    """A status as the rig service publishes it (not retained: the real service's stays)."""
    status = {"state": state, "run_id": run_id, "since": since, "message": message}
    done = broker.pub(f"orbitrig/{RIG}/status", json.dumps(status), user="orbitrig-service")
    assert done.returncode == 0, done.stderr


def alarm_rows(page: Page) -> list[dict]:
    return page.d.execute_script(
        "return [...document.querySelectorAll('#alarms tr')].map(r => ({id: r.dataset.alarm, cls: r.className,"
        " cells: [...r.children].map(c => c.innerText)}))")


def test_alarms_latch_until_an_operator_acknowledges_them(broker, dashboard, browsers):
    operator, viewer = (Page(browsers(), dashboard.url, dashboard) for _ in range(2))
    for page, user in ((operator, "operator"), (viewer, "viewer")):
        page.sign_in(user, ACCOUNTS[user])
        page.signed_in()
        page.wait_text("link", "online")
    trip_since = "2026-01-05T10:00:00.000Z"
    publish_status(broker, "paused", "suspended by interlock: lubricant supply pump is off", trip_since)
    for page in (operator, viewer):
        page.wait(lambda p=page: len(alarm_rows(p)) == 1, 10, "the trip in the alarm list")
        page.wait_text("alarm-count", "1 unacknowledged", 5)
    row = alarm_rows(viewer)[0]
    assert row["id"] == f"r-alarm@{trip_since}" and row["cls"] == "unacked"
    assert row["cells"][1:4] == ["trip", "suspended by interlock: lubricant supply pump is off", "active"]

    # the condition clears: the trip stays latched (unacknowledged) until someone acknowledges it
    publish_status(broker, "running", "interlock cleared (supply_pump): settling and acquiring the block again",
                   "2026-01-05T10:00:05.000Z")
    viewer.wait(lambda: alarm_rows(viewer)[0]["cells"][3] == "cleared", 10, "the trip cleared")
    assert alarm_rows(viewer)[0]["cls"] == "unacked" and viewer.text("alarm-count") == "1 unacknowledged"

    # a viewer may not acknowledge (the broker drops the message); an operator may
    viewer.d.find_element("css selector", "#alarms button.ack").click()
    refused = viewer.wait_text("alarm-result", lambda t: "sent" not in t and t != "", 10)
    assert "refused: not authorised" in refused and "'viewer' may not acknowledge" in refused
    assert alarm_rows(operator)[0]["cls"] == "unacked"
    operator.d.find_element("css selector", "#alarms button.ack").click()
    assert operator.wait_text("alarm-result", lambda t: "sent" not in t and t != "", 10) == "acknowledge: done"
    for page in (operator, viewer):
        page.wait_text("alarm-count", "none unacknowledged", 10)
        row = alarm_rows(page)[0]
        assert row["cls"] == "acked" and row["cells"][4].startswith("operator, ")
        assert not page.d.find_elements("css selector", "#alarms button.ack")

    # a run failed by an interlock is a trip, failed otherwise a fault; newest first
    publish_status(broker, "faulted", "run of 'demo' failed: interlock: spin drive tripped: fault 7 overcurrent",
                   "2026-01-05T11:00:00.000Z", "r-alarm-2")
    publish_status(broker, "faulted", "run of 'demo' failed: no revolutions from the A/D board",
                   "2026-01-05T12:00:00.000Z", "r-alarm-3")
    operator.wait(lambda: len(alarm_rows(operator)) == 3, 10, "three alarms")
    assert [r["cells"][1] for r in alarm_rows(operator)] == ["fault", "trip", "trip"]
    assert operator.text("alarm-count") == "2 unacknowledged"
    publish_status(broker, "idle", "run stopped", "2026-01-05T12:00:01.000Z", "r-alarm-3")
