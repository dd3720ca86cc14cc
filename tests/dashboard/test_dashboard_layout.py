"""The page's layout in a real chromium on a real authenticated mosquitto, at a laptop's
1280 x 800 and in one column at 800 px: the status message is shown whole (the waiting prompt
says whether the drives turn, an end says why); the manual setting panel fits its card and says
whether the drives turn; nothing on the page moves when the panel appears or goes or the first
alarm comes; a page load asks for no missing icon. The tests publish what the rig service would
(as orbitrig-service), the messages in the service's own words."""

from __future__ import annotations

import time

import pytest
from orbitrig.run.control import CLOSING_RAMP
from support.dash_helpers import Page, dashboard_running, publish_as_service
from support.mqtt_helpers import ACCOUNTS

SIZES = [(1280, 800), (800, 800)]

#: the service's waiting prompt with the drives turning (orbitrig/run/procedure.py: set_manual)
TURNING = (
    "set by hand and confirm: manual settings (set by hand): orbit radius 5.76 um, static eccentricity "
    "ratio 0.15 (e/C), recess pressure 0.4826 MPa, pressure ratio 0.4; the drives are turning: spin "
    "1000 rpm, orbit 500 rpm (confirm step 'manual:0001')"
)
ENDS = (
    "run aborted: aborted by operator; point 0000 (2 blocks stored) is incomplete: orbitrig sweep "
    "--resume measures it again from its start (its blocks so far kept in aside/)",
    "drives not confirmed stopped: DriveLinkError: spin drive (id 1), register CW (0): cannot connect "
    "to tcp://127.0.0.1:40489 (the run was ending failed: interlock: Modbus link to the drives lost)",
)


@pytest.fixture(scope="module")
def dashboard(broker, tmp_path_factory):
    """The dashboard alone on the broker (no rig service)."""
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


@pytest.fixture
def own_dashboard(broker, tmp_path):
    """A dashboard of the test's own: its alarm list starts empty (alarms stay latched per dashboard)."""
    with dashboard_running(broker.url, tmp_path) as dash:
        yield dash


def status(broker, state: str, message: str, run_id: str | None = "r-layout") -> None:
    publish_as_service(
        broker, "status", {"state": state, "run_id": run_id, "since": "2026-01-05T13:00:00.000Z", "message": message}
    )


def waiting(message: str = TURNING, outside: bool = True) -> dict:
    """A waiting status as the service publishes it; `outside`: every measured value outside its band."""

    def setting(value, unit, half, measured):
        return {"value": value, "unit": unit, "measured": measured, "band": [value - half, value + half]}

    far = 2.0 if outside else 1.0
    return {
        "state": "waiting",
        "run_id": "r-layout",
        "since": "2026-01-05T13:00:00.000Z",
        "step": "manual:0001",
        "message": message,
        "settings": {
            "orbit_radius": setting(5.76e-6, "m", 0.864e-6, 5.76e-6 * far),
            "static_eccentricity": setting(0.15, "1", 0.05, 0.15 * far),
            "recess_pressure": setting(0.4826e6, "Pa", 0.04826e6, 0.4826e6 * far),
            "pressure_ratio": setting(0.4, "1", 0.05, 0.4 * far),
        },
    }


#: a progress as the service publishes it (eta_s: the plan's rig time left, wall s)
PROGRESS = {
    "run_id": "r-layout",
    "point": 12,
    "points": 120,
    "frequency": 10,
    "frequencies": 12,
    "revolutions": 12345,
    "eta_s": 4000,
}


def live(run_id: str = "r-layout") -> dict:
    """Live values as long as they come (the drives' table, the sensors' bands, the run's numbers)."""
    drive = {"reference_rpm": 1000.0, "actual_rpm": 1000.0, "torque_pct": 12.5, "state": "ready to switch on"}
    aux = {f"p_recess_{k}": 0.4830e6 for k in range(1, 5)}
    aux.update(p_supply=1.206e6, t_supply=313.15, t_recess=314.25, t_groove=313.81, flow=2.1e-5, beta=0.4)
    return {
        "run_id": run_id,
        "point": 12,
        "frequency": 10,
        "direction": "backward",
        "revolutions": 12345,
        "orbit_hz": 20.0,
        "spin_rpm": 1000.0,
        "drives": {"link_ok": True, "spin": drive, "orbit": {**drive, "actual_rpm": 500.0}},
        "aux": aux,
        "bands": {"p_supply": [0.2e6, 8.0e6], "p_recess": [0.4343e6, 0.5309e6], "beta": [0.35, 0.45]},
        "waveforms": {},
    }


