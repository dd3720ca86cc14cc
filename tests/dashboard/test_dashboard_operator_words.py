"""What the page says, as an operator reads it, in a real chromium on a real authenticated mosquitto:
the sensors of a lost CAN node are greyed and the card says they are the last it sent (the node's
faulty-sensor and pump-off flags said there too, in a place of their own: nothing moves); live values
no longer coming are greyed and each card says how old they are (the run's progress and ETA with them);
a sensor outside its band says so in words; a value not known is "—" without a unit; a speed reads in
one form on the Run card and in the Drives table, the terminal's ("1000 rpm", not "1000.0"); alarm and
event times are a 24 h clock with an ISO date, whatever the browser's locale. The test publishes what
the rig service would (as orbitrig-service)."""

from __future__ import annotations

import math
import re
import time

import pytest
from support.dash_helpers import Page, dashboard_running, publish_as_service
from support.mqtt_helpers import ACCOUNTS

RUN = "r-words"


@pytest.fixture(scope="module")
def dashboard(broker, tmp_path_factory):
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


def status(state: str, message: str, since: str) -> dict:
    return {"state": state, "run_id": RUN, "since": since, "message": message}


def live(k: int, **flags: bool) -> dict:
    aux = {"p_supply": 1.9e6, "t_supply": 313.15, "flow": 2.1e-5, "node_lost": False, "sensor_fault": False}
    aux.update({"pump_off": False, **flags})
    drive = {"reference_rpm": 1000.0, "actual_rpm": 1000.0, "torque_pct": 2.0, "state": "running"}
    return {
        "run_id": RUN,
        "point": 1,
        "revolutions": k,
        "spin_rpm": 1000.0,
        "orbit_hz": None,
        "aux": aux,
        "drives": {"spin": drive, "orbit": dict(drive, actual_rpm=None)},
    }


def sensors_height(page: Page) -> float:
    return page.d.execute_script(
        "return document.getElementById('aux').closest('section').getBoundingClientRect().height"
    )


@pytest.fixture
def page(broker, dashboard, browsers) -> Page:
    publish_as_service(broker, "status", status("running", "run started", "2026-12-05T01:00:00.000Z"), retain=True)
    p = Page(browsers(), dashboard.url, dashboard)
    p.sign_in("viewer", ACCOUNTS["viewer"])
    p.signed_in()
    p.wait_state("running", 15)
    return p


def test_a_lost_can_node_greys_the_sensors_and_says_so(broker, page):
    publish_as_service(broker, "live", live(1), qos=0)
    page.wait(lambda: "1.9000" in page.text("aux"), 10, "a value")
    assert page.text("aux-state") == ""
    height = sensors_height(page)
    publish_as_service(broker, "live", live(2, node_lost=True), qos=0)
    page.wait_text("aux-state", "CAN sensor node lost: the values are the last it sent, not the present", 10)
    assert "stale" in page.el("aux").get_attribute("class")
    assert sensors_height(page) == height  # the note has its own place
    publish_as_service(broker, "live", live(3, sensor_fault=True, pump_off=True), qos=0)
    page.wait_text("aux-state", "the CAN node reports a faulty sensor; the supply pump is off", 10)
    assert "stale" not in (page.el("aux").get_attribute("class") or "")
    assert sensors_height(page) == height


def test_a_value_not_known_is_a_dash_without_a_unit(broker, page):
    publish_as_service(broker, "live", live(1), qos=0)
    page.wait_text("op-spin", "1000 rpm", 10)
    assert page.text("op-orbit-hz") == "—"  # orbit_hz null: no revolutions coming in now
    assert page.text("op-orbit") == "—"


