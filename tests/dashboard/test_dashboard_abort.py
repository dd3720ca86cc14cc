"""The ABORT and STOP path of the page, in a real chromium on a real authenticated mosquitto (no
rig service: the tests publish its statuses): the outcome says only what is known ("not
authorised" from the broker itself, else "unknown"), an abort goes to the rig the page shows
(also when the session watches another by now), an ended session or a frozen dashboard never loses an abort silently, the confirmation
dialog never outlives the session, and latched alarms outlive sessions and rig switches."""

from __future__ import annotations

import json
import signal
import time

import pytest
from orbitrig.dashboard.commands import EMERGENCY
from support.dash_helpers import Dashboard, Page, RIG, dashboard_running, fresh_page
from support.mqtt_helpers import ACCOUNTS, Watcher

REPLY_TIMEOUT = 8.0  # s: --reply-timeout of the module's dashboard (the bounds below leave a busy host 7 s)


@pytest.fixture(scope="module")
def dashboard(broker, tmp_path_factory):
    """The dashboard alone on the broker: no rig service answers."""
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard"), REPLY_TIMEOUT) as dash:
        yield dash


@pytest.fixture
def page(driver, dashboard):
    """The module's browser on the dashboard, signed out, one tab."""
    return fresh_page(driver, dashboard)


@pytest.fixture
def aborts(broker):
    """Every stop and abort reaching the broker on any rig's abort topic."""
    w = Watcher(broker, "orbitrig/+/abort")
    yield w
    w.close()


def sign_in(page: Page, user: str) -> None:
    page.sign_in(user, ACCOUNTS[user])
    page.signed_in()
    page.wait_text("link", "online")


def publish_status(broker, state: str, message: str, *, rig: str = RIG, retain: bool = False) -> None:
    status = {"state": state, "run_id": "r-abort", "since": "2026-01-06T09:00:00.000Z", "message": message}
    done = broker.pub(f"orbitrig/{rig}/status", json.dumps(status), user="orbitrig-service", retain=retain)
    assert done.returncode == 0, done.stderr


def confirm_abort(page: Page) -> None:
    page.d.execute_script("document.getElementById('cmd-result').textContent = ''")
    page.el("btn-abort").click()
    page.wait(lambda: page.el("abort-confirm").is_displayed(), 10, "the abort confirmation")
    page.el("abort-confirm").click()


def outcome(page: Page, timeout: float = 20.0) -> str:
    return page.wait_text("cmd-result", lambda t: t != "" and not t.endswith("…"), timeout)


def end_session_unseen(page: Page) -> None:
    """The session ends while the page does not hear of it (its feed was away): a sign-out elsewhere."""
    page.d.execute_async_script(
        "const done = arguments[0]; st.ws.onmessage = null; st.ws.onclose = null;"
        "fetch('/api/logout', {method: 'POST', headers: {'Content-Type': 'application/json'}, body: '{}'})"
        ".then(() => done(), () => done())"
    )


def test_a_session_ending_under_the_open_abort_dialog_leaves_the_page_usable(page):
    sign_in(page, "operator")
    page.el("btn-abort").click()
    page.wait(lambda: page.el("abort-confirm").is_displayed(), 10, "the abort confirmation")
    page.d.execute_script(  # a sign-out in another tab of this browser: the feed says the session ended
        "fetch('/api/logout', {method: 'POST', headers: {'Content-Type': 'application/json'}, body: '{}'})"
    )
    page.wait_text("signin-error", "session ended: signed out", 10)
    assert page.d.execute_script("return document.querySelectorAll('dialog[open]').length") == 0
    sign_in(page, "operator")  # clicks and typing reach the form: no invisible modal in the way
    assert not page.el("abort-dialog").is_displayed()