def open_page(browsers, dashboard, size: tuple[int, int]) -> Page:
    d = browsers()
    d.set_window_size(*size)
    page = Page(d, dashboard.url, dashboard)
    page.sign_in("operator", ACCOUNTS["operator"])
    page.signed_in()
    page.wait_text("link", "online")
    assert d.execute_script("return innerWidth") == size[0]
    return page


def message_box(page: Page) -> dict:
    """The message element's box, its text's box and the top of what follows it (px)."""
    return page.d.execute_script(
        "const m = document.getElementById('message'), r = m.getBoundingClientRect(), range = document.createRange();"
        "range.selectNodeContents(m); const t = range.getBoundingClientRect();"
        "return {scroll: m.scrollHeight, client: m.clientHeight, bottom: r.bottom, right: r.right,"
        " text_bottom: t.bottom, text_right: t.right, next_top: m.nextElementSibling.getBoundingClientRect().top,"
        " text: m.textContent};"
    )


def assert_whole(page: Page, message: str) -> None:
    box = message_box(page)
    assert box["text"] == message
    assert box["scroll"] <= box["client"], f"the message scrolls inside its box: {box}"
    assert box["text_bottom"] <= box["bottom"] + 0.5 and box["text_right"] <= box["right"] + 0.5, box
    assert box["bottom"] <= box["next_top"], f"the message runs over the progress bar: {box}"


#: every element drawn outside its card: "card: element left..right (card left..right)"
OUTSIDE_CARDS = r"""
const out = [];
document.querySelectorAll('main > section').forEach(card => {
  const c = card.getBoundingClientRect(), name = card.id || card.querySelector('h2').textContent.trim();
  card.querySelectorAll('*').forEach(e => {
    if (!e.getClientRects().length) return;
    const r = e.getBoundingClientRect();
    if (r.width && (r.right > c.right + 0.5 || r.left < c.left - 0.5 || r.bottom > c.bottom + 0.5))
      out.push(name + ': ' + e.tagName.toLowerCase() + (e.id ? '#' + e.id : '') + ' ' + r.left.toFixed(1) + '..'
        + r.right.toFixed(1) + ' (card ' + c.left.toFixed(1) + '..' + c.right.toFixed(1) + ')');
  });
});
return out;"""


def layout(page: Page) -> dict[str, list[float]]:
    """(left, top) of every card, in page pixels."""
    return page.d.execute_script(
        "const out = {}; document.querySelectorAll('main > section').forEach((s, i) => {"
        " const r = s.getBoundingClientRect(); out[s.id || 'card ' + i] = [r.left, r.top + scrollY]; }); return out;"
    )


