"""The dashboard for a shift in a real chromium, on a real authenticated mosquitto. The tests
publish what a rig service would (known values, as orbitrig-service): trends with nice ticks
and the service's bands over the last N minutes or the run; latched alarms and their
acknowledgement (operators only); the manual panel's band highlight; sign-out; several rigs."""

from __future__ import annotations

import itertools
import json
import time

import pytest
from support.dash_helpers import Page, RIG, card_shot, chromium, dashboard_running
from support.mqtt_helpers import ACCOUNTS


@pytest.fixture(scope="module")
def dashboard(broker, tmp_path_factory):
    """The dashboard alone on the broker: these tests publish what the rig service would."""
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


@pytest.fixture(scope="module")
def drivers(tmp_path_factory):
    """Two headless chromiums for the whole module (an operator's and a viewer's)."""
    root = tmp_path_factory.mktemp("chromium")
    made = [chromium(root), chromium(root)]
    yield made
    for d in made:
        d.quit()


@pytest.fixture
def browsers(drivers):
    """The module's browsers one after the other, each signed out (no session cookie)."""
    left = list(drivers)

    def make():
        d = left.pop(0)
        d.get("about:blank")
        d.delete_all_cookies()
        return d

    return make


def fresh_page(browsers, dashboard) -> Page:
    page = Page(browsers(), dashboard.url, dashboard)
    page.d.delete_all_cookies()  # the dashboard's own cookie (set for its origin)
    page.d.refresh()
    return page


def live_payload(k: int) -> dict:
    """A live payload of run r-trend: spin 1000 rpm, orbit 600 rpm, pressures and temperatures."""
    return {
        "run_id": "r-trend",
        "point": 1,
        "frequency": 1,
        "direction": "forward",
        "revolutions": k,
        "orbit_hz": 10.0,
        "spin_rpm": 1000.0,
        "drives": {
            "link_ok": True,
            "spin": {"reference_rpm": 1000.0, "actual_rpm": 998.0 + k, "torque_pct": 20.0, "state": "running"},
            "orbit": {"reference_rpm": 600.0, "actual_rpm": 600.0, "torque_pct": 5.0, "state": "running"},
        },
        "aux": {
            "p_supply": 2.0e6,
            "p_recess_1": 0.47e6,
            "p_recess_2": 0.48e6,
            "p_recess_3": 0.49e6,
            "p_recess_4": 0.50e6,
            "t_supply": 313.15,
            "t_recess": 318.15,
            "t_groove": 320.15,
            "flow": 2.5e-5,
            "beta": 0.40,
            "node_lost": False,
        },
        "waveforms": {},
        "units": {},
        "bands": {"p_supply": [0.2e6, 8.0e6], "p_recess": [0.432e6, 0.528e6], "beta": [0.35, 0.45]},
    }


def canvas(page: Page, element_id: str) -> dict[str, str]:
    return page.d.execute_script("return Object.assign({}, document.getElementById(arguments[0]).dataset)", element_id)


def test_trends_draw_the_live_samples_with_bands_and_nice_ticks(broker, dashboard, browsers):
    page = fresh_page(browsers, dashboard)
    page.sign_in("viewer", ACCOUNTS["viewer"])
    page.signed_in()
    page.wait_text("link", "online")
    for k in range(4):  # the dashboard takes one trend sample a second (one closer than 0.95 s is dropped)
        done = broker.pub(f"orbitrig/{RIG}/live", json.dumps(live_payload(k)), user="orbitrig-service", qos=0)
        assert done.returncode == 0, done.stderr
        time.sleep(1.5)  # room for uneven delivery on a busy host
    page.wait(lambda: int(canvas(page, "trend-speed").get("samples", 0)) >= 4 * 4, 10, "4 speed samples")

    speed = canvas(page, "trend-speed")
    assert speed["series"] == "spin,spin set,orbit,orbit set"
    ticks = [float(t) for t in speed["ticks"].split()]
    assert ticks[0] <= 600 and ticks[-1] >= 1001 and len(ticks) <= 7
    steps = {round(b - a, 6) for a, b in itertools.pairwise(ticks)}
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
    page.d.execute_script(
        "const s = document.getElementById('trend-window'); s.value = 'run';s.dispatchEvent(new Event('change'))"
    )
    assert int(canvas(page, "trend-speed")["samples"]) >= 16
    # the page's own arrays stay bounded: 1800 recent samples, the run's view plus 600 since it
    kept = page.d.execute_script(
        "const s = trendState.recent[trendState.recent.length - 1], kept = trendState.runKept || 0;"
        "for (let k = 1; k <= 5000; k++) trends.trendSample(Object.assign({}, s, {t: s.t + k}), trendState.runId);"
        "return [trendState.recent.length, trendState.run.length, kept, trendState.run[0].t];"
    )
    assert kept[0] == 1800 and kept[1] == kept[2] + 600  # (the server sends its view every 300 samples)

    late = fresh_page(browsers, dashboard)
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
        " cells: [...r.children].map(c => c.innerText)}))"
    )