def test_the_abort_confirmation_names_the_rig_and_what_it_stops(broker, page):
    """It asked "Abort the run?" whatever the rig did, and of no rig by name: it names the rig the abort goes
    to and the run it stops in its state now, follows the state while open, and says when no run is under way
    or the rig service is offline (the drives may not hear it)."""
    sign_in(page, "operator")
    publish_status(broker, "running", "measuring point 1 of 1")
    page.wait_state("running", 10)
    page.el("btn-abort").click()
    page.wait(lambda: page.el("abort-confirm").is_displayed(), 10, "the abort confirmation")
    said = f"Abort run r-abort on rig {RIG}? It is running: both drives ramp to zero at once (emergency ramp)."
    assert page.text("abort-question") == said
    publish_status(broker, "paused", "paused at a safe point")  # the open confirmation follows
    page.wait_text("abort-question", said.replace("running", "paused"), 10)
    publish_status(broker, "offline", "connection to the rig service lost")
    page.wait_text(
        "abort-question", lambda t: t.startswith(f"Emergency stop on rig {RIG}? The rig service is offline"), 10
    )
    assert page.text("abort-question").endswith("if the drives turn, use the rig's emergency stop.")
    publish_status(broker, "idle", "run stopped")
    idle = f"Emergency stop on rig {RIG}? No run is under way there (idle): both drives get an emergency stop (OFF3) all the same."
    page.wait_text("abort-question", idle, 10)
    page.el("abort-cancel").click()
    assert not page.el("abort-dialog").is_displayed()


def test_a_viewers_abort_is_refused_by_the_broker_at_once(page, aborts):
    sign_in(page, "viewer")
    t0 = time.monotonic()
    confirm_abort(page)
    text = outcome(page)
    elapsed = time.monotonic() - t0
    assert text.startswith("abort: refused: not authorised — user 'viewer' may not command this rig"), text
    assert elapsed < REPLY_TIMEOUT - 1.0, elapsed  # the broker's answer (PUBACK 135), not a missing reply
    time.sleep(0.3)
    assert aborts.on("abort") == []  # the broker dropped it


def test_a_reload_shows_the_latest_command_outcome(page):
    sign_in(page, "viewer")
    confirm_abort(page)
    refused = outcome(page)
    assert refused.startswith("abort: refused: not authorised")
    page.d.refresh()  # the same session: its latest outcomes come again with the snapshot
    page.signed_in()
    shown = page.wait_text("cmd-result", lambda t: t != "", 10)
    assert shown == refused + " (before this page was loaded)", shown  # its time on the line under it
    assert refused in page.text("events")


def test_an_operators_abort_without_a_reply_has_an_unknown_outcome(broker, page, aborts):
    sign_in(page, "operator")
    publish_status(broker, "running", "point 1 of 1")
    page.wait_state("running", 10)
    confirm_abort(page)
    aborts.wait_for(lambda m: m.json().get("cmd") == "abort", 10, what="the abort at the broker")
    publish_status(broker, "stopping", "aborting: emergency ramp")  # the service began, then hung
    text = outcome(page)
    assert "not authorised" not in text, text
    assert text.startswith(f"abort: no reply from the rig service within {REPLY_TIMEOUT:g} s: the outcome is unknown")
    assert "since the click the status went to stopping" in text and EMERGENCY in text, text

    # the rig's service is offline (its last will): the broker keeps no abort for it, said at once
    publish_status(broker, "offline", "connection to the rig service lost")
    page.wait_state("offline", 10)
    t0 = time.monotonic()
    confirm_abort(page)
    text = outcome(page)
    assert text == (
        "abort: the rig service is offline: the broker does not keep an abort for it; use the rig's emergency stop"
    )
    assert time.monotonic() - t0 < REPLY_TIMEOUT - 1.0
    publish_status(broker, "idle", "ready")


def test_an_abort_goes_to_the_rig_the_page_shows_not_the_one_watched(broker, page, aborts):
    publish_status(broker, "idle", "rig-b idle", rig="rig-b", retain=True)
    try:
        sign_in(page, "operator")
        page.wait(lambda: "rig-b" in page.text("rig-select"), 10, "rig-b listed")
        tab_a = page.d.current_window_handle
        page.d.execute_script("st.ws.onmessage = null")  # this tab's feed lags behind
        page.d.switch_to.new_window("tab")  # tab B of the same browser: the same session
        tab_b = Page(page.d, page.url, page.dashboard)
        tab_b.signed_in()
        tab_b.wait(lambda: "rig-b" in tab_b.text("rig-select"), 10, "rig-b listed in tab B")
        tab_b.d.execute_script(
            "const s = document.getElementById('rig-select'); s.value = 'rig-b'; s.dispatchEvent(new Event('change'))"
        )
        tab_b.wait_text("rig", "orbitrig/rig-b", 10)
        page.d.switch_to.window(tab_a)
        assert page.text("rig") == f"orbitrig/{RIG}"
        confirm_abort(page)
        aborts.wait_for(lambda m: m.json().get("cmd") == "abort", 10, what="the abort at the broker")
        assert outcome(page, REPLY_TIMEOUT + 15) == (  # no service of the rig answers here
            f"abort to rig orbitrig/{RIG}: no reply from the rig service within {REPLY_TIMEOUT:g} s: the outcome is "
            f"unknown — check the rig's state; {EMERGENCY}"
        )
        assert [m.topic for m in aborts.on("abort")] == [f"orbitrig/{RIG}/abort"]  # not to rig-b
    finally:
        broker.pub("orbitrig/rig-b/status", "", user="orbitrig-service", retain=True)