def moved(before: dict, after: dict) -> dict:
    return {
        k: (before[k], after[k])
        for k in before
        if abs(before[k][0] - after[k][0]) + abs(before[k][1] - after[k][1]) > 0.5
    }


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}px")
def test_the_whole_message_is_shown(broker, dashboard, browsers, size):
    page = open_page(browsers, dashboard, size)
    status(broker, "idle", "service ready", None)
    page.wait_text("message", "service ready", 10)
    publish_as_service(broker, "status", waiting())
    page.wait(lambda: page.el("manual").is_displayed(), 10, "the manual setting panel")
    # the tail says whether the shaft turns: to the person about to put hands on the rig
    assert_whole(page, TURNING)
    for end in ENDS:
        status(broker, "idle", end)
        page.wait_text("message", end, 10)
        assert_whole(page, end)


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}px")
def test_manual_panel_fits_its_card_and_says_whether_the_drives_turn(broker, dashboard, browsers, size):
    page = open_page(browsers, dashboard, size)
    publish_as_service(broker, "status", waiting(outside=True))
    page.wait(lambda: page.el("manual").is_displayed(), 10, "the manual setting panel")
    publish_as_service(broker, "progress", PROGRESS, qos=0)
    publish_as_service(broker, "live", live(), qos=0)
    page.wait_text("eta", "1:06:40", 10)
    assert page.text("eta-held") == "(paused: waiting for the operator)"
    page.wait(lambda: "0.4830" in page.rows("aux", "aux").get("p_recess_1", ""), 10, "the live sensors")
    rows = page.rows("manual-table", "setting")
    assert all("(outside the band)" in text for text in rows.values()), rows
    assert "0.4343 … 0.5309" in rows["recess_pressure"].replace("\n", " ")
    table = page.d.execute_script(
        "const t = document.querySelector('#manual table').getBoundingClientRect(),"
        " c = document.getElementById('manual-card'), r = c.getBoundingClientRect(), s = getComputedStyle(c);"
        "return [t.right, r.right - parseFloat(s.borderRightWidth) - parseFloat(s.paddingRight)];"
    )
    assert table[0] <= table[1] + 0.5, f"the manual table ends at {table[0]}, its card's content at {table[1]}"
    assert page.d.execute_script(OUTSIDE_CARDS) == []  # the Run card's table, the Band column included

    # the drives' motion, as the service's prompt says it, in the panel itself
    motion = page.el("manual-motion")
    assert motion.text == "The drives are turning: spin 1000 rpm, orbit 500 rpm"
    assert "turning" in motion.get_attribute("class").split()
    standstill = TURNING.replace("the drives are turning: spin 1000 rpm, orbit 500 rpm", "both drives at standstill")
    publish_as_service(broker, "status", waiting(standstill, outside=False))
    page.wait_text("manual-motion", "Both drives at standstill", 10)
    assert "turning" not in motion.get_attribute("class").split()
    measured = page.d.execute_script("return document.querySelector('#manual-table tr').children[2].innerText")
    assert measured == "5.76"  # inside its band: no note
    publish_as_service(
        broker,
        "status",
        waiting("point 0001: manual settings not met: pressure ratio 0.52 (confirm step 'verify:0001')"),
    )
    page.wait_text("manual-motion", "", 10)  # a prompt that does not say: nothing guessed
    status(broker, "idle", "run stopped")
    page.wait(lambda: not page.el("manual").is_displayed(), 10, "the panel to close")


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}px")
def test_nothing_moves_when_the_manual_panel_or_the_first_alarm_appears(broker, own_dashboard, browsers, size):
    page = open_page(browsers, own_dashboard, size)
    status(broker, "idle", "service ready", None)
    page.wait_text("message", "service ready", 10)
    page.wait_text("alarm-count", "none unacknowledged", 10)
    status(broker, "running", "running")
    publish_as_service(broker, "progress", PROGRESS, qos=0)
    page.wait_text("eta", "1:06:40", 10)
    before = layout(page)

    publish_as_service(broker, "status", waiting(outside=True))  # the tallest panel: every value outside its band
    page.wait(lambda: page.el("manual").is_displayed(), 10, "the manual setting panel")
    # under the ETA, in a line of its own: why it stands still
    assert (page.text("eta"), page.text("eta-held")) == ("1:06:40", "(paused: waiting for the operator)")
    assert moved(before, layout(page)) == {}
    assert page.d.execute_script(OUTSIDE_CARDS) == []
    status(broker, "running", "confirmed manual:0001")
    page.wait(lambda: not page.el("manual").is_displayed(), 10, "the panel to go")
    assert moved(before, layout(page)) == {}

    assert (page.text("eta"), page.text("eta-held")) == ("1:06:40", "")

    status(broker, "paused", "suspended by interlock: lubricant supply pump is off")
    page.wait(lambda: page.d.find_elements("css selector", "#alarms button.ack"), 10, "the first alarm")
    assert (page.text("eta"), page.text("eta-held")) == ("1:06:40", "(paused with the run)")
    assert moved(before, layout(page)) == {}
    assert page.d.execute_script(OUTSIDE_CARDS) == []
    status(broker, "idle", "run stopped")


@pytest.mark.parametrize("size", [*SIZES, (1200, 900), (1400, 900), (1920, 1080)], ids=lambda s: f"{s[0]}px")
def test_nothing_moves_when_live_values_come_or_leave_their_band(broker, own_dashboard, browsers, size):
    """The drives' and sensors' rows stand as tall before the first live message ("—", no band)
    as with their values and bands, and a value said outside its band in words does not widen
    its column (which would wrap the names and move every card below, as the operator looks)."""
    page = open_page(browsers, own_dashboard, size)
    status(broker, "running", "running")
    page.wait_text("message", "running", 10)
    before = layout(page)
    publish_as_service(broker, "live", live(), qos=0)
    page.wait(lambda: "0.4343" in page.rows("aux", "aux").get("p_recess_1", ""), 10, "the live sensors and bands")
    assert moved(before, layout(page)) == {}
    outside = live()
    outside["aux"].update(beta=0.25, p_recess_1=0.3e6, p_supply=9.0e6)
    publish_as_service(broker, "live", outside, qos=0)
    page.wait(lambda: "(outside the band)" in page.rows("aux", "aux").get("beta", ""), 10, "a value outside its band")
    assert moved(before, layout(page)) == {}
    assert page.d.execute_script(OUTSIDE_CARDS) == []
    status(broker, "idle", "run stopped")


