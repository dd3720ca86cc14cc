"""The page's times over midnight, in a real chromium on a real authenticated mosquitto: an item not of
the browser's today carries its date (the events, the Run card's latest warning, the command outcome's
time), also once the page's own day has changed under it; a kept outcome says its time once; a new
page's matrix field says the matrix of the rig's run. The tests publish what a rig service would."""

from __future__ import annotations

import re
from datetime import datetime, timedelta, timezone

import pytest
from support.dash_helpers import Page, dashboard_running, pass_midnight, publish_as_service
from support.mqtt_helpers import ACCOUNTS

CLOCK = re.compile(r"\d\d:\d\d:\d\d")


@pytest.fixture(scope="module")
def dashboard(broker, tmp_path_factory):
    """The dashboard alone on the broker: the tests publish what the rig service would."""
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


@pytest.fixture
def page(browsers, dashboard):
    """A viewer's page in a browser whose clock reads UTC (so that the test knows its dates)."""
    driver = browsers()
    driver.execute_cdp_cmd("Emulation.setTimezoneOverride", {"timezoneId": "UTC"})
    try:
        p = Page(driver, dashboard.url, dashboard)
        p.sign_in("viewer", ACCOUNTS["viewer"])
        p.signed_in()
        p.wait_text("link", "online", 15)
        yield p
    finally:
        driver.execute_cdp_cmd("Emulation.setTimezoneOverride", {"timezoneId": ""})


def iso(t: datetime) -> str:
    return t.strftime("%Y-%m-%dT%H:%M:%S.") + f"{t.microsecond // 1000:03d}Z"


def events(page: Page) -> list[str]:
    return page.text("events").splitlines()


def test_items_of_yesterday_carry_their_date(broker, page):
    now = datetime.now(timezone.utc)
    ended = now - timedelta(hours=30)  # before the browser's today whatever the hour
    closing = {
        "state": "idle",
        "run_id": "r-night",
        "since": iso(ended),
        "message": "run stopped: stop requested by ada",
        "matrix": "demo",
    }
    publish_as_service(broker, "status", closing, retain=True)
    note = {"run_id": "r-night", "severity": "warning", "message": "spin drifted", "at": iso(ended), "said": 1}
    publish_as_service(broker, "note", note, retain=True)
    day = ended.strftime("%Y-%m-%d %H:%M:%S")
    page.wait(lambda: any("r-night stopped" in e for e in events(page)), 10, "the run's end listed")
    page.wait(lambda: any("spin drifted" in e for e in events(page)), 10, "the run's warning listed")
    assert [e for e in events(page) if "r-night stopped" in e] == [
        day + " ⚠ run r-night stopped: stop requested by ada"
    ]
    assert [e for e in events(page) if "spin drifted" in e] == [day + " ⚠ warning: run r-night: spin drifted"]
    assert page.text("run-warnings").startswith("⚠ 1 warning in this run, the latest at " + day + ":")
    today = {**note, "message": "spin drifted again", "at": iso(now), "said": 2}  # today's: the clock alone
    publish_as_service(broker, "note", today, retain=True)
    page.wait(lambda: any("drifted again" in e for e in events(page)), 10, "today's warning listed")
    (line,) = [e for e in events(page) if "drifted again" in e]
    assert line == now.strftime("%H:%M:%S") + " ⚠ warning: run r-night: spin drifted again"


def test_a_page_left_open_over_midnight_dates_what_it_showed(broker, page):
    page.send("pause", "refused: not authorised", 10)  # the viewer's: the broker's refusal, now
    said = page.text("cmd-when")
    assert said.startswith("at "), said
    assert CLOCK.fullmatch(said.removeprefix("at ")), said  # today's: the clock alone
    (refused,) = [e for e in events(page) if "pause: refused" in e]
    # the page's clock passes its midnight (a night's shift, a laptop woken the next day): an hour into tomorrow
    pass_midnight(page)
    day = datetime.now(timezone.utc).strftime("%Y-%m-%d")
    page.wait_text("cmd-when", "at " + day + " " + said.removeprefix("at "), 5)
    page.wait(lambda: day + " " + refused in events(page), 5, "the refusal dated")


def test_a_kept_outcome_says_its_time_once(page):
    page.send("pause", "refused: not authorised", 10)
    page.d.refresh()  # the session's latest outcome comes again with the snapshot
    page.signed_in()
    shown = page.wait_text("cmd-result", lambda t: t != "", 10)
    assert shown.startswith("pause: refused: not authorised") and shown.endswith(" (before this page was loaded)")
    assert not CLOCK.search(shown), shown  # its time: once, on the line under it
    assert CLOCK.fullmatch(page.text("cmd-when").removeprefix("at ")), page.text("cmd-when")


def test_a_new_page_says_the_matrix_of_the_rigs_run(broker, page):
    running = {
        "state": "running",
        "run_id": "r-paper",
        "since": iso(datetime.now(timezone.utc)),
        "message": "run started",
    }
    publish_as_service(broker, "status", {**running, "matrix": "paper", "by": "ada"}, retain=True)
    page.wait_state("running", 10)
    assert page.el("matrix").get_attribute("value") == "paper"  # the run's matrix, not demo
    page.el("matrix").clear()
    page.el("matrix").send_keys("eccentricity")  # what the operator types stays
    publish_as_service(broker, "status", {**running, "matrix": "paper", "message": "point 2"}, retain=True)
    page.wait_text("message", "point 2", 10)
    assert page.el("matrix").get_attribute("value") == "eccentricity"
