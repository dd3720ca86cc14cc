"""The event list and the results table in a real chromium on a real authenticated mosquitto:
each fit warning of a result listed once (not again from the result's `warnings`, which repeats
every fit's), the closing status's grouped warnings listed, and nothing listed or drawn twice
when the page's websocket reconnects (the server's snapshot replaces what the page showed).
The test publishes what the rig service does (as orbitrig-service, docs/protocols/mqtt.md)."""

from __future__ import annotations

import html
import re
import time

import pytest
from support.dash_helpers import Page, dashboard_running, publish_as_service
from support.mqtt_helpers import ACCOUNTS

from orbitrig.analysis.typeset import message_html

PIEZO = "bad fit: chi2 = 104.2 for 57 degrees of freedom (p = 0.00014): the residuals exceed the stated u_*"
STRAIN = "condition number 3.1e6: Kxy poorly determined"
GROUPED = (
    "kc7 none ols, piezo: bad fit: chi2 above its 95 % quantile at 2 of 3 points (0000, 0002)"
    " - the residuals exceed the stated u_* uncertainties; see kc8"
)

#: the Run card's line for the three points' results (two fits each, a warning each)
FITS_COUNTED = "⚠ 6 fit warnings in this run: listed under Warnings and refusals"


@pytest.fixture(scope="module")
def dashboard(broker, tmp_path_factory):
    """The dashboard alone on the broker: the test publishes what the rig service would."""
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


def fit(lms: str, warnings: list[str]) -> dict:
    return {
        "lms": lms,
        "model": "kc7",
        "freq_dep": "none",
        "method": "ols",
        "coefficients": {"Kxx": 1.5e7, "Cxx": 2.0e4},
        "expanded_uncertainty": {"k": 2, "basis": "statistical", "values": {"Kxx": 2e5, "Cxx": 2e2}},
        "units": {"Kxx": "N/m", "Cxx": "N s/m"},
        "warnings": warnings,
    }


def result(run_id: str, index: int) -> dict:
    """A point's result as the service publishes it: the fits' warnings in their rows and, prefixed by
    their fit, all together in `warnings`."""
    return {
        "run_id": run_id,
        "index": index,
        "point": index,
        "label": "w1000rpm",
        "identification": [fit("piezo", [PIEZO]), fit("strain", [STRAIN])],
        "warnings": [f"piezo kc7 none ols: {PIEZO}", f"strain kc7 none ols: {STRAIN}"],
    }


def events(page: Page) -> list[str]:
    return page.d.execute_script("return [...document.querySelectorAll('#events li')].map(li => li.textContent)")


def result_rows(page: Page) -> int:
    return page.d.execute_script("return document.querySelectorAll('#results tr').length")


def shown(text: str) -> str:
    """`text` as the page shows it: the columns it names lifted by the report's rule (message_html:
    u_* -> u<sub>*</sub>, read as u*)."""
    return html.unescape(re.sub(r"<[^>]+>", "", message_html(text)))


def with_text(items: list[str], text: str) -> int:
    return sum(shown(text) in item for item in items)


def viewer_page(broker, browsers, dashboard, run_id: str) -> Page:
    """A viewer's page, the run `run_id` running and three of its points' results shown."""
    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in("viewer", ACCOUNTS["viewer"])
    page.signed_in()
    page.wait_text("link", "online")
    status = {"state": "running", "run_id": run_id, "since": "2026-01-07T08:00:00.000Z", "message": "started"}
    publish_as_service(broker, "status", status, retain=True)
    page.wait_state("running", 10)
    for index in range(3):
        publish_as_service(broker, "result", result(run_id, index))
    page.wait(lambda: result_rows(page) == 3 * 2 * 2, 10, "3 points x 2 fits x 2 coefficients")
    return page


def test_each_fit_warning_is_listed_once_and_the_closing_ones_too(broker, dashboard, browsers):
    page = viewer_page(broker, browsers, dashboard, "r-events")
    listed = events(page)
    for index in range(3):
        assert with_text(listed, f"point {index + 1} piezo kc7: {PIEZO}") == 1, listed
        assert with_text(listed, f"point {index + 1} strain kc7: {STRAIN}") == 1, listed
    assert with_text(listed, PIEZO) == 3 and with_text(listed, STRAIN) == 3, listed
    # the Run card counts them: not "none in this run" beside a list of the run's warnings
    page.wait_text("run-warnings", FITS_COUNTED, 10)

    # the run completes: its grouped warnings, in the closing status, are listed too
    closing = {"state": "idle", "run_id": "r-events", "since": "2026-01-07T08:01:00.000Z"}
    publish_as_service(broker, "status", {**closing, "message": f"run completed; warning: {GROUPED}"}, retain=True)
    page.wait_state("idle", 10)
    page.wait(lambda: with_text(events(page), f"warning: {GROUPED}") == 1, 10, "the closing status's warning")
    # a warning is told by its mark, not by its colour alone (the time, then the mark)
    kinds = page.d.execute_script(
        "return [...document.querySelectorAll('#events li')].map(li => [li.className, li.textContent])"
    )
    warned = [text for kind, text in kinds if kind == "warn"]
    assert len(warned) >= 7 and all(re.match(r"(\d{4}-\d\d-\d\d )?\d\d:\d\d:\d\d ⚠ ", t) for t in warned), warned
    assert not [text for kind, text in kinds if kind != "warn" and "⚠" in text], kinds
    assert page.text("run-warnings") == FITS_COUNTED  # the closing status groups the same: none more


