"""The results table over a shift, in a real headless chromium against a real authenticated
mosquitto and `orbitrig serve --sim` running a three-point matrix: two runs' rows each under
a row naming their run; a page whose websocket reconnects draws them once, not twice; results
published while the dashboard's own broker link is down (cut by a relay between the dashboard
and the broker) come when it is back, the broker having kept them for the session; and a gap
the broker did not keep (it restarted meanwhile, without persistence) is marked in the table, its
times dated once the page's day has changed under it."""

from __future__ import annotations

import re
import time

import pytest
from support.dash_helpers import RIG, Page, dashboard_running, idle_page, pass_midnight
from support.mqtt_helpers import Service, Watcher, service_password_file

from orbitrig.store.layout import point_name

CLOCK = re.compile(r"\d\d:\d\d:\d\d")

#: three operating points (spin speeds: no manual setting between them), short blocks
MATRIX = """\
name = "threep"
revolutions = 10
settle_hold_s = 0.1

[operating]
spin_rpm = [1000.0, 1100.0, 1200.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.4]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.096]

[orbit]
ratios = [0.5, 0.8]
directions = ["forward", "backward"]

[[models]]
model = "kc7"
"""
POINTS, FITS = 3, 2  # a result per point; piezo and strain, kc7


@pytest.fixture(scope="module")
def service(broker, tmp_path_factory):
    """`orbitrig serve --sim` on the three-point matrix, manual settings confirmed by the simulator."""
    work = tmp_path_factory.mktemp("serve")
    (work / "matrices").mkdir()
    (work / "matrices" / "threep.toml").write_text(MATRIX)
    args = ["--sim", "--broker", broker.service_url, "--rig-id", RIG, "--username", "orbitrig-service"]
    args += ["--password-file", str(service_password_file(work)), "--matrices", str(work / "matrices")]
    args += ["--out", str(work / "runs"), "--speedup", "20", "--confirm", "auto", "--no-draw-figures"]
    svc = Service(args, work)
    yield svc
    svc.stop()


@pytest.fixture(scope="module")
def dashboard(relay, service, tmp_path_factory):
    with dashboard_running(relay.url, tmp_path_factory.mktemp("dashboard"), "3") as dash:
        yield dash


def rows(page: Page) -> list[dict]:
    """The results table's rows in order: class, run, first cell and its tooltip."""
    return page.d.execute_script(
        "return [...document.querySelectorAll('#results tr')].map(r => ({cls: r.className, run: r.dataset.run,"
        " first: r.children[0].innerText, title: r.children[0].title}))"
    )


def fits(page: Page) -> int:
    return sum(r["cls"] == "fit-first" for r in rows(page))


def heading(page: Page) -> str | None:
    """The run named in the results card's heading."""
    return page.d.execute_script("const e = document.getElementById('results-run'); return e && e.textContent")


def start(page: Page) -> None:
    page.el("matrix").clear()
    page.el("matrix").send_keys("threep")
    assert "start: accepted" in page.command("btn-start", "start:")


def run_once(page: Page) -> str:
    """Start the matrix, wait for its results and its end; its run id."""
    before, shown = page.text("run-id"), fits(page)
    start(page)
    page.wait(lambda: page.text("run-id") not in ("", before), 30, "the new run")
    run_id = page.text("run-id")
    page.wait(lambda: fits(page) == shown + POINTS * FITS, 120, f"the results of {run_id}")
    page.wait_state("idle", 60)
    assert page.text("message").startswith("run completed"), page.text("message")
    return run_id