#: the free room (px) of each row of the page's cards: main's content width less its cards' and their gaps
ROOM = r"""
const main = document.querySelector('main'), m = main.getBoundingClientRect(), cs = getComputedStyle(main);
const right = m.right - parseFloat(cs.paddingRight), boxes = [...document.querySelectorAll('main > section')]
  .map(card => card.getBoundingClientRect());
// at each card's top: the rightmost edge of the cards there (one of an earlier row reaching down included)
return boxes.map(b => Math.round(right - Math.max(...boxes.filter(o => o.top <= b.top + 1 && o.bottom > b.top + 1)
  .map(o => o.right))));"""

#: per chart of a card: [its right edge's distance to the card's content edge, its drawing width, its width on the page]
CHARTS = r"""
const card = document.getElementById(arguments[0]), c = card.getBoundingClientRect(), cs = getComputedStyle(card);
const edge = c.right - parseFloat(cs.paddingRight);
return [...card.querySelectorAll('canvas')].map(k => [Math.round(edge - k.getBoundingClientRect().right), k.width, k.clientWidth]);"""

#: per chart of a card drawn already at its place's width (class fluid): [its drawing width, its figure's width
#: less the canvas's border]
FITTED = r"""
return [...document.getElementById(arguments[0]).querySelectorAll('canvas.fluid')].filter(k => Number(k.dataset.updates) > 0)
  .map(k => [k.width, Math.floor(k.parentElement.getBoundingClientRect().width) - 2]);"""


@pytest.mark.parametrize("size", [(1280, 800), (1920, 1080)], ids=lambda s: f"{s[0]}px")
def test_a_wide_window_leaves_no_column_empty(broker, own_dashboard, browsers, size):
    """Every row of cards reaches the page's right edge (the first row: the Run card with the drives and
    sensors beside it), and the charts share their card's width, drawn in the page's pixels."""
    page = open_page(browsers, own_dashboard, size)
    status(broker, "running", "running")
    wave = [0.5e-5 * ((k % 36) - 18) / 18 for k in range(360)]  # m, over one revolution
    publish_as_service(
        broker, "live", {**live(), "waveforms": dict.fromkeys(("x_a", "y_a", "x_b", "y_b"), wave)}, qos=0
    )
    page.wait(lambda: page.canvas_updates("plot-disp") >= 1, 10, "the averaged revolution drawn")
    assert all(room < 2 for room in page.d.execute_script(ROOM)), page.d.execute_script(ROOM)
    run = page.d.find_element("css selector", "main > .run").rect
    assert page.el("drives-card").rect["y"] == page.el("sensors-card").rect["y"] == run["y"]  # beside the Run card
    # the six trends in two rows of three, each as wide as its third of the card, not stretched
    page.wait(lambda: all(w == cw for _, w, cw in page.d.execute_script(CHARTS, "trends-card")), 10, "trends drawn")
    trends = page.d.execute_script(CHARTS, "trends-card")
    tops = sorted({page.el(f"trend-{n}").rect["y"] for n in ("speed", "supply", "recess", "temperature", "flow")})
    assert len(tops) == 2 and trends[2][0] < 2 and trends[5][0] < 2, trends  # the third and sixth reach the edge
    revolution = page.d.execute_script(CHARTS, "revolution-card")
    assert revolution[2][0] < 2 and revolution[1][1] == revolution[1][2] > 420, revolution  # displacements, orbit
    # a window made narrower (800 px): the trends one a row, each drawn again as wide as the card, not cut
    page.d.set_window_size(800, size[1])
    narrow = lambda: page.d.execute_script(CHARTS, "trends-card")  # noqa: E731
    page.wait(lambda: all(edge < 2 and w == cw for edge, w, cw in narrow()), 10, f"the trends redrawn: {narrow()}")
    # and the displacements (the payload's only waveforms) drawn again at their figure's new width, no live
    # payload since
    fitted = lambda: page.d.execute_script(FITTED, "revolution-card")  # noqa: E731
    page.wait(lambda: [w == room for w, room in fitted()] == [True], 10, f"the displacements redrawn: {fitted()}")
    status(broker, "idle", "run stopped")
    # the run's view emptied at its end: a window made wider again draws the trends again, not its revolution
    page.wait(lambda: page.el("plot-disp").get_attribute("data-samples") == "0", 10, "the revolution cleared")
    drawn = page.canvas_updates("plot-disp")
    page.d.set_window_size(*size)
    wide = lambda: page.d.execute_script(CHARTS, "trends-card")  # noqa: E731
    page.wait(lambda: wide()[2][0] < 2 and all(w == cw for _, w, cw in wide()), 10, f"the trends redrawn: {wide()}")
    assert page.canvas_updates("plot-disp") == drawn