def test_speeds_read_as_the_terminal_says_them_on_the_run_card_and_in_the_drives_table(broker, page):
    payload = live(1)
    payload["spin_rpm"] = 999.9  # the drive's reading in its 0.15 rpm steps
    payload["drives"]["spin"]["actual_rpm"] = 999.9
    payload["drives"]["orbit"].update(reference_rpm=-977.7777777, actual_rpm=-977.7777777)
    publish_as_service(broker, "live", payload, qos=0)
    page.wait_text("op-spin", "999.9 rpm", 10)
    assert page.text("op-orbit") == "-977.778 rpm"
    rows = {k: " ".join(v.split()) for k, v in page.rows("drives", "drive").items()}
    assert rows == {
        "spin": "spin 1000 999.9 2.0 running none",
        "orbit": "orbit -977.778 -977.778 2.0 running none",
    }, rows


def live_old(page: Page) -> dict:
    """Whether the page marks the live values as not the present, and what each card says."""
    script = (
        "return {old: document.getElementById('app').classList.contains('live-old'),"
        " notes: [...document.querySelectorAll('.live-note')].map(e => e.textContent),"
        " spin: getComputedStyle(document.getElementById('op-spin')).color,"
        " greyed: ['point', 'block', 'revolutions', 'eta', 'progress-bar'].map(id => {"
        "  const s = getComputedStyle(document.getElementById(id)); return s.color + ' ' + s.backgroundColor; }),"
        " held: document.getElementById('eta-held').textContent,"
        " age: document.getElementById('live-age').textContent}"
    )
    return page.d.execute_script(script)


def test_live_values_no_longer_coming_are_greyed_and_said_old(broker, page):
    """A service that hangs (its last will comes 15 s later) or an acquisition that stalls leaves the last live
    payload on the page: past 3 s (15 payloads missed) its values are greyed, and each card says so in words."""
    progress = {"run_id": RUN, "point": 2, "points": 3, "frequency": 4, "frequencies": 10, "revolutions": 31}
    publish_as_service(broker, "progress", dict(progress, block_revolutions=50, eta_s=750.0, fraction=0.4), qos=0)
    page.wait_text("eta", "12:30", 10)
    publish_as_service(broker, "live", live(1), qos=0)
    page.wait_text("op-spin", "1000 rpm", 10)
    seen, fresh = time.monotonic(), live_old(page)
    assert not fresh["old"] and fresh["notes"] == ["", "", ""] and fresh["held"] == "", fresh
    page.wait(lambda: live_old(page)["old"], 10, "the live values marked old")
    assert time.monotonic() - seen >= 2.0  # not before the limit (3 s since the page got them)
    old = live_old(page)
    assert old["notes"] == [old["notes"][0]] * 3, old
    assert re.fullmatch(r"\(the last live values, [3-9] s old: not the present\)", old["notes"][0]), old
    assert old["age"].endswith(" s ago: not the present") and old["spin"] != fresh["spin"], old
    assert page.text("op-spin") == "1000 rpm"  # the last values stay, marked
    # the run's progress comes with its live values: the point, block, revolutions, ETA and bar are the last
    # known too, greyed, and the line under the ETA says so (an ETA standing still is not the rig's time left)
    assert all(now != then for now, then in zip(old["greyed"], fresh["greyed"])), (old, fresh)
    assert re.fullmatch(r"\(the last known, [3-9] s old: not the present\)", old["held"]), old
    assert (page.text("point"), page.text("block"), page.text("eta")) == ("2 / 3", "4 of 10", "12:30")
    publish_as_service(broker, "live", live(2), qos=0)  # the payloads come again: live at once
    page.wait(lambda: not live_old(page)["old"], 5, "the live values current again")
    back = live_old(page)
    assert back["notes"] == ["", "", ""] and back["held"] == "" and back["greyed"] == fresh["greyed"], back


