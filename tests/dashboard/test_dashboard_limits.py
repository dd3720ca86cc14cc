"""The dashboard's limits against a hostile client (a real `orbitrig dashboard` on a real
mosquitto): sign-in throttled per user name and per client address (a growing delay, then a
lockout the right password does not end early), sessions capped per user (the oldest ends,
so one user cannot fill the global cap), and a read deadline for held connections."""

from __future__ import annotations

import contextlib
import json
import re
import socket
import time
import urllib.error
import urllib.request

import pytest

from support.dash_helpers import RIG, Dashboard, Page
from support.mqtt_helpers import ACCOUNTS

pytestmark = pytest.mark.timeout(150)


def _login(url: str, user: str, password: str, cookie: str | None = None) -> tuple[int, dict, str | None]:
    """POST /api/login with a fresh client: (status, body, the session cookie's value)."""
    headers = {"Content-Type": "application/json", **({"Cookie": cookie} if cookie else {})}
    req = urllib.request.Request(
        url + "api/login",
        method="POST",
        headers=headers,
        data=json.dumps({"user": user, "password": password}).encode(),
    )
    try:
        with urllib.request.urlopen(req, timeout=20) as r:
            token = re.search(r"orbitrig_session=([^;]+)", r.headers["Set-Cookie"]).group(1)
            return r.status, json.loads(r.read()), token
    except urllib.error.HTTPError as err:
        return err.code, json.loads(err.read()), None


def _alive(url: str, token: str) -> bool:
    req = urllib.request.Request(url + "api/session", headers={"Cookie": f"orbitrig_session={token}"})
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status == 200
    except urllib.error.HTTPError as err:
        assert err.code == 401
        return False


def _wait_asked(body: dict) -> float:
    m = re.search(r"try again in ([\d.]+) s", body["error"])
    assert m, body
    return float(m.group(1))


def test_signin_delay_grows_per_user_then_a_lockout_the_right_password_waits_out(broker, tmp_path):
    dash = Dashboard(broker.url, RIG, tmp_path, "--signin-delay", "0.5", "--lockout-after", "4", "--lockout", "3")
    try:
        asked, gaps = [], []
        for n in range(1, 5):
            sent = time.monotonic()
            assert _login(dash.url, "operator", "wrong")[0] == 401
            if n < 4:
                status, body, _ = _login(dash.url, "operator", "wrong")  # at once: not even tried
                gaps.append(time.monotonic() - sent)  # at most the time from the refusal to this answer
                assert status == 429
                asked.append(_wait_asked(body))
                time.sleep(asked[-1] + 0.05)
        # 0.5 s doubling, less the time from the refusal to the next answer (measured: a busy host's
        # is longer), less 0.05 s of the one decimal said
        delays = [0.5 * 2**k for k in range(3)]
        assert all(d - g - 0.05 <= a <= d for d, g, a in zip(delays, gaps, asked, strict=True)), (asked, gaps)
        t_locked = time.monotonic()
        status, body, _ = _login(dash.url, "operator", ACCOUNTS["operator"])
        assert status == 429 and "locked for" in body["error"] and "lockout 3 s" in body["error"], body
        assert _login(dash.url, "viewer", ACCOUNTS["viewer"])[0] == 200  # another user, same address: free
        time.sleep(1.0)
        assert _login(dash.url, "operator", ACCOUNTS["operator"])[0] == 429  # still locked
        time.sleep(max(0.0, t_locked + 3.2 - time.monotonic()))
        assert _login(dash.url, "operator", ACCOUNTS["operator"])[0] == 200
        assert ACCOUNTS["operator"] not in dash.text() and "not tried" in dash.text()
    finally:
        assert dash.stop() == 0, dash.text()[-2000:]


def test_signin_throttled_per_client_address_across_user_names(broker, tmp_path):
    """lock-after 1: an address has 1 free refusal, then 0.5 s, 1 s..., a lockout at 4."""
    dash = Dashboard(broker.url, RIG, tmp_path, "--signin-delay", "0.5", "--lockout-after", "1", "--lockout", "2")
    try:
        assert _login(dash.url, "mallory1", "x")[0] == 401
        sent = time.monotonic()
        assert _login(dash.url, "mallory2", "x")[0] == 401  # the address's free refusal
        status, body, _ = _login(dash.url, "mallory3", "x")
        gap = time.monotonic() - sent  # at most the time from the refusal to this answer (as in the test above)
        assert status == 429 and 0.5 - gap - 0.05 <= _wait_asked(body) <= 0.5, (body, gap)  # another user name
        time.sleep(_wait_asked(body) + 0.05)
        sent = time.monotonic()
        assert _login(dash.url, "mallory3", "x")[0] == 401
        status, body, _ = _login(dash.url, "mallory4", "x")
        gap = time.monotonic() - sent
        assert status == 429 and 1.0 - gap - 0.05 <= _wait_asked(body) <= 1.0, (body, gap)  # doubled
        time.sleep(_wait_asked(body) + 0.05)
        assert _login(dash.url, "mallory4", "x")[0] == 401  # the 4th refusal: the address is locked out
        t_locked = time.monotonic()
        status, body, _ = _login(dash.url, "operator", ACCOUNTS["operator"])
        assert status == 429 and "locked for" in body["error"] and "this address" in body["error"], body
        time.sleep(max(0.0, t_locked + 2.2 - time.monotonic()))
        assert _login(dash.url, "operator", ACCOUNTS["operator"])[0] == 200
    finally:
        assert dash.stop() == 0, dash.text()[-2000:]


