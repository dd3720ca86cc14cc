"""A broker restart with its persistence on (as config/mosquitto/mosquitto.conf has it), in a real
chromium on a real authenticated mosquitto: the dashboard's session outlives the restart, so a
result published while the dashboard's link was down (cut by a relay) comes when it is back, and
the page says the results caught up, with no gap row. mosquitto 2.0 saves to its persistence only
the sessions not begun with a clean start. The test publishes what the rig service would."""

from __future__ import annotations


import json
import subprocess
import time

import pytest
from support.dash_helpers import RIG, Dashboard, Page, dashboard_running, idle_page, publish_as_service
from support.mqtt_helpers import ACCOUNTS, Broker

RUN = "r-restart"
#: s of the window around an outage (link_lost.WILL_NEAR_OUTAGE_S) of a test's own dashboard: its will older
GRACE_S = 2.0


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


WILL = {
    "state": "offline",
    "run_id": None,
    "since": "2026-12-05T00:59:00.000Z",
    "message": "connection to the rig service lost",
    "last_will": "the broker published this last will, registered when the service connected (2026-12-05T00:59:00.000Z)",
}


def signed_in_page(browsers, dashboard) -> Page:
    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in("viewer", ACCOUNTS["viewer"])
    page.signed_in()
    return page


def offline_words(page: Page) -> dict[str, str]:
    """What the page says of the rig service besides its badge: the watched rig's entry in the header's selector,
    Start's tooltip, and the ABORT confirmation's words (as set, open or not)."""
    script = """const sel = document.getElementById('rig-select');
      return {rig: sel.options[sel.selectedIndex].textContent, start: document.getElementById('btn-start').title,
        abort: document.getElementById('abort-question').textContent};"""
    return page.d.execute_script(script)


def test_a_last_will_that_came_with_a_broker_outage_is_not_read_as_the_service_gone(broker, relay, dashboard, browsers):
    """The broker publishes the service's last will as it stops and keeps it until the service reconnects, while
    the run goes on: a page that saw its own broker link go down says the service's state is unknown, its link
    lost, not `offline`; a session signed in after the outage did not see it and reads the will as the contract
    says (offline)."""
    running = {"state": "running", "run_id": "r-will", "since": "2026-12-05T01:00:01.000Z", "message": "run started"}
    publish_as_service(broker, "status", running, retain=True)
    page = signed_in_page(browsers, dashboard)
    page.wait_state("running", 15)

    relay.cut()
    page.wait_text("link", "broker unreachable", 15)
    publish_as_service(broker, "status", WILL, retain=True)  # the will, as the broker publishes it going down
    relay.restore()
    page.wait_text("link", "online", 30)
    page.wait_text("state", "unknown — link lost", 10)
    message = page.text("message")
    assert message.startswith("the rig service's state is unknown: its link to the broker was lost in a broker outage")
    assert "the run may go on on the rig" in message and message.endswith("Its last status said: " + WILL["message"])
    assert "offline" not in page.el("state").get_attribute("class")
    assert page.text("offline-banner").startswith("the rig service's link to the broker was lost in a broker outage")
    assert page.text("run-id") == "r-will"  # the run on view stays
    # the rig selector, Start, Pause and Resume's tooltips and the ABORT confirmation say what the badge says
    page.wait(lambda: offline_words(page)["rig"].endswith(" (unknown — link lost)"), 5, "the selector's words")
    said = offline_words(page)
    lost = "the rig service's state is unknown — link lost: the dashboard sends it only STOP and ABORT"
    assert said["start"] == "not now: " + lost
    assert page.el("btn-resume").get_attribute("title") == "not now: " + lost
    assert said["abort"].endswith(
        "? The rig service's state is unknown — link lost: it may not hear the abort;"
        " if the drives turn, use the rig's emergency stop."
    )

    other = signed_in_page(browsers, dashboard)  # loaded after the outage: the will as the contract reads it
    other.wait_state("offline", 15)
    assert other.text("message") == WILL["message"]
    other.wait(lambda: offline_words(other)["rig"].endswith(" (offline)"), 5, "the selector's words")
    said = offline_words(other)
    assert said["start"] == "not now: the rig service is offline: the dashboard sends it only STOP and ABORT"
    assert "? The rig service is offline: it may not hear the abort;" in said["abort"]

    publish_as_service(broker, "status", running, retain=True)  # the service back: its statuses say the state
    page.wait_state("running", 10)
    assert page.text("message") == "run started" and page.text("offline-banner") == ""


