"""Commands that must not be carried out late, and a page that must not look live when it is not, in a
real chromium on a real authenticated mosquitto (no rig service: the tests publish its statuses and
replies): no ordinary command goes while the service is offline, a command the service did not answer
in time expires at the broker, a stop's or abort's late reply is shown, an abort without a broker link
says it was not sent, a page whose feed went silent says it is stale and connects again, and one whose
dashboard server died is greyed at once."""

from __future__ import annotations

import contextlib
import json
import signal
import socket
import subprocess
import threading
import time

import pytest
from support.dash_helpers import Dashboard, Page, RIG, dashboard_running
from support.mqtt_helpers import ACCOUNTS, Broker, CutProxy, Watcher

REPLY_TIMEOUT = 1.5  # s: --reply-timeout of the module's dashboard (its commands expire after 2 s)
EXPIRY = 2


class Blackhole(CutProxy):
    """A relay whose bytes vanish while ``dead`` (the connections stay up: no FIN, no RST), as on a
    Wi-Fi or VPN path that died."""

    dead = False

    def _relay(self, client, upstream) -> None:
        for a, b in ((client, upstream), (upstream, client)):
            threading.Thread(target=self._vanish, args=(a, b), daemon=True).start()

    def _vanish(self, src: socket.socket, dst: socket.socket) -> None:
        try:
            while data := src.recv(65536):
                if not self.dead:
                    dst.sendall(data)
        except OSError:
            pass
        for s in (src, dst):  # a connection one end closed is reset at the other, as on a path back up
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)


@pytest.fixture(scope="module")
def dashboard(relay, tmp_path_factory):
    with dashboard_running(relay.url, tmp_path_factory.mktemp("dashboard"), REPLY_TIMEOUT) as dash:
        yield dash


def status(broker, state: str, message: str = "") -> None:
    body = {"state": state, "run_id": "r-safe", "since": "2026-01-06T09:00:00.000Z", "message": message}
    done = broker.pub(f"orbitrig/{RIG}/status", json.dumps(body), user="orbitrig-service", retain=True)
    assert done.returncode == 0, done.stderr


def signed_in(driver, url: str, dashboard: Dashboard, state: str) -> Page:
    driver.get(url)
    driver.delete_all_cookies()
    page = Page(driver, url, dashboard)
    page.sign_in("operator", ACCOUNTS["operator"])
    page.signed_in()
    page.wait_text("link", "online")
    page.wait_state(state, 15)
    return page


def service_session(broker, *extra: str) -> subprocess.CompletedProcess:
    """mosquitto_sub as the rig service (client id bound to its name) on <prefix>/cmd, QoS 1, MQTT 5."""
    args = ["mosquitto_sub", *broker.client_args("orbitrig-service", broker.service_port), "-V", "5", "-c", "-q", "1"]
    args += ["-i", "mosq-service"]  # the prefix the broker asks; it then takes the user name
    return subprocess.run([*args, "-t", f"orbitrig/{RIG}/cmd", *extra], capture_output=True, text=True, timeout=20)


def test_no_command_but_stop_and_abort_goes_while_the_service_is_offline(broker, dashboard, driver):
    status(broker, "offline", "rig service connection lost")
    page = signed_in(driver, dashboard.url, dashboard, "offline")
    sent = Watcher(broker, (f"orbitrig/{RIG}/cmd", f"orbitrig/{RIG}/abort"))
    try:
        assert not page.el("btn-start").is_enabled()  # its click could only be refused
        assert page.send("start", "start:", matrix="demo") == "start: not sent: the rig service is offline"
        time.sleep(0.5)
        assert sent.messages == []  # the broker would have kept it for the service: carried out when back
        out = page.command("btn-abort", "abort:")
        assert "the rig service is offline" in out and "emergency stop" in out
        sent.wait_for(lambda m: json.loads(m.payload)["cmd"] == "abort", 10)  # an abort always goes
    finally:
        sent.close()
        status(broker, "idle")