def flagged(page: Page, said: str | None) -> None:
    """An unacknowledged alarm is said where the operator looks whatever the page shows: scrolled down to the
    events, the sticky header's flag (in view; a click brings the list) and the tab's title (a tab in the
    background); `said` None: neither says one."""
    page.d.execute_script("window.scrollTo(0, document.body.scrollHeight)")
    flag = page.d.find_element("css selector", "#alarm-flag")
    if said is None:
        assert not flag.is_displayed() and page.d.title == "orbitrig \u2014 live view"
        return
    assert flag.is_displayed() and flag.text == "\u26a0 " + said.replace(" unacknowledged", "")
    top = page.d.execute_script("return arguments[0].getBoundingClientRect().top", flag)
    assert 0 <= top < page.d.execute_script("return innerHeight")  # in view, scrolled to the bottom
    assert page.d.title == "\u26a0 " + said + " \u2014 orbitrig \u2014 live view"
    flag.click()
    # the list in view, under the sticky header (where it is on the page depends on the window's width)
    card = (
        "const c = document.getElementById('alarms-card').getBoundingClientRect(),"
        " l = document.getElementById('alarms').getBoundingClientRect();"
        "return c.top >= document.querySelector('.top').getBoundingClientRect().bottom && l.bottom <= innerHeight"
    )
    page.wait(lambda: page.d.execute_script(card), 5, "the alarm list in view")
    page.d.execute_script("window.scrollTo(0, 0)")


def test_alarms_latch_until_an_operator_acknowledges_them(broker, dashboard, browsers, tmp_path):
    operator, viewer = (fresh_page(browsers, dashboard) for _ in range(2))
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
    flagged(viewer, "1 unacknowledged alarm")
    assert row["cells"][1:4] == ["trip", "suspended by interlock: lubricant supply pump is off", "active"]
    assert row["cells"][0] == viewer.d.execute_script("return orbitPlots.dateTimeOf(arguments[0])", trip_since)  # local

    # the condition clears: the trip stays latched (unacknowledged) until someone acknowledges it
    publish_status(
        broker,
        "running",
        "interlock cleared (supply_pump): settling and acquiring the block again",
        "2026-01-05T10:00:05.000Z",
    )
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
        flagged(page, None)

    # a run failed by an interlock is a trip, failed otherwise a fault; newest first
    publish_status(
        broker,
        "faulted",
        "run of 'demo' failed: interlock: spin drive tripped: fault 7 overcurrent",
        "2026-01-05T11:00:00.000Z",
        "r-alarm-2",
    )
    publish_status(
        broker,
        "faulted",
        "run of 'demo' failed: no revolutions from the A/D board",
        "2026-01-05T12:00:00.000Z",
        "r-alarm-3",
    )
    operator.wait(lambda: len(alarm_rows(operator)) == 3, 10, "three alarms")
    assert [r["cells"][1] for r in alarm_rows(operator)] == ["fault", "trip", "trip"]
    assert operator.text("alarm-count") == "2 unacknowledged"
    card_shot(operator, "alarms-card", "alarms", tmp_path)
    publish_status(broker, "idle", "run stopped", "2026-01-05T12:00:01.000Z", "r-alarm-3")