def test_one_user_signing_in_59_times_keeps_its_newest_sessions_and_the_operator_gets_in(broker, tmp_path):
    dash = Dashboard(broker.url, RIG, tmp_path, "--sessions-per-user", "3")
    try:
        tokens = []
        for _ in range(59):
            status, body, token = _login(dash.url, "viewer", ACCOUNTS["viewer"])
            assert status == 200, body
            tokens.append(token)
        assert [_alive(dash.url, t) for t in tokens[-5:]] == [False, False, True, True, True]
        assert not _alive(dash.url, tokens[0])
        status, body, token = _login(dash.url, "operator", ACCOUNTS["operator"])
        assert status == 200 and body["user"] == "operator" and _alive(dash.url, token)
        assert dash.text().count("oldest session ended") == 56
    finally:
        assert dash.stop() == 0, dash.text()[-2000:]


def _closed_within(sock: socket.socket, limit: float, trickle: bytes = b"") -> float:
    """Seconds until the server closes `sock` (sending one byte of `trickle` every 0.3 s)."""
    t0 = time.monotonic()
    sock.settimeout(0.3)
    for i in range(int(limit / 0.3) + 1):
        try:
            if sock.recv(4096) == b"":
                return time.monotonic() - t0
        except socket.timeout:
            pass
        except ConnectionResetError:
            return time.monotonic() - t0
        if trickle:
            try:
                sock.sendall(trickle[i % len(trickle) : i % len(trickle) + 1])
            except (BrokenPipeError, ConnectionResetError):
                return time.monotonic() - t0
    raise AssertionError(f"connection still open after {limit} s")


def test_held_connections_are_cut_after_the_request_timeout_and_the_feed_is_not(broker, tmp_path):
    dash = Dashboard(broker.url, RIG, tmp_path, "--request-timeout", "1.5")
    try:
        cases = {
            "silent": b"",
            "slow head": b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n",
            "slow body": (
                b"POST /api/login HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
                b'Content-Length: 200\r\n\r\n{"user":'
            ),
        }
        for what, start in cases.items():
            with socket.create_connection(("127.0.0.1", dash.port), timeout=5) as s:
                s.sendall(start)
                trickle = {"silent": b"", "slow head": b"X-a: b\r\n", "slow body": b" "}[what]
                took = _closed_within(s, 6.0, trickle)
                assert 1.2 <= took <= 4.0, (what, took)
        assert "not read in full within 1.5 s" in dash.text()
        _, _, token = _login(dash.url, "viewer", ACCOUNTS["viewer"])
        with socket.create_connection(("127.0.0.1", dash.port), timeout=5) as s:  # the page's feed
            s.sendall(
                f"GET /api/feed HTTP/1.1\r\nHost: 127.0.0.1:{dash.port}\r\nUpgrade: websocket\r\n"
                "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                f"Sec-WebSocket-Version: 13\r\nCookie: orbitrig_session={token}\r\n\r\n".encode()
            )
            assert s.recv(4096).startswith(b"HTTP/1.1 101")
            time.sleep(3.0)  # twice the request timeout
            s.settimeout(1.0)
            s.sendall(b"\x88\x82abcd" + bytes(b ^ k for b, k in zip(b"\x03\xe8", b"ab")))  # a masked close frame
            got = b""
            with contextlib.suppress(socket.timeout):
                while chunk := s.recv(65536):
                    got += chunk
            assert b"\x88" in got  # the server answered the close (after the hello frames): the feed was open
    finally:
        assert dash.stop() == 0, dash.text()[-2000:]


def test_the_page_says_the_lockout_and_the_oldest_page_is_signed_out(broker, tmp_path, browsers):
    dash = Dashboard(broker.url, RIG, tmp_path, "--lockout-after", "1", "--lockout", "60", "--sessions-per-user", "1")
    drivers = [browsers() for _ in range(3)]
    try:
        page = Page(drivers[0], dash.url, dash)
        page.sign_in("operator", "wrong")
        page.wait_text("signin-error", "refused: wrong user name or password")
        page.sign_in("operator", ACCOUNTS["operator"])
        page.wait_text("signin-error", lambda t: "locked for" in t and "lockout 60 s" in t)
        assert not page.el("app").is_displayed() and page.d.get_cookies() == []
        first, second = Page(drivers[1], dash.url, dash), Page(drivers[2], dash.url, dash)
        first.sign_in("viewer", ACCOUNTS["viewer"])
        first.signed_in()
        second.sign_in("viewer", ACCOUNTS["viewer"])
        second.signed_in()
        first.wait(lambda: first.el("signin").is_displayed(), 15, "the oldest page signed out")
        assert "signed in elsewhere" in first.text("signin-error")
    finally:  # stopped with a page open: its session ends, so its feed does not hold the stop
        t0 = time.monotonic()
        assert dash.stop() == 0, dash.text()[-2000:]
        assert time.monotonic() - t0 < 10
