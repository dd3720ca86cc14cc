"""Real parts for the dashboard tests: the `orbitrig dashboard` process and a
headless Debian chromium driven by chromedriver (selenium)."""

from __future__ import annotations

import contextlib
import json

import os
import socket
import sys
import tempfile
import threading
import time
from pathlib import Path
from collections.abc import Callable, Iterator

from selenium import webdriver
from selenium.common.exceptions import StaleElementReferenceException
from selenium.webdriver.chrome.service import Service as DriverService
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

from .cli_helpers import orbitrig_cmd, started
from .mqtt_helpers import Broker, CutProxy, Service, interrupt, service_password_file
from .paths import ROOT as REPO
from .ports import free_port, wait_port


RIG = "dash-rig"  # rig id of the service the tests start
CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    "--window-size=1400,1500",
)


SPEEDUP = "5"  # the demo matrix runs for ~20 s: time to pause, resume and stop it


class ServiceHolder:
    """`orbitrig serve --sim` on the shipped matrices (config/matrices: demo, paper), restartable;
    behind ``launcher`` if given (mqtt_helpers.Service)."""

    def __init__(self, broker: Broker, work, launcher: tuple[str, ...] = (), matrices: Path | None = None):
        """``matrices``: a matrix folder of the test's own instead of the shipped one."""
        self.broker, self.work, self.launcher = broker, work, launcher
        pw = service_password_file(work)
        self.args = [
            "--sim",
            "--broker",
            broker.service_url,
            "--rig-id",
            RIG,
            "--username",
            "orbitrig-service",
            "--password-file",
            str(pw),
            "--matrices",
            str(matrices or REPO / "config" / "matrices"),
            "--out",
            str(work / "runs"),
            "--speedup",
            SPEEDUP,
        ]
        self.proc = Service(self.args, work, launcher=launcher)

    def restart(self) -> None:
        """The service ended (if it has not) and started again (mqtt_helpers.Service.restart)."""
        self.proc.restart()

    def text(self) -> str:
        return self.proc.text()


class Dashboard:
    """`orbitrig dashboard` as a subprocess on a free loopback port (its log in ``log``)."""

    def __init__(
        self, broker_url: str, rig_id: str, workdir: Path, *extra: str, tty: int | None = None, will_grace: float = 0
    ):
        """``tty``: a terminal its output goes to (else its log file); ``will_grace``: s of its
        link_lost.WILL_NEAR_OUTAGE_S instead of the shipped 10 s (0: the shipped)."""
        self.port = free_port()
        self.url = f"{'https' if '--https-cert' in extra else 'http'}://127.0.0.1:{self.port}/"
        self.log = Path(workdir) / f"dashboard-{self.port}.log"
        with open(self.log, "ab") as log:
            start = log.tell()  # what an earlier dashboard on this port wrote is not this one's
            args = ("dashboard", "--broker", broker_url, "--rig-id", rig_id, "--http", f"127.0.0.1:{self.port}", *extra)
            self.proc = started(
                _graced(will_grace, args) if will_grace else orbitrig_cmd(*args),
                stdin=None,
                stdout=log if tty is None else tty,
                stderr=log if tty is None else tty,
                env={"PYTHONUNBUFFERED": "1"},
            )
        try:
            wait_port(self.port, timeout=30)
            if tty is None:  # its own line: not another process that took the port meanwhile
                self._wait_said(f"dashboard on {self.url}", start, 30)
        except TimeoutError:
            self.stop()
            raise RuntimeError(f"dashboard did not start:\n{self.text()}") from None

    def _wait_said(self, line: str, start: int, timeout: float) -> None:
        """Until its log (from byte ``start``) says ``line``; TimeoutError if it ended or ``timeout`` s passed."""
        deadline = time.monotonic() + timeout
        while line not in self.log.read_bytes()[start:].decode(errors="replace"):
            if self.proc.poll() is not None or time.monotonic() > deadline:
                raise TimeoutError(line)
            time.sleep(0.02)

    def text(self) -> str:
        return self.log.read_text(errors="replace")

    def stop(self) -> int:
        return interrupt(self.proc)