def test_a_page_load_asks_for_no_missing_icon(dashboard, browsers):
    """The page names its icon (inline): no request for /favicon.ico, which the server has not."""
    d = browsers()
    d.get_log("browser")  # (empties the log)
    page = Page(d, dashboard.url, dashboard)
    page.wait(lambda: page.el("signin").is_displayed(), 15, "the sign-in form")
    time.sleep(1.0)  # the browser asks for the icon after the page's load
    severe = [e["message"] for e in d.get_log("browser") if e["level"] == "SEVERE"]
    assert not [m for m in severe if "favicon" in m], severe
    # the one left: the page's check for a session, refused as documented (401: not signed in)
    assert all("/api/session" in m and "401" in m for m in severe), severe


#: a ready status of a service restarted after an aborted run (orbitrig.service.last_run: the store's words)
LAST_RUN = {
    "run_id": "sim-rig@2026-01-05T12:40:02.125Z",
    "outcome": "aborted",
    "message": "aborted by ada; point 0000 (2 blocks stored) is incomplete: orbitrig sweep --resume measures it "
    "again from its start (its blocks so far kept in aside/)",
    "folder": "/srv/orbitrig/runs/20260105T124002.125Z-demo",
    "ended_at": "2026-01-05T12:41:17.504Z",
}
#: an operating point's label as its result names it (orbitrig.run.plan.OperatingPoint.label)
LABEL = "w1000rpm_pr0.4826MPa_b0.4_es0.15_ed0.096"


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}px")
def test_the_last_run_and_the_operating_point_take_their_places_and_move_nothing(broker, own_dashboard, browsers, size):
    page = open_page(browsers, own_dashboard, size)
    status(broker, "running", "running")
    publish_as_service(broker, "progress", PROGRESS, qos=0)
    page.wait_text("eta", "1:06:40", 10)
    assert page.text("point-label") == "—"  # a service that does not name the point: nothing guessed
    before = layout(page)

    publish_as_service(broker, "progress", {**PROGRESS, "point_label": LABEL}, qos=0)
    page.wait_text("point-label", LABEL, 10)
    assert moved(before, layout(page)) == {}
    assert page.d.execute_script(OUTSIDE_CARDS) == []

    # a restarted service's ready status: how the last run ended, as the store recorded it
    ready = {"state": "idle", "run_id": None, "since": "2026-01-05T13:00:00.000Z", "message": "service ready"}
    publish_as_service(broker, "status", {**ready, "last_run": LAST_RUN})
    page.wait(lambda: page.d.find_elements("id", "last-run"), 10, "the last run's line")
    at = page.d.execute_script("return orbitPlots.dateTimeOf(arguments[0])", LAST_RUN["ended_at"])  # local time
    said = f"last run sim-rig@2026-01-05T12:40:02.125Z aborted at {at}, folder /srv/orbitrig/runs/20260105T124002.125Z-demo"
    assert page.text("last-run") == said and page.el("last-run").get_attribute("title") == LAST_RUN["message"]
    assert page.text("point-label") == "—"  # the run's view emptied with its end
    box = message_box(page)
    assert box["scroll"] <= box["client"] and box["bottom"] <= box["next_top"], box  # inside the message's room
    assert moved(before, layout(page)) == {}

    publish_as_service(broker, "status", {**ready, "last_run": {**LAST_RUN, "outcome": "running", "ended_at": None}})
    page.wait_text("last-run", lambda t: "still recorded as running" in t, 10)  # a kill left it so: no end said
    assert f" at {at}" not in page.text("last-run")
    status(broker, "running", "run started")  # a run of this service: its own statuses say it
    page.wait(lambda: not page.d.find_elements("id", "last-run"), 10, "the last run's line to go")
    assert moved(before, layout(page)) == {}
    status(broker, "idle", "run stopped")