def test_an_abort_or_stop_after_the_session_ended_says_it_was_not_sent(page):
    for button, word in (("btn-abort", "ABORT"), ("btn-stop", "STOP")):
        sign_in(page, "operator")
        end_session_unseen(page)
        if button == "btn-abort":
            confirm_abort(page)
        else:
            page.el(button).click()
        page.wait(lambda: page.el("signin").is_displayed(), 10, "the sign-in form")
        assert page.text("signin-error") == (
            f"session ended: {word} NOT SENT — sign in and send it again, or use the rig's emergency stop"
        )


def test_latched_alarms_outlive_a_rig_switch_and_a_new_sign_in(broker, driver, tmp_path):
    """With a dashboard of its own: the only session watching the rig is this page's."""
    publish_status(broker, "idle", "rig-b idle", rig="rig-b", retain=True)
    dash = Dashboard(broker.url, RIG, tmp_path, "--reply-timeout", "1")
    try:
        driver.delete_all_cookies()
        page = Page(driver, dash.url, dash)
        sign_in(page, "operator")
        publish_status(broker, "paused", "suspended by interlock: lubricant supply pump is off")
        page.wait_text("alarm-count", "1 unacknowledged", 10)
        page.wait(lambda: "rig-b" in page.text("rig-select"), 10, "rig-b listed")
        for rig, count in (("rig-b", "none unacknowledged"), (RIG, "1 unacknowledged")):
            page.d.execute_script(
                "const s = document.getElementById('rig-select'); s.value = arguments[0];"
                "s.dispatchEvent(new Event('change'))",
                rig,
            )
            page.wait_text("rig", f"orbitrig/{rig}", 10)
            page.wait_text("alarm-count", count, 10)
        page.el("signout").click()  # the only session ends: the rig's alarm stays latched
        sign_in(page, "viewer")
        page.wait_text("alarm-count", "1 unacknowledged", 10)
        assert "suspended by interlock" in page.text("alarms")
    finally:
        broker.pub("orbitrig/rig-b/status", "", user="orbitrig-service", retain=True)
        assert dash.stop() == 0, dash.text()[-2000:]


def test_a_frozen_or_gone_dashboard_leaves_the_outcome_unknown(broker, driver, tmp_path):
    dash = Dashboard(broker.url, RIG, tmp_path, "--reply-timeout", "0.5")
    try:
        driver.delete_all_cookies()
        page = Page(driver, dash.url, dash)
        sign_in(page, "operator")
        dash.proc.send_signal(signal.SIGSTOP)  # the dashboard server hangs
        try:
            page.el("btn-stop").click()
            text = outcome(page, 15)
        finally:
            dash.proc.send_signal(signal.SIGCONT)
        assert text == (
            "stop: no answer from the dashboard within 3 s: the outcome is unknown (the command may have been "
            f"sent) — check the rig's state; {EMERGENCY}"
        )
        dash.proc.kill()  # now it is gone (no goodbye to the page: it keeps trying to reconnect)
        dash.proc.wait(10)
        page.el("btn-abort").click()
        page.wait(lambda: page.el("abort-confirm").is_displayed(), 10, "the abort confirmation")
        page.el("abort-confirm").click()
        text = page.wait_text("cmd-result", lambda t: t.startswith("abort: dashboard server unreachable"), 10)
        assert text.endswith(
            f": the outcome is unknown (the command may have been sent) — check the rig's state; {EMERGENCY}"
        )
    finally:
        if dash.proc.poll() is None:
            dash.proc.kill()
            dash.proc.wait(10)