def _graced(will_grace: float, args: tuple[str, ...]) -> list[str]:
    """`python -m orbitrig ARGS...` with link_lost.WILL_NEAR_OUTAGE_S set to ``will_grace`` s before the
    command line (and so the dashboard's session) is imported: an outage's window of a test's own length."""
    code = (
        f"import orbitrig.dashboard.link_lost as lost; lost.WILL_NEAR_OUTAGE_S = {float(will_grace)!r}; "
        "import runpy; runpy.run_module('orbitrig', run_name='__main__', alter_sys=True)"
    )
    return [sys.executable, "-c", code, *args]


@contextlib.contextmanager
def dashboard_running(broker_url: str, workdir: Path, reply_timeout: float | str = "1.5") -> Iterator[Dashboard]:
    """A Dashboard of rig RIG on `broker_url` (`--reply-timeout` s) for the block (a fixture's
    life); once it is left the dashboard must end cleanly on its interrupt (exit 0)."""
    dash = Dashboard(broker_url, RIG, workdir, "--reply-timeout", str(reply_timeout))
    yield dash
    assert dash.stop() == 0, dash.text()[-3000:]


#: bytes of the relay's receive buffer on a held feed (the kernel doubles it): with the dashboard's send buffer
#: (up to 4 MB) the held path takes about 4.5 MB, as a stalled browser's path would
HELD_BUFFER = 1 << 18


class HeldFeeds(CutProxy):
    """A relay between a browser and the dashboard's web port (``url``) that holds what the dashboard
    server sends on the pages' feeds (their websockets, ``GET /api/feed``) while ``hold()`` lasts, from a
    feed's handshake on or in the middle of one, as on a slow or stalled path: the page and its other
    requests (sign-in, commands) go through. ``release()`` lets the held bytes go on."""

    def __init__(self, target_port: int):
        self.flowing = threading.Event()
        self.flowing.set()
        super().__init__(target_port)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}/"

    def hold(self) -> None:
        self.flowing.clear()

    def release(self) -> None:
        self.flowing.set()

    def _relay(self, client: socket.socket, server: socket.socket) -> None:
        threading.Thread(target=self._sort, args=(client, server), daemon=True).start()

    def _sort(self, client: socket.socket, server: socket.socket) -> None:
        """Relay one connection, its answers held while ``flowing`` is clear once it carries a feed (its
        websocket's request seen: the first on the connection, or one after others on a connection kept alive)."""
        with contextlib.suppress(OSError):  # bounded here, not by the machine's TCP autotuning (up to 32 MB)
            server.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, HELD_BUFFER)
        feed = threading.Event()
        threading.Thread(target=self._requests, args=(client, server, feed), daemon=True).start()
        threading.Thread(target=self._held_pump, args=(server, client, feed), daemon=True).start()

    @staticmethod
    def _requests(src: socket.socket, dst: socket.socket, feed: threading.Event) -> None:
        """The browser's bytes to the dashboard; ``feed`` set once a feed's request went."""
        try:
            while data := src.recv(65536):
                if b"GET /api/feed" in data:
                    feed.set()
                dst.sendall(data)
        except OSError:
            pass
        for s in (src, dst):
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)

    def _held_pump(self, src: socket.socket, dst: socket.socket, feed: threading.Event) -> None:
        try:
            while data := src.recv(65536):
                if feed.is_set():
                    self.flowing.wait()
                dst.sendall(data)
        except OSError:
            pass
        for s in (src, dst):
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)


def chromium(profile_root: Path) -> webdriver.Chrome:
    """A fresh headless chromium with its own profile directory."""
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for flag in CHROMIUM_FLAGS:
        opts.add_argument(flag)
    opts.add_argument(f"--user-data-dir={tempfile.mkdtemp(prefix='chromium-', dir=profile_root)}")
    return webdriver.Chrome(service=DriverService(CHROMEDRIVER), options=opts)