def test_the_operating_point_line_names_what_the_status_names(broker, own_dashboard, browsers):
    """Between points the line names the next point, said as next; in the closing ramp none."""
    page = open_page(browsers, own_dashboard, SIZES[0])
    nxt = LABEL.replace("w1000rpm", "w2000rpm")
    said = {"run_id": "r-layout", "since": "2026-01-05T13:00:00.000Z"}
    measuring = f"measuring point 12 of 120: {LABEL} (point 0011)"
    publish_as_service(broker, "status", {**said, "state": "running", "message": measuring, "point_label": LABEL})
    page.wait_text("point-label", LABEL, 10)
    paused = f"paused at a safe point (drives keep their speeds); next: point 13 of 120: {nxt} (point 0012)"
    between = {"point_label": nxt, "between_points": True}
    publish_as_service(broker, "status", {**said, "state": "paused", "message": paused, **between})
    page.wait_text("point-label", f"next: {nxt}", 10)  # not the point done
    assert page.el("point-label").get_attribute("title") == f"next: {nxt}"
    publish_as_service(broker, "status", {**said, "state": "running", "message": CLOSING_RAMP})
    page.wait_text("point-label", "—", 10)  # no point under way: none named


#: the Run card's numbers with their units, each read as one piece ("1000.05 rpm", not "rpm" on a line of its own)
WITH_UNITS = ("op-spin", "op-orbit", "op-orbit-hz", "eta", "revolutions", "point", "block")


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}px")
def test_a_run_card_number_stays_on_one_line_with_its_unit(broker, dashboard, browsers, size):
    page = open_page(browsers, dashboard, size)
    status(broker, "running", "running")
    page.wait_text("message", "running", 10)
    publish_as_service(broker, "progress", {**PROGRESS, "block_revolutions": 50000}, qos=0)
    body = live()
    body.update(spin_rpm=1000.05, orbit_hz=-19.99)
    body["drives"]["orbit"]["actual_rpm"] = -1199.95
    publish_as_service(broker, "live", body, qos=0)
    page.wait_text("op-orbit", "-1199.95 rpm", 10)
    lines = page.d.execute_script(
        "return arguments[0].map(id => { const r = document.createRange();"
        " r.selectNodeContents(document.getElementById(id));"
        " return [id, document.getElementById(id).textContent, new Set([...r.getClientRects()].map(b => b.top)).size]; })",
        list(WITH_UNITS),
    )
    assert [line for line in lines if line[2] != 1] == [], lines
    assert page.d.execute_script(OUTSIDE_CARDS) == []
    status(broker, "idle", "run stopped")


#: the banner's box, the header's ABORT button's and the top of the page's first cards (px in the window: the
#: Run card's heading, the Commands card's), at the scroll given
BANNER_BOXES = (
    "window.scrollTo(0, arguments[0]);"
    " const box = el => { const r = el.getBoundingClientRect(); return [r.top, r.bottom]; };"
    " return {banner: box(document.getElementById('offline-banner')), header: box(document.getElementById('btn-abort')),"
    " cards: Math.min(...[...document.querySelectorAll('main > .card')].slice(0, 2).map(c => box(c)[0]))};"
)


@pytest.mark.parametrize("size", [(1024, 768), (1920, 1080)], ids=lambda s: f"{s[0]}px")
def test_the_offline_banner_hides_nothing_and_stays_in_view(broker, dashboard, browsers, size):
    """The banner (the rig service or the broker gone, the feed stale) has a room of its own under the header:
    it covered the Run card's state and run id, what the operator reads first; scrolled, it stays in view
    under the header as the ABORT button does."""
    page = open_page(browsers, dashboard, size)
    status(broker, "running", "running")
    page.wait_state("running", 10)
    status(broker, "offline", "connection to the rig service lost")
    page.wait_text("offline-banner", "offline: the rig service is not connected", 10)
    top = page.d.execute_script(BANNER_BOXES, 0)
    assert top["banner"][1] <= top["cards"], top  # the Run card whole below the banner, not under it
    assert page.el("state").is_displayed() and page.el("run-id").is_displayed()
    scrolled = page.d.execute_script(BANNER_BOXES, 600)
    assert scrolled["banner"] == top["banner"] and scrolled["header"] == top["header"], scrolled  # both in view
    status(broker, "idle", "run stopped")
    page.wait(lambda: not page.el("offline-banner").is_displayed(), 10, "the banner to go")