def test_a_last_will_heard_before_a_broker_outage_stays_offline_after_it(broker, relay, browsers, tmp_path):
    """A service gone before the outage (its will retained, the page showing it offline): the broker hands the
    same retained will again when the dashboard's link is back, and that copy did not come with the outage, so
    the page still says `offline`, not `unknown — link lost` (the run may go on) for a service gone long before."""
    publish_as_service(broker, "status", WILL, retain=True)
    dash = Dashboard(relay.url, RIG, tmp_path, "--reply-timeout", "1.5", will_grace=GRACE_S)
    try:
        page = signed_in_page(browsers, dash)
        page.wait_state("offline", 15)  # the dashboard has heard the will
        time.sleep(GRACE_S + 0.2)  # the will heard longer ago than the window around an outage
        said_across_an_outage(page, relay)
    finally:
        assert dash.stop() == 0, dash.text()[-3000:]


def said_across_an_outage(page: Page, relay) -> None:
    """The page across a cut of the dashboard's broker link: still the will's `offline` for 4 s once back."""
    relay.cut()
    page.wait_text("link", "broker unreachable", 15)
    relay.restore()
    page.wait_text("link", "online", 30)
    deadline = time.monotonic() + 4  # the retained will comes again on the session's subscription
    while time.monotonic() < deadline:
        assert page.text("state") != "unknown — link lost", page.text("message")
        time.sleep(0.2)
    assert page.text("message") == WILL["message"]


def test_the_dashboard_servers_own_refusals_in_a_broker_outage_say_what_is_known(broker, relay, dashboard, browsers):
    """The dashboard server refuses Start while the rig's status says offline (the broker would keep it for the
    service), and says an abort is kept for nobody: when that offline is the last will of a broker outage its
    session saw, its words say the service's state is unknown, its link lost, as the page's badge does (before,
    'the rig service is offline' beside a badge 'unknown — link lost')."""
    running = {"state": "running", "run_id": "r-refused", "since": "2026-12-05T01:00:02.000Z", "message": "run"}
    publish_as_service(broker, "status", running, retain=True)
    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in("operator", ACCOUNTS["operator"])
    page.signed_in()
    page.wait_state("running", 15)
    relay.cut()
    page.wait_text("link", "broker unreachable", 15)
    publish_as_service(broker, "status", WILL, retain=True)
    relay.restore()
    page.wait_text("link", "online", 30)
    page.wait_text("state", "unknown — link lost", 10)
    try:
        start = page.send("start", "start:", matrix="demo")
        assert start == (
            "start: not sent: the rig service's state is unknown — link lost (its link to the broker was lost in a "
            "broker outage; the run may go on on the rig): try again when it reconnects"
        ), start
        abort = page.send("abort", "abort:")
        assert abort.startswith(
            "abort: the rig service's state is unknown — link lost: the broker does not keep an abort for it; "
            "use the rig's emergency stop"
        ), abort
    finally:
        publish_as_service(broker, "status", running, retain=True)


def rig_options(page: Page) -> dict[str, tuple[str, str]]:
    """The header's rig selector: rig id -> (its entry's words, its tooltip)."""
    script = "return [...document.getElementById('rig-select').options].map(o => [o.value, o.textContent, o.title]);"
    return {rig: (text, title) for rig, text, title in page.d.execute_script(script)}


def publish_other_rig(broker, rig: str, status: dict) -> None:
    """A status of another rig's service on the same broker (retained, as a service's is)."""
    done = broker.pub(f"orbitrig/{rig}/status", json.dumps(status), user="orbitrig-service", retain=True)
    assert done.returncode == 0, done.stderr


def test_the_rig_selector_tells_another_rigs_last_will_of_an_outage_from_its_service_gone(
    broker, relay, dashboard, browsers
):
    """Another rig's entry in the header's selector follows the badge's rule: its last will that came with a broker
    outage the page saw is 'unknown — link lost' (the reason in its tooltip), while its service's own goodbye
    ('rig service stopped', no last will) stays 'offline'; 10 s after the link was back, its service not back, the
    will is 'offline' too. Before, both said 'offline' once the page's link was back (and later, the will stayed
    'unknown — link lost' for good)."""
    running = {"state": "running", "run_id": "r-other", "since": "2026-12-05T01:00:03.000Z", "message": "run"}
    gone = {**WILL, "message": "rig service stopped"}
    del gone["last_will"]
    for rig in ("rig-will", "rig-gone"):
        publish_other_rig(broker, rig, running)
    publish_as_service(broker, "status", running, retain=True)
    page = signed_in_page(browsers, dashboard)
    page.wait_state("running", 15)
    page.wait(lambda: {"rig-will", "rig-gone"} <= set(rig_options(page)), 10, "both rigs listed")

    relay.cut()
    page.wait_text("link", "broker unreachable", 15)
    publish_other_rig(broker, "rig-will", WILL)  # its service's link lost as the broker went down
    publish_other_rig(broker, "rig-gone", gone)  # its service stopped meanwhile, saying so itself
    relay.restore()
    page.wait_text("link", "online", 30)
    page.wait(lambda: rig_options(page)["rig-gone"][0] == "rig-gone (offline)", 10, "the service gone said offline")
    text, tooltip = rig_options(page)["rig-will"]
    assert text == "rig-will (unknown — link lost)", text
    assert tooltip.startswith("the rig service's state is unknown: its link to the broker was lost in a broker outage")
    assert rig_options(page)["rig-gone"][1] == ""

    other = signed_in_page(browsers, dashboard)  # loaded after the outage: the will as the contract reads it
    other.wait(lambda: rig_options(other).get("rig-will", ("",))[0] == "rig-will (offline)", 10, "the will as offline")
    # its service not back 10 s after the link was (link_lost.WILL_NEAR_OUTAGE_S): offline, as the broker says it
    page.wait(lambda: rig_options(page)["rig-will"] == ("rig-will (offline)", ""), 20, "the will offline after 10 s")