def waiting_status(measured_ratio: float) -> dict:
    """A waiting status as the service publishes it: pressure ratio asked 0.400 (band 0.35..0.45)."""

    def setting(value, unit, measured, half):
        return {"value": value, "unit": unit, "measured": measured, "band": [value - half, value + half]}

    return {
        "state": "waiting",
        "run_id": "r-manual",
        "since": "2026-01-05T13:00:00.000Z",
        "step": "manual:0000",
        "message": "set by hand and confirm: manual settings (set by hand): orbit radius 5.76 um, static eccentricity"
        " ratio 0 (e/C), recess pressure 0.4826 MPa, pressure ratio 0.4; both drives at standstill (confirm step"
        " 'manual:0000')",
        "settings": {
            "orbit_radius": setting(5.76e-6, "m", 5.70e-6, 0.864e-6),
            "static_eccentricity": setting(0.0, "1", 0.01, 0.05),
            "recess_pressure": setting(0.4826e6, "Pa", 0.48e6, 0.04826e6),
            "pressure_ratio": setting(0.4, "1", measured_ratio, 0.05),
        },
    }


def manual_rows(page: Page) -> dict[str, tuple[str, str]]:
    """{setting: (measured cell text, row class)}."""
    return {
        k: tuple(v)
        for k, v in page.d.execute_script(
            "const out = {}; document.querySelectorAll('#manual-table tr').forEach(r => {"
            " out[r.dataset.setting] = [r.children[2].innerText, r.className]; }); return out;"
        ).items()
    }


def test_manual_panel_highlights_a_measured_value_outside_its_band(broker, dashboard, browsers, tmp_path):
    page = fresh_page(browsers, dashboard)
    page.sign_in("viewer", ACCOUNTS["viewer"])
    page.signed_in()
    page.wait_text("link", "online")
    done = broker.pub(f"orbitrig/{RIG}/status", json.dumps(waiting_status(0.25)), user="orbitrig-service")
    assert done.returncode == 0, done.stderr
    page.wait(lambda: page.el("manual").is_displayed(), 10, "the manual setting panel")
    rows = manual_rows(page)
    assert rows["pressure_ratio"] == ("0.250 (outside the band)", "outside")  # asked 0.400 +/- 0.05
    assert rows["recess_pressure"] == ("0.4800", "") and rows["orbit_radius"] == ("5.70", "")
    assert "0.350 … 0.450" in page.rows("manual-table", "setting")["pressure_ratio"]
    # a ratio says of what, as the prompt does ("static eccentricity ratio 0 (e/C)"): not read as a length
    assert page.rows("manual-table", "setting")["static_eccentricity"].startswith("static eccentricity (e/C)")
    assert page.text("manual-motion") == "Both drives at standstill"  # the prompt's word on the drives
    card_shot(page, "manual-card", "manual", tmp_path)

    # the live payload carries the settings as measured now: the panel follows it
    live = {
        **live_payload(0),
        "run_id": "r-manual",
        "settings_measured": {"pressure_ratio": 0.40, "orbit_radius": 7.5e-6},
    }
    done = broker.pub(f"orbitrig/{RIG}/live", json.dumps(live), user="orbitrig-service", qos=0)
    assert done.returncode == 0, done.stderr
    page.wait(lambda: manual_rows(page)["pressure_ratio"] == ("0.400", ""), 10, "the live pressure ratio")
    assert manual_rows(page)["orbit_radius"] == ("7.50 (outside the band)", "outside")  # 5.76 um +/- 15 %
    publish_status(broker, "idle", "run stopped", "2026-01-05T13:00:05.000Z", "r-manual")
    page.wait(lambda: not page.el("manual").is_displayed(), 10, "the panel to close")


def test_sign_out_leaves_nothing_of_the_previous_person(broker, dashboard, browsers):
    page = fresh_page(browsers, dashboard)
    page.sign_in("viewer", ACCOUNTS["viewer"])
    page.signed_in()
    page.wait_text("link", "online")
    assert "refused: not authorised" in page.command("btn-pause", "refused")
    assert "refused: not authorised" in page.text("events")
    page.el("signout").click()
    page.wait(lambda: page.el("signin").is_displayed(), 10, "the sign-in form")
    assert page.el("user").get_attribute("value") == "" and page.el("password").get_attribute("value") == ""
    page.el("user").send_keys("operator")  # typed into an empty field: nothing appended
    assert page.el("user").get_attribute("value") == "operator"
    page.el("password").send_keys(ACCOUNTS["operator"])
    page.el("signin-btn").click()
    page.signed_in()
    page.wait_text("link", "online")
    assert page.text("who") == "operator"
    assert page.text("events") == "" and page.text("cmd-result") == ""  # the viewer's refusals are gone
    assert page.text("alarm-count") and page.rows("aux", "aux")  # the rig's view drawn again


