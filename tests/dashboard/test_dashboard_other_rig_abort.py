"""STOP and ABORT from a page showing a rig its session no longer watches (another tab of the same
browser chose another rig), in a real chromium on a real authenticated mosquitto (the shipped ACL)
with two real rig services (`orbitrig serve --sim`): they go to the rig the page shows, when the
dashboard knows it, their reply is matched although the session reads the other rig, and the
outcome names the rig; every other command keeps its refusal."""

from __future__ import annotations

import time

import pytest
from support.dash_helpers import Page, RIG, dashboard_running, fresh_page
from support.mqtt_helpers import ACCOUNTS, Watcher, broker_fixture, sim_service

OTHER = "rig-b"
REPLY_TIMEOUT = 8.0  # s: the dashboard's --reply-timeout (a busy host's replies come well within it)
SENT = "emergency stop (OFF3) sent to both drives over a link of the service's own (no run held them)"
WATCHES_B = f"this page shows rig orbitrig/{RIG} but the session now watches orbitrig/{OTHER}: reload the page"


#: a broker of the module's own, without the client-id binding: two rig services of one account
broker = broker_fixture()


@pytest.fixture(scope="module")
def services(broker, tmp_path_factory):
    """The rig services of RIG and OTHER, both idle."""
    made = {rig: sim_service(broker.url, rig, tmp_path_factory.mktemp(rig)) for rig in (RIG, OTHER)}
    yield made
    for svc in made.values():
        svc.stop()


@pytest.fixture(scope="module")
def dashboard(broker, services, tmp_path_factory):
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard"), REPLY_TIMEOUT) as dash:
        yield dash


@pytest.fixture
def commands(broker):
    """Every command reaching the broker, on any rig's command or abort topic."""
    w = Watcher(broker, ("orbitrig/+/abort", "orbitrig/+/cmd"))
    yield w
    w.close()


def page_of_a_with_session_on_b(driver, dashboard, user: str = "operator") -> Page:
    """Tab A showing RIG, whose feed lags behind; tab B of the same browser (the same session of
    ``user``) then chose OTHER. Returned on tab A."""
    page = fresh_page(driver, dashboard)
    page.sign_in(user, ACCOUNTS[user])
    page.signed_in()
    page.wait_text("link", "online", 20)
    page.wait_state("idle", 30)
    page.wait(lambda: f"{OTHER} (idle)" in page.text("rig-select"), 30, f"{OTHER} listed")
    tab_a = driver.current_window_handle
    driver.execute_script("st.ws.onmessage = null")  # this tab's feed lags behind: it still shows RIG
    driver.switch_to.new_window("tab")
    tab_b = Page(driver, dashboard.url, dashboard)
    tab_b.signed_in()
    tab_b.wait(lambda: OTHER in tab_b.text("rig-select"), 20, f"{OTHER} listed in tab B")
    driver.execute_script(
        "const s = document.getElementById('rig-select'); s.value = arguments[0]; s.dispatchEvent(new Event('change'))",
        OTHER,
    )
    tab_b.wait_text("rig", f"orbitrig/{OTHER}", 20)
    tab_b.wait_state("idle", 20)  # the session reads OTHER now
    driver.switch_to.window(tab_a)
    assert page.text("rig") == f"orbitrig/{RIG}"
    return page


def test_an_abort_from_a_page_of_another_rig_goes_to_the_rig_it_shows(dashboard, services, driver, commands):
    page = page_of_a_with_session_on_b(driver, dashboard)
    outcome = page.command("btn-abort", "abort", timeout=2 * REPLY_TIMEOUT + 10)
    # the service of RIG carried it out and its reply, on RIG's reply topic, was matched
    assert outcome == f"abort to rig orbitrig/{RIG}: accepted: {SENT}", outcome
    assert f"abort to rig orbitrig/{RIG}: {SENT}" in page.text("events")
    assert "abort: no run holds the drives: emergency stop (OFF3) to both" in services[RIG].text()
    assert [m.topic for m in commands.on("abort")] == [f"orbitrig/{RIG}/abort"]
    assert "no run holds the drives" not in services[OTHER].text()

    outcome = page.command("btn-stop", "stop", timeout=2 * REPLY_TIMEOUT + 10)
    assert outcome.startswith(f"stop to rig orbitrig/{RIG}: "), outcome
    assert "unknown" not in outcome and "not sent" not in outcome, outcome
    assert [m.topic for m in commands.on("abort")] == [f"orbitrig/{RIG}/abort"] * 2

    page.d.execute_script("document.getElementById('matrix').value = 'demo'")  # every other command: refused
    assert page.command("btn-start", "start", timeout=20) == f"start: not sent: {WATCHES_B}"
    assert not page.el("btn-pause").is_enabled()  # (no run under way: it cannot apply)
    time.sleep(0.5)
    assert commands.on("cmd") == []
    # the reply topic of RIG was subscribed and unsubscribed without awaiting the broker's answer:
    # the client takes those answers itself (aiomqtt logged each as an error with a traceback)
    log = dashboard.text()
    assert "Unexpected message ID" not in log and "Traceback" not in log, log[-3000:]


def test_an_abort_from_a_page_naming_a_rig_the_dashboard_does_not_know_is_refused(dashboard, driver, commands):
    page = page_of_a_with_session_on_b(driver, dashboard)
    for shown in ("orbitrig/rig-x", "elsewhere/rig"):  # a rig of no listing, a tree the dashboard does not watch
        page.d.execute_script("document.getElementById('rig').textContent = arguments[0]", shown)
        assert page.command("btn-abort", "abort", timeout=20) == (
            f"abort: not sent: this page shows rig {shown}, which this dashboard does not know: reload the page; "
            "if it is still running use the rig's emergency stop"
        )
    time.sleep(0.5)
    assert commands.messages == []


def test_the_broker_still_refuses_a_viewers_abort_to_the_rig_the_page_shows(dashboard, driver, commands):
    page = page_of_a_with_session_on_b(driver, dashboard, "viewer")
    assert page.command("btn-abort", "abort", timeout=20) == (
        f"abort to rig orbitrig/{RIG}: refused: not authorised — user 'viewer' may not command this rig "
        "(the broker refused it)"
    )
    time.sleep(0.5)
    assert commands.messages == []  # the broker dropped it