def test_a_wall_clock_stepped_back_in_an_outage_leaves_its_last_will_unknown(broker, relay, dashboard, browsers):
    """The outage and when a last will was heard are timed on the server's monotonic clock (time.monotonic()), the
    page showing its reading: the browser's wall clock stepped back an hour during the outage (Date.now(), an NTP
    step) still reads the will that came with it 'unknown — link lost'. Before, it read 'offline'."""
    running = {"state": "running", "run_id": "r-step", "since": "2026-12-05T01:00:05.000Z", "message": "run"}
    publish_other_rig(broker, "rig-step", running)
    publish_as_service(broker, "status", running, retain=True)
    page = signed_in_page(browsers, dashboard)
    page.wait_state("running", 15)
    page.wait(lambda: "rig-step" in rig_options(page), 10, "the rig listed")

    relay.cut()
    page.wait_text("link", "broker unreachable", 15)
    page.d.execute_script("const wall = Date.now; Date.now = () => wall() - 3600e3;")
    publish_other_rig(broker, "rig-step", WILL)
    relay.restore()
    page.wait_text("link", "online", 30)
    page.wait(lambda: rig_options(page)["rig-step"][0] != "rig-step (running)", 10, "the will listed")
    assert rig_options(page)["rig-step"][0] == "rig-step (unknown — link lost)", rig_options(page)["rig-step"]


def test_a_last_will_near_an_outage_is_read_unknown_until_10_s_after_the_link_is_back():
    """The session's reading (orbitrig/dashboard/link_lost.py), which the page shows as sent with each status: a last
    will heard from 10 s before the outage began is `unknown — link lost` while the outage lasts and until 10 s
    after the link was back (the service's time to reconnect), then `offline` (the service still away: the will
    as the contract reads it); 1 ms beyond either edge, `offline`; the service's own offline never. Before, a will
    that came with an outage stayed unknown for good."""
    from orbitrig.dashboard.link_lost import Outage, link_lost

    start, end = 100.0, 130.0
    gone = {key: value for key, value in WILL.items() if key != "last_will"}
    over, on = Outage(start, end), Outage(start)
    assert not link_lost(WILL, start - 10.001, on, start) and link_lost(WILL, start - 10.0, on, start + 500)
    assert link_lost(WILL, start, over, end) and link_lost(WILL, end, over, end + 10.0)
    assert not link_lost(WILL, end, over, end + 10.001)  # the grace over: offline
    assert not link_lost(WILL, end + 10.001, over, end + 10.001) and not link_lost(WILL, start, over, end + 60)
    assert not any(link_lost(gone, at, o, at) for at in (start, 115.0, end) for o in (over, on))
    assert not link_lost(WILL, None, over, end) and not link_lost(WILL, start, None, end)


def test_the_rig_selector_follows_the_link_with_no_status_of_the_rig_watched(broker, relay, dashboard, browsers):
    """The header's selector says another rig's offline anew as the page's broker link goes down, also while the
    rig watched has no status yet (its service never connected): its last will heard as 'offline' just before is
    'unknown — link lost' while the link is down. Before, the selector was named again only with a status of the
    rig watched, and kept 'offline'."""
    clear = ["mosquitto_pub", *broker.client_args("orbitrig-service"), "-t", f"orbitrig/{RIG}/status", "-r", "-n"]
    cleared = subprocess.run(clear, capture_output=True, timeout=10, check=False)  # its retained status gone
    assert cleared.returncode == 0, cleared.stderr
    try:
        page = signed_in_page(browsers, dashboard)
        page.wait_text("link", "online", 15)
        publish_other_rig(broker, "rig-quiet", WILL)
        page.wait(lambda: rig_options(page).get("rig-quiet", ("",))[0] == "rig-quiet (offline)", 10, "the will")
        relay.cut()
        page.wait_text("link", "broker unreachable", 15)
        page.wait(
            lambda: rig_options(page)["rig-quiet"][0] == "rig-quiet (unknown — link lost)",
            5,
            "the will unknown while the link is down",
        )
    finally:
        relay.restore()
        publish_as_service(broker, "status", {"state": "idle", "run_id": None, "since": WILL["since"]}, retain=True)