def choose_rig(page: Page, rig_id: str) -> None:
    """Pick a rig in the header's selector (in one go: the options are redrawn as statuses arrive)."""
    page.d.execute_script(
        "const s = document.getElementById('rig-select'); s.value = arguments[0];s.dispatchEvent(new Event('change'))",
        rig_id,
    )


def rig_options(page: Page) -> list[str]:
    return page.d.execute_script("return [...document.getElementById('rig-select').options].map(o => o.text)")


def test_several_rigs_on_one_broker_are_listed_and_selectable(broker, dashboard, browsers):
    for rig, state in (("rig-b", "idle"), ("rig-c", "offline")):  # retained, as each rig's service leaves them
        status = {"state": state, "run_id": None, "since": "2026-01-05T14:00:00.000Z", "message": f"{rig} {state}"}
        done = broker.pub(f"orbitrig/{rig}/status", json.dumps(status), user="orbitrig-service", retain=True)
        assert done.returncode == 0, done.stderr
    page = fresh_page(browsers, dashboard)
    page.sign_in("operator", ACCOUNTS["operator"])
    page.signed_in()
    page.wait_text("link", "online")
    page.wait(lambda: {"rig-b (idle)", "rig-c (offline)"} <= set(rig_options(page)), 10, "the rigs on the broker")
    assert page.text("rig") == f"orbitrig/{RIG}"
    publish_status(
        broker, "paused", "suspended by interlock: lubricant supply pump is off", "2026-01-05T14:00:01.000Z", "r-here"
    )
    page.wait_text("alarm-count", lambda t: t.endswith(" unacknowledged") and not t.startswith("none"), 10)

    choose_rig(page, "rig-b")
    page.wait_text("rig", "orbitrig/rig-b", 10)
    page.wait_state("idle", 10)  # rig-b's retained status
    assert page.text("message") == "rig-b idle"
    assert page.text("alarm-count") == "none unacknowledged"  # the other rig's alarm is not this one's
    failed = {
        "state": "faulted",
        "run_id": "r-here",
        "since": "2026-01-05T14:00:02.000Z",
        "message": "run of 'demo' failed: no revolutions",
    }  # on the first rig, retained
    assert (
        broker.pub(f"orbitrig/{RIG}/status", json.dumps(failed), user="orbitrig-service", retain=True).returncode == 0
    )
    done = broker.pub("orbitrig/rig-b/live", json.dumps(live_payload(0)), user="orbitrig-service", qos=0)
    assert done.returncode == 0, done.stderr
    page.wait(lambda: int(canvas(page, "trend-speed").get("samples", 0)) >= 4, 10, "rig-b's trend")
    assert page.state() == "idle" and page.text("alarm-count") == "none unacknowledged"
    # another person choosing rig-b later sees its trend so far at once (from the first session)
    other = fresh_page(browsers, dashboard)
    other.sign_in("viewer", ACCOUNTS["viewer"])
    other.signed_in()
    other.wait(lambda: "rig-b (idle)" in rig_options(other), 10, "the rigs")
    choose_rig(other, "rig-b")
    other.wait(lambda: int(canvas(other, "trend-speed").get("samples", 0)) >= 4, 10, "rig-b's trend so far")
    choose_rig(page, RIG)
    page.wait_text("rig", f"orbitrig/{RIG}", 10)
    page.wait_state("faulted", 10)  # its retained status, and the alarm it raises (beside the alarms of
    page.wait(
        lambda: (
            {"id": "r-here@2026-01-05T14:00:02.000Z", "cls": "unacked"}.items()  # sessions on it)
            <= next((r for r in alarm_rows(page) if r["id"].startswith("r-here@")), {}).items()
        ),
        10,
        "the alarm",
    )
    page.wait(lambda: any("rig-b" in o for o in rig_options(page)), 5, "the rigs listed again")
    for rig in (RIG, "rig-b", "rig-c"):
        broker.pub(f"orbitrig/{rig}/status", "", user="orbitrig-service", retain=True)  # clears the retained
