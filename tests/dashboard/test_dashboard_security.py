"""Signing in is the broker's business: a wrong password is refused, the session
cookie is HttpOnly and SameSite=Strict, the password is kept nowhere in the page
or the logs, and a session ends on sign-out or after the idle time."""

from __future__ import annotations

import http.cookiejar
import json
import time
import urllib.error
import urllib.request

from support.cli_helpers import orbitrig
from support.dash_helpers import RIG, Dashboard, Page
from support.mqtt_helpers import ACCOUNTS


def test_wrong_password_is_refused(dashboard, browsers):
    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in("operator", "not-the-password")
    page.wait_text("signin-error", lambda t: t != "")
    assert page.text("signin-error") == "refused: wrong user name or password"
    assert not page.el("app").is_displayed()
    assert page.d.get_cookies() == []
    assert page.el("password").get_attribute("value") == ""
    page.sign_in("nobody", "x")
    page.wait_text("signin-error", "refused: wrong user name or password")


def test_session_cookie_storage_and_sign_out(dashboard, browsers, service):
    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in("operator", ACCOUNTS["operator"])
    page.signed_in()
    page.wait(lambda: page.state() not in ("—", ""), 20, "the rig state")
    (cookie,) = page.d.get_cookies()
    assert cookie["httpOnly"] is True and cookie["sameSite"] == "Strict"
    secret = ACCOUNTS["operator"]
    storage = page.d.execute_script(
        "return JSON.stringify([document.cookie, Object.entries(localStorage), Object.entries(sessionStorage),"
        " location.href, document.documentElement.outerHTML,"
        " Array.from(document.querySelectorAll('input')).map(i => i.value)])"
    )
    assert secret not in storage and cookie["value"] not in storage
    assert secret not in dashboard.text() and secret not in service.text()
    page.el("signout").click()
    page.wait(lambda: page.el("signin").is_displayed(), 10, "the sign-in form after sign-out")
    page.wait_text("signin-error", "signed out")
    assert page.d.get_cookies() == []
    # the old session id is dead on the server too
    req = urllib.request.Request(
        dashboard.url + "api/session", headers={"Cookie": f"orbitrig_session={cookie['value']}"}
    )
    try:
        urllib.request.urlopen(req, timeout=5)
        raise AssertionError("the session survived its sign-out")
    except urllib.error.HTTPError as err:
        assert err.code == 401


def _client():
    jar = http.cookiejar.CookieJar()
    return urllib.request.build_opener(urllib.request.HTTPCookieProcessor(jar)), jar


def _post(opener, url, body):
    req = urllib.request.Request(
        url, data=json.dumps(body).encode(), method="POST", headers={"Content-Type": "application/json"}
    )
    try:
        with opener.open(req, timeout=15) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as err:
        return err.code, json.loads(err.read())


def test_no_anonymous_access_and_idle_timeout(broker, tmp_path):
    dash = Dashboard(broker.url, RIG, tmp_path, "--idle-timeout", "2")
    try:
        opener, _ = _client()
        for path in ("api/session", "api/feed"):
            try:
                opener.open(dash.url + path, timeout=5)
                raise AssertionError(f"{path} answered without a session")
            except urllib.error.HTTPError as err:
                assert err.code == 401
        assert _post(opener, dash.url + "api/cmd", {"cmd": "abort"})[0] == 401
        assert _post(opener, dash.url + "api/login", {"user": "operator", "password": ""})[0] == 400
        status, body = _post(opener, dash.url + "api/login", {"user": "operator", "password": ACCOUNTS["operator"]})
        assert status == 200 and body["user"] == "operator"
        with opener.open(dash.url + "api/session", timeout=5) as r:
            assert r.status == 200
        time.sleep(3.5)  # idle longer than --idle-timeout
        try:
            opener.open(dash.url + "api/session", timeout=5)
            raise AssertionError("the session outlived its idle time")
        except urllib.error.HTTPError as err:
            assert err.code == 401
        deadline = time.monotonic() + 10  # the session ends before its log line is written
        while "idle for more than 2 s" not in dash.text() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert "'operator' signed in" in dash.text() and "idle for more than 2 s" in dash.text()
        assert ACCOUNTS["operator"] not in dash.text()
    finally:
        assert dash.stop() == 0, dash.text()[-2000:]


def test_https_and_no_plain_http_off_loopback(broker, tmp_path):
    import ssl

    from support.mqtt_helpers import make_test_ca

    refused = orbitrig("dashboard", "--broker", broker.url, "--http", "0.0.0.0:8080", timeout=60, columns=None)
    assert refused.returncode == 2 and "plain HTTP only on loopback" in refused.stderr

    ca = make_test_ca(tmp_path)  # also server.crt / server.key for 127.0.0.1
    dash = Dashboard(
        broker.url,
        RIG,
        tmp_path,
        "--https-cert",
        str(tmp_path / "server.crt"),
        "--https-key",
        str(tmp_path / "server.key"),
    )
    try:
        assert dash.url.startswith("https://")
        ctx = ssl.create_default_context(cafile=str(ca))
        req = urllib.request.Request(
            dash.url + "api/login",
            method="POST",
            headers={"Content-Type": "application/json"},
            data=json.dumps({"user": "viewer", "password": ACCOUNTS["viewer"]}).encode(),
        )
        with urllib.request.urlopen(req, timeout=15, context=ctx) as r:
            cookie = r.headers["Set-Cookie"]
        assert "HttpOnly" in cookie and "SameSite=Strict" in cookie and "Secure" in cookie
    finally:
        assert dash.stop() == 0, dash.text()[-2000:]