def test_a_command_without_a_reply_expires_at_the_broker(broker, dashboard, driver):
    status(broker, "idle")
    assert service_session(broker, "-x", "300", "-E").returncode == 0  # the service's session, then away
    page = signed_in(driver, dashboard.url, dashboard, "idle")
    t0 = time.monotonic()
    assert "no reply from the rig service within 1.5 s: the outcome is unknown" in page.command("btn-start", "start:")
    time.sleep(max(0.0, EXPIRY + 1.5 - (time.monotonic() - t0)))  # the broker counts whole seconds
    back = service_session(broker, "-x", "0", "-W", "2")  # the service back: what the broker kept for it
    assert back.stdout.strip() == "", back.stdout  # not the start nobody is waiting for any more


def test_a_late_reply_to_an_abort_is_shown(broker, dashboard, driver):
    status(broker, "idle")
    page = signed_in(driver, dashboard.url, dashboard, "idle")
    aborts = Watcher(broker, f"orbitrig/{RIG}/abort")
    try:
        out = page.command("btn-abort", "abort:")
        assert "the outcome is unknown" in out
        cid = json.loads(aborts.wait_for(lambda m: True, 10).payload)["id"]
        error = "emergency stop delivered to no drive (spin: timeout); use the rig's emergency stop"
        reply = json.dumps({"id": cid, "ok": False, "error": error})
        assert broker.pub(f"orbitrig/{RIG}/reply", reply, user="orbitrig-service").returncode == 0
        late = page.wait_text("cmd-result", lambda t: "late reply" in t, 10)
        assert late.startswith("abort: late reply, ") and late.endswith("s after the click: " + error), late
        assert any(error in e for e in page.text("events").splitlines())
    finally:
        aborts.close()


def test_an_abort_without_the_broker_link_says_it_was_not_sent(broker, dashboard, relay, driver):
    status(broker, "idle")
    page = signed_in(driver, dashboard.url, dashboard, "idle")
    relay.cut()
    try:
        page.wait_text("link", "broker unreachable", 30)
        out = page.command("btn-abort", "abort:")
        assert out == (
            "abort: ABORT NOT SENT: the dashboard has no connection to the broker; use the rig's emergency stop"
        ), out
    finally:
        relay.restore()
    page.wait_text("link", "online", 30)


#: --tick of the silent feed's dashboard (s; default 3): the page calls its view stale after 7/3 ticks (3.5 s)
#: and gives the feed up after 4 (6 s); the test's times are the default's halved, each margin kept relative
TICK = 1.5
SCALE = TICK / 3.0


@pytest.fixture
def ticking(broker, tmp_path):
    """A dashboard of the test's own, on the module's broker, ticking every TICK s."""
    dash = Dashboard(broker.url, RIG, tmp_path, "--reply-timeout", str(REPLY_TIMEOUT), "--tick", str(TICK))
    try:
        yield dash
    finally:
        assert dash.stop() == 0, dash.text()[-3000:]


def test_a_silent_feed_is_shown_stale_and_connected_again(broker, ticking, driver):
    dashboard = ticking
    status(broker, "idle")
    hole = Blackhole(dashboard.port)
    try:
        page = signed_in(driver, f"http://127.0.0.1:{hole.port}/", dashboard, "idle")
        time.sleep(9 * SCALE)  # nothing happens on the rig: the server's ticks keep the page live past its stale limit
        assert not page.el("offline-banner").is_displayed(), page.text("offline-banner")
        hole.dead = True
        text = page.wait_text(
            "offline-banner", lambda t: t.startswith("STALE: no data from the dashboard server"), 12 * SCALE
        )
        assert "app stale" in "app " + page.el("app").get_attribute("class"), text
        page.wait_text("offline-banner", lambda t: "reconnecting" in t, 15 * SCALE)  # the dead feed given up
        hole.dead = False
        page.wait(lambda: not page.el("offline-banner").is_displayed(), 30, "the feed back")
        assert "stale" not in (page.el("app").get_attribute("class") or "")
        assert page.state() == "idle"
    finally:
        hole.close()