def reconnect_feed(page) -> None:
    """The page's websocket dropped: until it is open again and the offline banner gone."""
    page.d.execute_script("window.oldFeed = st.ws; st.ws.close()")
    page.wait(
        lambda: page.d.execute_script("return !!st.ws && st.ws !== window.oldFeed && st.ws.readyState === 1"),
        15,
        "the feed to reconnect",
    )
    page.wait(lambda: not page.el("offline-banner").is_displayed(), 10, "the banner to go")


def test_nothing_is_listed_or_drawn_twice_when_the_feed_reconnects(broker, dashboard, browsers):
    page = viewer_page(broker, browsers, dashboard, "r-again")
    closing = {"state": "idle", "run_id": "r-again", "since": "2026-01-07T09:01:00.000Z"}
    publish_as_service(broker, "status", {**closing, "message": f"run completed; warning: {GROUPED}"}, retain=True)
    page.wait_state("idle", 10)
    assert "refused: not authorised" in page.command("btn-stop", "stop:")  # one refusal of the session
    before, rows = events(page), result_rows(page)

    # the page's websocket drops and reconnects: the snapshot replaces what the page showed
    reconnect_feed(page)
    page.wait(lambda: result_rows(page) >= rows, 10, "the results drawn again")
    time.sleep(1.0)  # the rest of the snapshot (alarms, outcomes) drawn
    assert result_rows(page) == rows
    assert events(page) == before
    assert page.text("run-warnings") == FITS_COUNTED  # the results handed on again: counted once
    assert page.text("cmd-result").startswith("stop: refused: not authorised")
    assert "before this page was loaded" not in page.text("cmd-result")  # the same page: its own outcome


def test_a_reconnect_lists_no_trimmed_warning_again_as_new(broker, dashboard, browsers):
    """The list keeps its latest 100 items; the server hands the rig's latest 100 warnings on to a
    feed starting again. A warning pushed out of the list by later events (here: statuses saying a
    link lost) was listed again at the top on a reconnect, an old warning over the present's."""
    page = viewer_page(broker, browsers, dashboard, "r-long")
    old = {"run_id": "r-long", "severity": "warning", "message": "settling took 40 s", "said": 1}
    publish_as_service(broker, "note", {**old, "at": "2026-01-07T10:00:00.000Z"}, retain=True)
    page.wait(lambda: with_text(events(page), "settling took 40 s") == 1, 10, "the warning")
    for k in range(100):  # later events push it out of the list
        since = f"2026-01-07T10:{1 + k // 60:02d}:{k % 60:02d}.000Z"
        status = {"state": "running", "run_id": "r-long", "since": since, "message": f"encoder link lost {k}"}
        publish_as_service(broker, "status", status, retain=True)
    page.wait(lambda: with_text(events(page), "encoder link lost 99") == 1, 20, "the latest status listed")
    before = events(page)
    assert len(before) == 100 and with_text(before, "settling took 40 s") == 0

    reconnect_feed(page)
    time.sleep(1.5)  # the snapshot (its warnings among it) drawn
    after = events(page)
    assert with_text(after, "settling took 40 s") == 0, after[:3]
    assert after == before


def test_a_page_loaded_again_lists_how_the_runs_ended_at_their_time(broker, dashboard, browsers):
    """How a run ended (its closing status: the outcome, why, the run's folder, its grouped warnings) was
    listed only by the pages open then: the next run's status replaced it on the Run card, and a page
    reloaded (or a second tab) no longer said it. The session keeps the runs' endings; a page lists them
    at the run's end, not at the time it was loaded."""
    page = viewer_page(broker, browsers, dashboard, "r-ended")
    since = "2026-01-07T11:01:00.000Z"
    closing = {"state": "idle", "run_id": "r-ended", "since": since, "folder": "/data/runs/r-ended"}
    said = f"run stopped: stopped by ada; warning: {GROUPED}"
    publish_as_service(broker, "status", {**closing, "message": said}, retain=True)
    page.wait_state("idle", 10)
    nxt = {"state": "running", "run_id": "r-next", "since": "2026-01-07T11:05:00.000Z", "message": "started"}
    publish_as_service(broker, "status", nxt, retain=True)
    page.wait_state("running", 10)

    page.d.refresh()  # the same session, a page loaded again
    page.signed_in()
    page.wait_state("running", 10)
    ended = "run r-ended stopped: stopped by ada (run folder /data/runs/r-ended)"
    page.wait(lambda: with_text(events(page), ended) == 1, 10, "the run's end listed again")
    # the run's end, not of today: with its date (the browser's local date and time)
    clock = page.d.execute_script(
        "const d = new Date(arguments[0]); return d.toLocaleDateString('sv-SE') + ' ' + d.toTimeString().slice(0, 8)",
        since,
    )
    listed = events(page)
    assert [e for e in listed if ended in e] == [f"{clock} ⚠ {ended}"], listed
    grouped = [e for e in listed if shown(f"warning: {GROUPED}") in e]
    assert grouped == [f"{clock} ⚠ run r-ended: {shown('warning: ' + GROUPED)}"], grouped  # at the end, not now
