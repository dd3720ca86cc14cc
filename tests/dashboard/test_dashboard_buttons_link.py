"""Start, Pause and Resume follow what the page knows of the way to the rig, in a real chromium on a real
authenticated mosquitto (no rig service: the test publishes its statuses), the page's feed passing a relay
that can hold it: while the page has not heard yet whether the dashboard's broker link is up (the badge
says `connecting`: the page just loaded, a new sign-in) the three are disabled, their tooltip saying
why, and the badge says `connecting`, not the previous session's link; while the view is stale
(nothing from the dashboard server for 7/3 ticks) all three are enabled: the state shown is not known
to be the present, the service decides. Stop and ABORT are enabled throughout."""

from __future__ import annotations

import pytest
from support.dash_helpers import RIG, Dashboard, HeldFeeds, Page, publish_as_service
from support.mqtt_helpers import ACCOUNTS

RUN = "sim-rig@2026-12-07T05:00:00.000Z"
BUTTONS = ("btn-start", "btn-pause", "btn-resume", "btn-stop", "btn-abort")
CONNECTING = "not now: the dashboard's link to the broker is not up yet (connecting): try again when it is online"
TICK = 1.0  # s: --tick of the module's dashboard: the view stale after 7/3 s of silence


@pytest.fixture(scope="module")
def dashboard(broker, tmp_path_factory):
    dash = Dashboard(broker.url, RIG, tmp_path_factory.mktemp("dashboard"), "--tick", str(TICK))
    yield dash
    assert dash.stop() == 0, dash.text()[-3000:]


@pytest.fixture
def held(dashboard):
    relay = HeldFeeds(dashboard.port)
    yield relay
    relay.release()
    relay.close()


def status(broker, state: str, message: str, run_id: str | None = RUN) -> None:
    body = {"state": state, "run_id": run_id, "since": "2026-12-07T05:00:01.000Z", "message": message}
    publish_as_service(broker, "status", body, retain=True)


def buttons(page: Page) -> dict[str, str]:
    """{button: "on", or the tooltip of a disabled one}."""
    return page.d.execute_script(
        "const out = {}; arguments[0].forEach(id => { const b = document.getElementById(id);"
        " out[id] = b.disabled ? b.title : 'on'; }); return out;",
        list(BUTTONS),
    )


def connecting(page: Page) -> None:
    """The page signed in, its feed held: the badge says connecting and no ordinary command is offered."""
    page.sign_in("operator", ACCOUNTS["operator"])
    page.signed_in()
    assert page.text("link") == "connecting"
    want = {**dict.fromkeys(BUTTONS[:3], CONNECTING), "btn-stop": "on", "btn-abort": "on"}
    page.wait(lambda: buttons(page) == want, 5, f"{want} while connecting")


def test_start_pause_resume_wait_for_the_link_abort_never(broker, dashboard, held, browsers):
    status(broker, "idle", "service ready", None)
    page = Page(browsers(), held.url, dashboard)
    held.hold()
    connecting(page)
    held.release()  # the feed's snapshot: the link online, the rig idle
    page.wait_text("link", "online", 10)
    on = {"btn-start": "on", "btn-stop": "on", "btn-abort": "on"}
    page.wait(lambda: {k: v for k, v in buttons(page).items() if v == "on"} == on, 10, "start, stop, abort on")

    page.el("signout").click()  # the next person's page knows nothing of this session's link
    page.wait(lambda: page.el("signin").is_displayed(), 10, "the sign-in form")
    held.hold()
    connecting(page)
    held.release()
    page.wait_text("link", "online", 10)


def test_a_stale_view_leaves_the_decision_to_the_service(broker, dashboard, held, browsers):
    status(broker, "running", "measuring point 1 of 2")
    page = Page(browsers(), held.url, dashboard)
    page.sign_in("operator", ACCOUNTS["operator"])
    page.signed_in()
    page.wait_state("running", 10)
    under_way = "not now: a run is under way (running): stop or abort it before starting another"
    page.wait(lambda: buttons(page)["btn-start"] == under_way, 5, "start disabled while running")
    held.hold()  # the feed goes silent: the page cannot tell whether the run still runs
    page.wait(lambda: "stale" in (page.el("app").get_attribute("class") or ""), 4 * TICK + 3, "the view stale")
    assert buttons(page) == dict.fromkeys(BUTTONS, "on")
    held.release()
    page.wait(lambda: "stale" not in (page.el("app").get_attribute("class") or ""), 20, "the view live again")
    page.wait(lambda: buttons(page)["btn-start"] == under_way, 5, "start disabled again")
    status(broker, "idle", "run stopped: stopped by ada")


def test_a_silent_feed_is_stale_although_the_wall_clock_was_stepped_back(broker, dashboard, held, browsers):
    """The page times its feed on its monotonic clock (performance.now()): the browser's wall clock stepped back an
    hour (Date.now(), an NTP step) as the feed goes silent still greys the view and says STALE after 7/3 ticks, and
    the page gives the feed up after 4 and connects again. Before, the feed's latest message looked an hour in the
    future: a dead feed went unnoticed for that hour, the view showing a run's state as the present."""
    status(broker, "running", "measuring point 1 of 2")
    page = Page(browsers(), held.url, dashboard)
    page.sign_in("operator", ACCOUNTS["operator"])
    page.signed_in()
    page.wait_state("running", 10)
    page.d.execute_script("const wall = Date.now; Date.now = () => wall() - 3600e3;")
    held.hold()  # the feed goes silent
    page.wait(lambda: "stale" in (page.el("app").get_attribute("class") or ""), 4 * TICK + 5, "the view stale")
    page.wait_text("offline-banner", lambda t: t.startswith("STALE: no data from the dashboard server for "), 5)
    held.release()
    page.wait(lambda: "stale" not in (page.el("app").get_attribute("class") or ""), 20, "the view live again")
    status(broker, "idle", "run stopped: stopped by ada")