def test_a_sensor_outside_its_band_says_so_in_words(broker, page):
    """Not in red alone (a reader who does not tell red, a grey print): as the manual panel says it."""
    bands = {"p_supply": [0.2e6, 8.0e6], "p_recess": [0.4343e6, 0.5309e6]}
    payload = live(1)
    payload["aux"].update(p_supply=9.1e6, p_recess_1=0.48e6, p_recess_2=0.40e6)
    publish_as_service(broker, "live", dict(payload, bands=bands), qos=0)
    page.wait(lambda: "9.1000" in page.text("aux"), 10, "the values")
    rows = {k: " ".join(v.split()) for k, v in page.rows("aux", "aux").items()}
    assert rows["p_supply"] == "supply pressure (MPa) 9.1000 (outside the band) 0.2000 … 8.0000", rows
    assert rows["p_recess_2"].startswith("recess pressure 2 (MPa) 0.4000 (outside the band) "), rows
    assert rows["p_recess_1"] == "recess pressure 1 (MPa) 0.4800 0.4343 … 0.5309", rows
    assert rows["t_supply"] == "supply temperature (°C) 40.00", rows  # no band: nothing said


def test_times_are_a_24_hour_clock_with_an_iso_date(broker, page):
    since = "2026-12-05T13:14:27.511Z"  # afternoon in UTC: a 12 h clock would say PM
    publish_as_service(
        broker, "status", status("paused", "suspended by interlock: CAN sensor node lost", since), retain=True
    )
    page.wait(lambda: page.rows("alarms", "alarm"), 10, "the alarm")
    first = page.d.execute_script("return document.querySelector('#alarms tr td').textContent")
    assert re.fullmatch(r"2026-12-0[56] \d\d:14:27", first), first
    events = page.d.execute_script("return [...document.querySelectorAll('#events li')].map(li => li.textContent)")
    assert events and all(re.match(r"\d\d:\d\d:\d\d [^AP]", e) for e in events), events


def test_how_a_run_ended_stays_listed_when_the_service_goes_offline_at_once(broker, page):
    ended = "run stopped: stopped at once by the service shutting down on SIGTERM; point 0002 (14 blocks stored)"
    publish_as_service(broker, "status", status("idle", ended, "2026-12-05T01:25:26.144Z"))
    publish_as_service(broker, "status", status("offline", "service stopped", "2026-12-05T01:25:26.145Z"), retain=True)
    page.wait_state("offline", 10)
    page.wait_text("events", lambda t: f"run {RUN} stopped: stopped at once by the service shutting down" in t, 10)
    assert "point 0002 (14 blocks stored)" in page.text("events")


def test_a_circular_orbit_is_drawn_round(broker, page):
    n, r = 45, 5e-6  # a 5 um circle, over one revolution
    xs = [r * math.cos(2 * math.pi * k / n) for k in range(n)]
    ys = [r * math.sin(2 * math.pi * k / n) for k in range(n)]
    payload = dict(live(1), waveforms={"x_a": xs, "x_b": xs, "y_a": ys, "y_b": ys})
    publish_as_service(broker, "live", payload, qos=0)
    page.wait(lambda: page.el("plot-orbit").get_attribute("data-samples") == "45", 10, "the orbit plot")
    # the trace's extent in canvas pixels (its colour, #1976d2), across and up
    box = page.d.execute_script(
        "const c = document.getElementById('plot-orbit'), d = c.getContext('2d').getImageData(0, 0, c.width, c.height);"
        "let x0 = 1e9, x1 = -1, y0 = 1e9, y1 = -1;"
        "for (let y = 0; y < c.height; y++) for (let x = 0; x < c.width; x++) { const i = 4 * (y * c.width + x);"
        "  if (Math.abs(d.data[i] - 25) < 30 && Math.abs(d.data[i + 1] - 118) < 30 && Math.abs(d.data[i + 2] - 210) < 30"
        "      && d.data[i + 3] > 200) { x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y); } }"
        "return [x1 - x0, y1 - y0];"
    )
    across, up = box
    assert across > 40 and abs(across - up) <= 2, box  # equal scales: as wide as tall, to 2 pixels
