"""`orbitrig dashboard` whose terminal stops reading (Ctrl-S: XOFF, the output held by the
terminal's line discipline) still sends an operator's ABORT: its log is written by a thread of its
own (orbitrig.cli.service_log). Before, the next record logged (another user's sign-in) held its
event loop: the abort was never published. Real parts: a pseudo-terminal and the keystrokes,
mosquitto, `orbitrig dashboard` (no rig service: the abort is watched on the broker)."""

from __future__ import annotations

import asyncio
import http.cookiejar
import json
import signal
import threading
import time
import urllib.error
import urllib.request

import pytest

from support.dash_helpers import RIG, Dashboard
from support.mqtt_helpers import ACCOUNTS, Watcher
from support.polling import until
from support.pseudo_terminal import CTRL_Q, CTRL_S, Terminal

pytestmark = pytest.mark.timeout(120)


def _signed_in(url: str, user: str) -> urllib.request.OpenerDirector:
    opener = urllib.request.build_opener(urllib.request.HTTPCookieProcessor(http.cookiejar.CookieJar()))
    assert _post(opener, url + "api/login", {"user": user, "password": ACCOUNTS[user]}, 15)[0] == 200
    return opener


def _post(opener: urllib.request.OpenerDirector, url: str, body: dict, timeout: float) -> tuple[int, dict]:
    req = urllib.request.Request(
        url, data=json.dumps(body).encode(), method="POST", headers={"Content-Type": "application/json"}
    )
    try:
        with opener.open(req, timeout=timeout) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as err:
        return err.code, json.loads(err.read())


def _abort_reaches_the_broker(operator: urllib.request.OpenerDirector, dash: Dashboard, aborts: Watcher) -> None:
    """The signed-in `operator` presses ABORT (its reply not awaited): the abort is on the broker
    within 5 s, sent by that operator."""
    threading.Thread(
        target=_post,
        args=(operator, dash.url + "api/cmd", {"cmd": "abort", "rig": f"orbitrig/{RIG}"}, 30),
        daemon=True,
    ).start()
    msg = aborts.wait_for(lambda m: m.json()["cmd"] == "abort", 5, what="the abort on the broker")
    assert msg.json()["by"] == "operator"


def test_an_abort_is_sent_while_the_terminal_does_not_read(broker, tmp_path):
    terminal = Terminal()
    aborts = Watcher(broker, f"orbitrig/{RIG}/abort")
    dash = Dashboard(broker.url, RIG, tmp_path, "--reply-timeout", "1", tty=terminal.tty)
    terminal.started()
    try:
        operator = _signed_in(dash.url, "operator")
        terminal.press(CTRL_S)
        # another user signs in meanwhile: its line meets the stopped output (before: the loop held there)
        threading.Thread(target=lambda: _signed_in(dash.url, "viewer"), daemon=True).start()
        time.sleep(2.0)  # its session connected to the broker, its line written
        _abort_reaches_the_broker(operator, dash, aborts)
        terminal.press(CTRL_Q)
        terminal.shows("'viewer' signed in", 10)  # logged all the same, once the terminal reads
    finally:
        terminal.press(CTRL_Q)
        assert dash.stop() == 0
        aborts.close()
        terminal.close()


def test_ctrl_z_does_not_suspend_the_dashboard(broker, tmp_path):
    """Ctrl-Z (SIGTSTP) at the dashboard's terminal is refused with a warning: an operator's sign-in
    and ABORT still go through (before, the dashboard was suspended and held them back until `fg`)."""
    aborts = Watcher(broker, f"orbitrig/{RIG}/abort")
    dash = Dashboard(broker.url, RIG, tmp_path, "--reply-timeout", "1")
    try:
        dash.proc.send_signal(signal.SIGTSTP)
        refused = "Ctrl-Z ignored: orbitrig dashboard does not suspend while it relays the operators' stop"
        asyncio.run(until(lambda: refused in dash.text(), 5, "the dashboard's warning of the refused Ctrl-Z"))
        _abort_reaches_the_broker(_signed_in(dash.url, "operator"), dash, aborts)
    finally:
        dash.proc.send_signal(signal.SIGCONT)  # `fg`, had it been suspended
        assert dash.stop() == 0
        aborts.close()
