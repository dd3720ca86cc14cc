"""Fixtures of the dashboard tests: a real mosquitto (password file + the shipped
ACL), `orbitrig serve --sim`, `orbitrig dashboard` and headless chromium."""

from __future__ import annotations

import pytest
from support.dash_helpers import ServiceHolder, as_new, chromium, dashboard_running
from support.mqtt_helpers import CutProxy, broker_fixture

broker = broker_fixture(bind_ids=True)  # the shipped client-id binding


@pytest.fixture(scope="module")
def relay(broker):
    """The way to the broker of a module's own dashboard, which its tests cut (CutProxy)."""
    proxy = CutProxy(broker.port)
    yield proxy
    proxy.close()


@pytest.fixture(scope="module")
def service(broker, tmp_path_factory):
    holder = ServiceHolder(broker, tmp_path_factory.mktemp("serve"))
    yield holder
    holder.proc.stop()


_FAILED = pytest.StashKey[bool]()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item, call):
    report = yield
    if report.when == "call" and report.failed:
        item.stash[_FAILED] = True
    return report


@pytest.fixture(autouse=True)
def _service_fresh_after_a_failure(request):
    """A test that fails mid-run leaves the module's service paused or running: the next test
    gets a service restarted (its drives stopped), not the failure's leftovers. The module's
    ``service`` is a ServiceHolder or a plain mqtt_helpers.Service: both restart alike."""
    yield
    if request.node.stash.get(_FAILED, False) and "service" in request.fixturenames:
        request.getfixturevalue("service").restart()


@pytest.fixture(scope="module")
def dashboard(broker, service, tmp_path_factory):
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


class _Chromiums:
    """Headless chromiums handed out as new and taken back (as_new: their other tabs closed, on
    about:blank, cookies and cache cleared, their start's window size); one is started only when none
    is free (a start costs about a second of a core)."""

    def __init__(self, root):
        self.root, self.free, self.started = root, [], []

    def take(self) -> tuple:
        """(a free chromium, its window size at start)."""
        if not self.free:
            d = chromium(self.root)
            self.started.append(d)
            self.free.append((d, d.get_window_size()))
        return self.free.pop()

    def give_back(self, entry: tuple) -> None:
        try:
            as_new(*entry)
        except Exception:  # noqa: BLE001  (a browser the test left unusable: not handed out again)
            self.started.remove(entry[0])
            entry[0].quit()
        else:
            self.free.append(entry)


@pytest.fixture(scope="session")
def _chromiums(tmp_path_factory):
    """The chromiums of the session's tests (of a test process: each xdist worker has its own)."""
    pool = _Chromiums(tmp_path_factory.mktemp("chromiums"))
    yield pool
    for d in pool.started:
        d.quit()


@pytest.fixture(scope="module")
def driver(_chromiums):
    """One headless chromium for the whole module, as new at its start."""
    entry = _chromiums.take()
    yield entry[0]
    _chromiums.give_back(entry)


@pytest.fixture
def browsers(_chromiums):
    """Factory of headless chromiums, each one a browser of its own in the test and as a new one."""
    given: list = []

    def make():
        given.append(_chromiums.take())
        return given[-1][0]

    yield make
    for entry in given:
        _chromiums.give_back(entry)