def test_a_dashboard_server_gone_greys_the_view_at_once(broker, driver, tmp_path):
    """The feed's websocket closed (the dashboard server died): nothing shown is the present from then on,
    the broker link's "online" included (the server's, not known any more); greyed at once, not after the
    7 s of silence that tell a feed dead without a close (at least 4 s after the server's last tick)."""
    status(broker, "idle")
    dash = Dashboard(broker.url, RIG, tmp_path, "--reply-timeout", str(REPLY_TIMEOUT))
    try:
        page = signed_in(driver, dash.url, dash, "idle")
        assert "stale" not in (page.el("app").get_attribute("class") or "")
        dash.proc.send_signal(signal.SIGKILL)
        gone = time.monotonic()
        page.wait(lambda: "stale" in (page.el("app").get_attribute("class") or ""), 3, "the view greyed")
        assert time.monotonic() - gone < 3.5
        assert page.text("offline-banner") == "offline: dashboard server unreachable — reconnecting"
        assert page.text("link") == "online"  # as last said, greyed with the view
    finally:
        dash.proc.kill()
        dash.proc.wait()


def test_the_results_table_trims_whole_points_and_says_which(broker, dashboard, driver):
    status(broker, "idle")
    page = signed_in(driver, dashboard.url, dashboard, "idle")
    for start in range(0, 700, 100):  # 100 results a script: each well inside WebDriver's script timeout on a busy host
        page.d.execute_script(
            "for (let i = arguments[0]; i < arguments[0] + 100; i++) resultTable.showResult({run_id: 'r-trim', index: i,"
            " identification: [{lms: 'A', model: 'K', coefficients: {kxx: i, kxy: 1, kyy: 2},"
            " expanded_uncertainty: {values: {}}, units: {}}]});",
            start,
        )
    rows = page.d.execute_script(
        "return [...document.querySelectorAll('#results tr')].map(r => [r.className, r.children[0].innerText]);"
    )
    assert len(rows) <= 2000  # MAX_RESULT_ROWS: 700 points of 3 rows each are 2100
    trim, first = rows[0], rows[1]
    assert trim == [
        "trim-row",
        "not shown (the table keeps the latest 2000 rows): run r-trim: points 1 to 34 (34 points)",
    ]
    assert first == ["fit-first", "35"], rows[:4]  # the oldest point shown whole, with its label
    assert sum(cls == "fit-first" for cls, _ in rows) == 700 - 34


def flood_replies(broker, n: int) -> None:
    """``n`` QoS 1 messages on <prefix>/reply, which every session reads: the broker's queue for a session
    that does not take them fills (max_queued_messages 10000) and what comes next is dropped for it."""
    import paho.mqtt.client as paho

    c = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id="mosq-flood")
    c.username_pw_set("orbitrig-service", ACCOUNTS["orbitrig-service"])
    c.max_queued_messages_set(0)
    c.connect("127.0.0.1", broker.port)
    c.loop_start()
    try:
        infos = [c.publish(f"orbitrig/{RIG}/reply", '{"id": "flood"}', 1) for _ in range(n)]
        infos[-1].wait_for_publish(30)
    finally:
        c.loop_stop()
        c.disconnect()


@pytest.fixture
def lone(tmp_path):
    """A broker and a dashboard of the test's own: the page's session is the one session the flood
    fills. (The module's dashboard keeps the sessions of the earlier tests' sign-ins, up to 4 of
    'operator', each with its own queue at the broker: the flood was 4 x 10000 messages for the
    one stopped process to take, and the status read again queued behind them, over 10 s late
    when both cores were busy.)"""
    with Broker(tmp_path / "broker", bind_ids=True) as b:
        dash = Dashboard(b.url, RIG, tmp_path, "--reply-timeout", str(REPLY_TIMEOUT))
        try:
            yield b, dash
        finally:
            code = dash.stop()
    assert code == 0, dash.text()[-3000:]


def test_an_unknown_outcome_reads_the_status_again(lone, driver):
    broker, dashboard = lone
    status(broker, "running")
    page = signed_in(driver, dashboard.url, dashboard, "running")
    dashboard.proc.send_signal(signal.SIGSTOP)  # the dashboard takes nothing for a moment
    try:
        flood_replies(broker, 10100)
        status(broker, "idle", "run aborted")  # dropped for the dashboard's session: its queue is full
    finally:
        dashboard.proc.send_signal(signal.SIGCONT)
    time.sleep(3)
    assert page.state() == "running"  # the run's end never reached this session
    out = page.command("btn-pause", "pause:")
    assert "the outcome is unknown" in out, out
    # the retained status read again after the unknown outcome: it comes behind what is left of the
    # flood (about 10 000 replies: over 10 s of the dashboard's with both cores busy)
    page.wait_state("idle", 60)