def as_new(driver: webdriver.Chrome, size: dict[str, int]) -> None:
    """``driver`` as a freshly started chromium: one tab on about:blank (the pages it showed closed, their
    feeds with them), no cookie, nothing cached, its window at ``size`` (as ``get_window_size`` said at its
    start). The dashboard keeps nothing else in a browser (no web storage)."""
    for handle in driver.window_handles[1:]:
        driver.switch_to.window(handle)
        driver.close()
    driver.switch_to.window(driver.window_handles[0])
    driver.get("about:blank")
    driver.execute_cdp_cmd("Network.clearBrowserCookies", {})
    driver.execute_cdp_cmd("Network.clearBrowserCache", {})
    driver.set_window_size(size["width"], size["height"])


class Page:
    """The dashboard page in one browser, with the waits the tests need."""

    def __init__(self, driver: webdriver.Chrome, url: str, dashboard: Dashboard | None = None):
        self.d, self.url, self.dashboard = driver, url, dashboard
        driver.get(url)

    def el(self, element_id: str):
        return self.d.find_element(By.ID, element_id)

    def text(self, element_id: str) -> str:
        return self.el(element_id).text

    def wait(self, pred: Callable[[], bool], timeout: float = 30.0, what: str = "condition") -> None:
        try:
            # an element the page replaced between finding and reading it (its list redrawn) is
            # read again at the next poll, not a failure
            WebDriverWait(
                self.d, timeout, poll_frequency=0.1, ignored_exceptions=(StaleElementReferenceException,)
            ).until(lambda _: pred())
        except Exception as err:  # re-raised with the page's state
            state = self._describe()
            log = self.dashboard.text()[-2000:] if self.dashboard else ""
            raise AssertionError(f"timed out waiting for {what}: {state}\n--- dashboard log ---\n{log}") from err

    def _describe(self) -> str:
        try:
            return ", ".join(
                f"{i}={self.text(i)!r}"
                for i in ("state", "message", "link", "cmd-result", "signin-error", "offline-banner")
            )
        except Exception as err:  # noqa: BLE001
            return f"(page not readable: {err})"

    def wait_text(self, element_id: str, pred: Callable[[str], bool] | str, timeout: float = 30.0) -> str:
        check = (lambda t: t == pred) if isinstance(pred, str) else pred
        seen: list[str] = []

        def matches() -> bool:
            seen[:] = [self.text(element_id)]
            return check(seen[0])

        self.wait(matches, timeout, f"#{element_id} {pred!r}")
        return seen[0]

    def sign_in(self, user: str, password: str) -> None:
        self.wait(lambda: self.el("signin").is_displayed(), 15, "the sign-in form")
        self.el("user").clear()
        self.el("user").send_keys(user)
        self.el("password").clear()
        self.el("password").send_keys(password)
        self.el("signin-btn").click()

    def signed_in(self, timeout: float = 20.0) -> None:
        self.wait(lambda: self.el("app").is_displayed(), timeout, "the dashboard after sign-in")

    def state(self) -> str:
        """The run's state the badge names (without how the last run ended, "idle — last run ...")."""
        return self.text("state").split(" — ")[0]

    def wait_state(self, state: str | tuple[str, ...], timeout: float = 60.0) -> None:
        states = (state,) if isinstance(state, str) else state
        self.wait(lambda: self.state() in states, timeout, f"state {states}")

    def command(self, button: str, expect: str | Callable[[str], bool], timeout: float = 20.0) -> str:
        """Click a command button; wait for its outcome line (not "sending…")."""
        before = self.d.execute_script("return document.getElementById('cmd-result').textContent = ''")
        del before
        self.el(button).click()
        if button == "btn-abort":
            self.wait(lambda: self.el("abort-confirm").is_displayed(), 10, "the abort confirmation")
            self.el("abort-confirm").click()
        check = (lambda t: expect in t) if isinstance(expect, str) else expect
        return self.wait_text("cmd-result", lambda t: not t.endswith("…") and t != "" and check(t), timeout)

    def send(self, cmd: str, expect: str, timeout: float = 20.0, **extra: str) -> str:
        """Send ``cmd`` as its button does, also while the button is disabled (a click in the moment before the
        page heard the status that disables it: the dashboard server's own refusal); wait for its outcome line."""
        self.d.execute_script(
            "document.getElementById('cmd-result').textContent = ''; send(arguments[0], arguments[1])", cmd, extra
        )
        return self.wait_text("cmd-result", lambda t: not t.endswith("…") and expect in t, timeout)

    def rows(self, tbody_id: str, key: str) -> dict[str, str]:
        """Rows of a table body redrawn live, read in one go: {data-<key>: row text}."""
        return self.d.execute_script(
            "const out = {}; document.querySelectorAll('#' + arguments[0] + ' tr').forEach("
            "r => { out[r.dataset[arguments[1]]] = r.innerText; }); return out;",
            tbody_id,
            key,
        )

    def canvas_updates(self, element_id: str) -> int:
        return int(self.el(element_id).get_attribute("data-updates") or 0)

    def screenshot(self, path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        self.d.save_screenshot(str(path))


#: Set to a folder (e.g. docs/images) to keep the screenshots of single cards the tests take.
SCREENSHOTS_ENV = "ORBITRIG_DASHBOARD_SCREENSHOTS"


def card_shot(page: Page, element_id: str, name: str, tmp_path: Path) -> Path:
    """A screenshot of one card of the page: <$ORBITRIG_DASHBOARD_SCREENSHOTS or tmp_path>/dashboard-<name>.png."""
    folder = Path(os.environ.get(SCREENSHOTS_ENV) or tmp_path)
    path = (folder if folder.is_absolute() else REPO / folder) / f"dashboard-{name}.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    page.d.execute_script("arguments[0].scrollIntoView({block: 'center'})", page.el(element_id))
    page.el(element_id).screenshot(str(path))
    assert path.stat().st_size > 5_000
    return path


def fresh_page(driver: webdriver.Chrome, dashboard: Dashboard) -> Page:
    """``driver`` on ``dashboard`` in one tab (the others closed), signed out."""
    for handle in driver.window_handles[1:]:
        driver.switch_to.window(handle)
        driver.close()
    driver.switch_to.window(driver.window_handles[0])
    driver.get(dashboard.url)
    driver.delete_all_cookies()
    return Page(driver, dashboard.url, dashboard)


def idle_page(browsers: Callable[[], webdriver.Chrome], dashboard: Dashboard, user: str = "operator") -> Page:
    """A fresh browser's page signed in as `user` (password of mqtt_helpers.ACCOUNTS), the rig idle."""
    from .mqtt_helpers import ACCOUNTS

    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in(user, ACCOUNTS[user])
    page.signed_in()
    page.wait_state("idle")
    return page


def publish_as_service(broker, leaf: str, body: dict, *, retain: bool = False, qos: int = 1) -> None:
    """What the rig service would publish on ``orbitrig/<RIG>/<leaf>``, as its broker account."""
    done = broker.pub(f"orbitrig/{RIG}/{leaf}", json.dumps(body), user="orbitrig-service", retain=retain, qos=qos)
    assert done.returncode == 0, done.stderr


def pass_midnight(page: Page) -> None:
    """The page's clock (its Date) moved on to 01:00 tomorrow in the browser's zone, as a page left open overnight
    or a machine woken the next day finds it; the page's own timers go on, and its feed's latest message is as
    recent as it was (the page times its feed on its monotonic clock, which the jump does not move: it does not take
    the jump for a dead feed and reload its snapshot, which would draw everything afresh)."""
    page.d.execute_script(
        "const Real = Date, ahead = arguments[0];"
        "const d = new Real(); ahead.ms = new Real(d.getFullYear(), d.getMonth(), d.getDate() + 1, 1) - d;"
        "window.Date = class extends Real { constructor(...a) { if (a.length) super(...a); else super(Real.now() + ahead.ms); }"
        " static now() { return Real.now() + ahead.ms; } };",
        {},
    )
