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
    gets a service restarted (its drives stopped), not the failure's leftovers."""
    yield
    if request.node.stash.get(_FAILED, False) and "service" in request.fixturenames:
        holder = request.getfixturevalue("service")
        holder.proc.stop()
        holder.restart()


@pytest.fixture(scope="module")
def dashboard(broker, service, tmp_path_factory):
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


@pytest.fixture(scope="module")
def driver(tmp_path_factory):
    """One headless chromium for the whole module."""
    d = chromium(tmp_path_factory.mktemp("chromium"))
    yield d
    d.quit()


@pytest.fixture(scope="session")
def _chromiums(tmp_path_factory):
    """The headless chromiums of the session's tests (of a test process: each xdist worker has its own),
    each started when a test first needs one more than there are: [(driver, its window size at start)]."""
    root, made = tmp_path_factory.mktemp("chromiums"), []
    yield root, made
    for d, _ in made:
        d.quit()


@pytest.fixture
def browsers(_chromiums):
    """Factory of headless chromiums, each one a browser of its own in the test and as a new one: an
    earlier test's, its tabs closed, its cookies and cache cleared (as_new), else a fresh one (a start
    costs about a second of a core)."""
    root, made = _chromiums
    given: list = []

    def make():
        if len(given) == len(made):
            d = chromium(root)
            made.append((d, d.get_window_size()))
        given.append(made[len(given)])
        return given[-1][0]

    yield make
    for entry in given:
        try:
            as_new(*entry)
        except Exception:  # noqa: BLE001  (a browser the test left unusable: not handed out again)
            made.remove(entry)
            entry[0].quit()