def test_two_runs_rows_are_each_under_a_row_naming_their_run(dashboard, browsers):
    page = idle_page(browsers, dashboard)
    first = run_once(page)
    one = heading(page)
    second = run_once(page)
    shown = rows(page)
    runs = [r for r in shown if r["cls"] == "run-row"]
    assert [r["first"] for r in runs] == [f"run {first}", f"run {second}"]
    assert one == f"run {first}" and heading(page) == ""  # one run: named in the card's heading, two: in rows
    cut = shown.index(runs[1])
    assert shown[0] == runs[0] and {r["run"] for r in shown[1:cut]} == {first}
    assert {r["run"] for r in shown[cut + 1 :]} == {second}
    points = [r["first"].split()[0] for r in shown if r["cls"] == "fit-first"]
    assert points == ["1", "1", "2", "2", "3", "3"] * 2  # the same points in both runs: told apart by the run rows
    files = [r["title"] for r in shown if r["cls"] == "fit-first"]  # as the service names them (result: point_name)
    assert files == [f"file point {point_name(i)}" for i in (0, 0, 1, 1, 2, 2)] * 2


def test_a_page_whose_feed_reconnects_draws_the_results_once(dashboard, browsers):
    page = idle_page(browsers, dashboard)
    run_once(page)
    shown = rows(page)
    assert fits(page) == POINTS * FITS and len(shown) > POINTS * FITS  # a row per coefficient
    page.d.execute_script("window.oldFeed = st.ws; st.ws.close()")  # the page's websocket drops
    page.wait(
        lambda: page.d.execute_script("return !!st.ws && st.ws !== window.oldFeed && st.ws.readyState === 1"),
        15,
        "the feed to reconnect",
    )
    page.wait(lambda: len(rows(page)) >= len(shown), 10, "the results drawn again")
    time.sleep(1.0)  # the rest of the snapshot
    assert rows(page) == shown  # replaced, not appended


def test_results_published_while_the_broker_link_is_down_come_when_it_is_back(broker, relay, dashboard, browsers):
    watcher = Watcher(broker, f"orbitrig/{RIG}/result")
    try:
        page = idle_page(browsers, dashboard)
        start(page)
        watcher.wait_for(lambda m: True, 60, what="the run's first result")
        relay.cut()  # the dashboard's broker link drops; the broker and the service carry on
        page.wait_text("link", "broker unreachable", 15)
        watcher.wait_for(lambda m: True, 60, start=1, what="a result while the link is down")
        time.sleep(0.5)
        relay.restore()
        page.wait_text("link", "online", 30)
        page.wait_state("idle", 60)
        page.wait(lambda: fits(page) == POINTS * FITS, 20, "every result of the run, caught up")
        assert len(watcher.messages) == POINTS
        assert not [r for r in rows(page) if r["cls"] == "gap-row"]
        assert "results caught up" in page.text("events")
    finally:
        relay.restore()
        watcher.close()


def test_a_gap_the_broker_did_not_keep_is_marked_in_the_results(broker, relay, dashboard, browsers):
    page = idle_page(browsers, dashboard)
    relay.cut()
    page.wait_text("link", "broker unreachable", 15)
    broker.stop()  # a restart without persistence: the dashboard's session (and its queue) is gone
    broker.start()
    relay.restore()
    page.wait_text("link", "online", 30)
    page.wait(lambda: any(r["cls"] == "gap-row" for r in rows(page)), 10, "the gap in the results")
    gap = next(r for r in rows(page) if r["cls"] == "gap-row")["first"]
    assert gap.startswith("results published between ") and "may be missing" in gap, gap
    assert "results published meanwhile may be missing" in page.text("events")
    page.wait_state("idle", 60)  # the service is back on the broker too
    span = re.compile(r"results published between (\S+) and (\S+) may be missing")
    today = span.match(gap)
    assert today and all(CLOCK.fullmatch(t) for t in today.groups()), gap  # today's: the clock alone
    day = page.d.execute_script("return orbitPlots.dateTimeOf(Date.now()).slice(0, 10)")  # the page's today
    pass_midnight(page)  # the page left open overnight: the gap's times carry their date, as the events do
    dated = f"results published between {day} {today[1]} and {day} {today[2]} may be missing"
    page.wait(
        lambda: next(r for r in rows(page) if r["cls"] == "gap-row")["first"].startswith(dated), 5, "the gap dated"
    )
