"""A rig service that dies during a broker outage, in a real chromium on a real authenticated mosquitto (persistence
on, as config/mosquitto/mosquitto.conf has it) stopped and started again, with `orbitrig serve --sim` killed while
the broker is down: the broker published the service's last will as it stopped and keeps it. While the dashboard's
link is down and until 10 s after it is back (orbitrig.dashboard.link_lost.WILL_NEAR_OUTAGE_S: the service's time to
reconnect) the page says the service's state is unknown, its link lost; then what the broker says, `offline` with
the will's reason, on every page and in the dashboard server's refusals alike, a page loaded meanwhile too."""

from __future__ import annotations

import time

import pytest
from support.dash_helpers import Page, ServiceHolder, dashboard_running
from support.mqtt_helpers import ACCOUNTS, Broker, CutProxy

from orbitrig.dashboard.link_lost import LINK_LOST, WILL_NEAR_OUTAGE_S
from orbitrig.service.link import WILL_MESSAGE

#: s the page may take beyond the grace to say it (the server's timer, the feed, the page's poll; both cores busy)
SAID_WITHIN_S = 8.0


@pytest.fixture(scope="module")
def broker(tmp_path_factory):
    """The shipped client-id binding and persistence: the retained last will survives the restart."""
    with Broker(tmp_path_factory.mktemp("broker"), bind_ids=True, persist=True) as b:
        yield b


@pytest.fixture(scope="module")
def service(broker, tmp_path_factory):
    holder = ServiceHolder(broker, tmp_path_factory.mktemp("serve"))
    yield holder
    holder.proc.stop()


@pytest.fixture(scope="module")
def dashboard(broker, service, tmp_path_factory):
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


def operator_page(browsers, dashboard, service, url: str | None = None) -> Page:
    """A page signed in as the operator (at ``url``: the dashboard's by default), the service (started again if
    a test killed it) ready."""
    if service.proc.proc.poll() is not None:
        service.restart()
    page = Page(browsers(), url or dashboard.url, dashboard)
    page.sign_in("operator", ACCOUNTS["operator"])
    page.signed_in()
    page.wait_state("idle", 60)
    return page


def service_dies_in_an_outage(broker, service, page: Page) -> tuple[float, float]:
    """The broker stopped (it publishes the service's last will), the service killed while it is down, the broker
    started again; monotonic s as it was started and as the page said the dashboard's link was back: the link came
    back between the two (the page says it later, with both cores busy by a second or more)."""
    broker.stop()
    page.wait_text("link", "broker unreachable", 20)
    service.proc.kill()
    restarted = time.monotonic()
    broker.start()
    page.wait_text("link", "online", 30)
    return restarted, time.monotonic()


def start_refusal(page: Page) -> str:
    return page.send("start", "start:", matrix="demo")


def test_a_service_dead_after_a_broker_outage_is_said_offline_once_its_time_to_reconnect_is_over(
    broker, service, dashboard, browsers
):
    """Before, the page said `unknown — link lost` for good (until a new status or a reload)."""
    page = operator_page(browsers, dashboard, service)
    restarted, _ = service_dies_in_an_outage(broker, service, page)
    page.wait_text("state", LINK_LOST, WILL_NEAR_OUTAGE_S - 2)  # the will, while the service may still reconnect
    page.wait_state("offline", WILL_NEAR_OUTAGE_S + SAID_WITHIN_S)
    said = time.monotonic() - restarted
    assert said >= WILL_NEAR_OUTAGE_S, said  # not before the service's time to reconnect
    assert page.text("message") == WILL_MESSAGE  # the will's reason, as the broker keeps it
    assert page.text("offline-banner") == "offline: the rig service is not connected"
    assert "offline" in page.el("state").get_attribute("class")
    start = "not now: the rig service is offline: the dashboard sends it only STOP and ABORT"
    page.wait(lambda: page.el("btn-start").get_attribute("title") == start, 5, "Start's tooltip")
    assert start_refusal(page) == "start: not sent: the rig service is offline"


def test_a_page_loaded_after_the_outage_says_what_the_servers_refusals_say(broker, service, dashboard, browsers):
    """A page (re)loaded once the dashboard's link is back did not see the outage: it shows the dashboard server's
    reading, sent with the status, in the words of the server's refusals, and follows it when the grace is over.
    Before, the page said `offline` while the server refused a start with `unknown — link lost`."""
    page = operator_page(browsers, dashboard, service)
    service_dies_in_an_outage(broker, service, page)
    page.d.refresh()  # the same session: its outage, the page loaded after it
    page.signed_in()
    page.wait_text("state", LINK_LOST, WILL_NEAR_OUTAGE_S - 2)
    assert page.text("message").startswith("the rig service's state is unknown: its link to the broker was lost")
    assert start_refusal(page).startswith(f"start: not sent: the rig service's state is {LINK_LOST} (its link")
    page.wait_state("offline", WILL_NEAR_OUTAGE_S + SAID_WITHIN_S)
    assert page.text("message") == WILL_MESSAGE
    assert start_refusal(page) == "start: not sent: the rig service is offline"


def test_a_page_whose_own_feed_is_down_as_the_grace_ends_gets_the_servers_reading_when_it_is_back(
    broker, service, dashboard, browsers
):
    """The page's own websocket to the dashboard server (not the broker) is lost during the 10 s after the
    dashboard's broker link is back, and comes back after them: meanwhile the page says so (its banner, the view
    greyed) and shows the last reading it had, nothing newer; the snapshot its feed starts with when back says the
    will as the server reads it now, `offline` with the will's reason."""
    way = CutProxy(dashboard.port)  # the page's way to the dashboard server
    try:
        page = operator_page(browsers, dashboard, service, f"http://127.0.0.1:{way.port}/")
        _, back = service_dies_in_an_outage(broker, service, page)
        page.wait_text("state", LINK_LOST, WILL_NEAR_OUTAGE_S - 2)
        way.cut()
        page.wait_text("offline-banner", "offline: dashboard server unreachable — reconnecting", 10)
        assert "stale" in page.el("app").get_attribute("class")
        time.sleep(max(0.0, back + WILL_NEAR_OUTAGE_S + 1.0 - time.monotonic()))  # the grace over on the server
        assert page.text("state") == LINK_LOST  # the last reading the page had, greyed
        way.restore()
        page.wait_state("offline", 30)
        assert page.text("message") == WILL_MESSAGE
        assert page.text("offline-banner") == "offline: the rig service is not connected"
    finally:
        way.close()
