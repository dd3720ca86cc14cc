"""The page in a real chromium on a real authenticated mosquitto shows the present run only:
the previous run's progress, ETA, live values and waveforms go when a new run starts or the
run ends (also in the first feed of a page loaded later), not when the service goes offline and comes
back to the same run; the live age is the payload's true
age after a reload; a refusal names its command once; a result's point is counted from 1.
The tests publish what the rig service would (as orbitrig-service)."""

from __future__ import annotations

import json
import time

import pytest
from support.dash_helpers import Page, dashboard_running, publish_as_service
from support.mqtt_helpers import ACCOUNTS

from orbitrig.service.protocol import result_payload


@pytest.fixture(scope="module")
def dashboard(broker, tmp_path_factory):
    """The dashboard alone on the broker (no rig service)."""
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


def status(broker, state: str, run_id: str, message: str = "") -> None:
    publish_as_service(
        broker, "status", {"state": state, "run_id": run_id, "since": "2026-01-05T13:00:00.000Z", "message": message}
    )


def progress(run_id: str) -> dict:
    return {
        "run_id": run_id,
        "point": 1,
        "points": 1,
        "frequency": 3,
        "frequencies": 10,
        "revolutions": 31,
        "eta_s": 23,
    }


def live(run_id: str) -> dict:
    wave = [1e-6 * (k % 9) for k in range(45)]
    orbit = {"reference_rpm": 600.0, "actual_rpm": 600.0, "torque_pct": 5.0, "state": "running"}
    return {
        "run_id": run_id,
        "point": 1,
        "frequency": 3,
        "direction": "forward",
        "revolutions": 31,
        "orbit_hz": 10.0,
        "spin_rpm": 1000.0,
        "drives": {"link_ok": True, "spin": {**orbit, "reference_rpm": 1000.0, "actual_rpm": 1000.0}, "orbit": orbit},
        "aux": {"p_supply": 2.0e6},
        "waveforms": {n: wave for n in ("x_a", "y_a", "x_b", "y_b")},
        "units": {},
    }


def signed_in(browsers, dashboard, user: str = "operator") -> Page:
    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in(user, ACCOUNTS[user])
    page.signed_in()
    page.wait_text("link", "online")
    return page


def run_view(page: Page) -> dict:
    ids = ("point", "block", "revolutions", "eta", "op-orbit-hz", "op-spin")
    out = {i: page.text(i) for i in ids}
    out["bar"] = page.d.execute_script("return document.getElementById('progress-bar').style.width")
    out["orbit-samples"] = page.el("plot-orbit").get_attribute("data-samples") or "0"
    return out


CLEARED = {i: "—" for i in ("point", "block", "revolutions", "eta", "op-orbit-hz", "op-spin")}


def test_a_new_run_and_a_run_end_clear_the_previous_runs_view(broker, dashboard, browsers):
    page = signed_in(browsers, dashboard)
    status(broker, "running", "r-old")
    page.wait_state("running")
    publish_as_service(broker, "progress", progress("r-old"), qos=0)
    publish_as_service(broker, "live", live("r-old"), qos=0)
    page.wait_text("eta", "0:23", 10)
    page.wait(lambda: page.el("plot-orbit").get_attribute("data-samples") == "45", 10, "the orbit plot")
    assert page.text("block") == "3 of 10" and page.text("op-orbit-hz") == "10.00 Hz"

    status(broker, "waiting", "r-new")  # another run: nothing of r-old stays
    page.wait_state("waiting")
    assert run_view(page) == {**CLEARED, "bar": "0px", "orbit-samples": "0"}, run_view(page)
    page.d.refresh()  # nor does the server replay r-old's progress and live to a page loaded now
    page.signed_in()
    page.wait_state("waiting")
    time.sleep(1.0)
    assert run_view(page) == {**CLEARED, "bar": "0px", "orbit-samples": "0"}, run_view(page)

    publish_as_service(broker, "progress", progress("r-new"), qos=0)
    publish_as_service(broker, "live", live("r-new"), qos=0)
    page.wait_text("eta", "0:23", 10)
    status(broker, "idle", "r-new", "run aborted")  # the run ends: no ETA, no live values
    page.wait_state("idle")
    assert run_view(page) == {**CLEARED, "bar": "0px", "orbit-samples": "0"}, run_view(page)

    # a page loaded now gets no progress of the ended run from the server either
    page.d.refresh()
    page.signed_in()
    page.wait_state("idle")
    time.sleep(1.0)
    assert run_view(page) == {**CLEARED, "bar": "0px", "orbit-samples": "0"}, run_view(page)

    status(broker, "idle", "r-new", "run completed")  # the bar full when completed ...
    page.wait(lambda: run_view(page)["bar"] == "100%", 10, "the full bar")
    status(broker, "waiting", "r-next")  # ... and empty again for the next run
    page.wait_state("waiting")
    assert run_view(page)["bar"] == "0px"


def test_the_live_age_after_a_reload_is_the_payloads_age(broker, dashboard, browsers):
    page = signed_in(browsers, dashboard)
    status(broker, "running", "r-age")
    page.wait_state("running")
    publish_as_service(broker, "live", live("r-age"), qos=0)
    page.wait(lambda: page.text("live-age").endswith("s ago"), 10, "the live age")
    time.sleep(4.0)
    page.d.refresh()
    page.signed_in()
    page.wait(lambda: " s ago" in page.text("live-age"), 10, "the live age after the reload")
    assert float(page.text("live-age").split()[0]) >= 3.5, page.text("live-age")
    status(broker, "idle", "r-age", "run stopped")


def test_a_run_view_outlives_the_service_going_offline_and_coming_back(broker, dashboard, browsers):
    """The broker's last will names the run of the service's connection (an earlier run here), not a new
    run: the id, matrix, point and ETA of a run that waits for the operator stay through the service's
    absence, on the page open then and on it loaded again (these statuses name no progress: the page keeps
    the one it had)."""
    page = signed_in(browsers, dashboard)
    waiting = {"state": "waiting", "run_id": "r-blip", "since": "2026-01-05T13:00:00.000Z", "message": "set by hand"}
    waiting.update(matrix="demo", by="ada")
    publish_as_service(broker, "status", dict(waiting, step="manual:0002", settings={}), retain=True)
    page.wait_state("waiting")
    publish_as_service(broker, "progress", dict(progress("r-blip"), point=3, points=10, eta_s=600), qos=0)
    page.wait_text("point", "3 / 10", 10)
    will = {"state": "offline", "run_id": "r-before", "since": "2026-01-05T12:00:00.000Z", "message": "connection lost"}
    publish_as_service(broker, "status", will, retain=True)
    page.wait_state("offline")
    assert (page.text("point"), page.text("eta")) == ("3 / 10", "10:00")  # the last known, under the banner
    # the run on view is named, not the connection's earlier run beside its point
    assert (page.text("run-id"), page.text("run-what")) == ("r-blip", "matrix demo, started by ada")
    back = dict(waiting, since="2026-01-05T13:00:20.000Z", step="manual:0002", settings={})
    publish_as_service(broker, "status", back, retain=True)
    page.wait_state("waiting")
    assert (page.text("point"), page.text("eta"), page.text("eta-held")) == (
        "3 / 10",
        "10:00",
        "(paused: waiting for the operator)",
    )
    page.d.refresh()  # the session's snapshot kept the progress too
    page.signed_in()
    page.wait_state("waiting")
    page.wait_text("point", "3 / 10", 10)
    assert page.text("eta") == "10:00"
    status(broker, "idle", "r-blip", "run stopped")
    page.wait_text("point", "—", 10)  # the run's end still clears it


def test_a_refusal_names_its_command_once(broker, dashboard, browsers):
    viewer = signed_in(browsers, dashboard, "viewer")
    status(broker, "idle", "r-refused", "run stopped")
    viewer.wait_state("idle")
    refused = viewer.command("btn-stop", "stop:")  # (pause cannot apply at idle: disabled)
    assert refused.startswith("stop: refused: not authorised — user 'viewer'"), refused
    assert refused.count("stop") == 1, refused

    operator = signed_in(browsers, dashboard)
    publish_as_service(
        broker, "status", {"state": "offline", "run_id": None, "since": "2026-01-05T13:00:00.000Z", "message": ""}
    )
    operator.wait_state("offline")
    operator.wait(lambda: not operator.el("btn-start").is_enabled(), 10, "start disabled, the service offline")
    offline = operator.send("start", "start:", matrix="demo")
    assert offline == "start: not sent: the rig service is offline", offline  # else carried out when it is back
    status(broker, "idle", "r-refused", "run stopped")


def test_a_results_point_is_counted_as_the_progress_counts_it(broker, dashboard, browsers):
    page = signed_in(browsers, dashboard)
    status(broker, "running", "r-result")
    row = {"lms": "piezo", "model": "kc7", "freq_dep": "none", "coefficients": {"Kxx": 1e7}, "units": {"Kxx": "N/m"}}
    result = {"run_id": "r-result", "index": 0, "point": 0, "label": "w1000rpm", "identification": [row]}
    publish_as_service(broker, "result", json.loads(result_payload("r-result", result)))  # as the service names it
    page.wait(lambda: page.d.find_elements("css selector", "#results tr.fit-first"), 10, "the result row")
    first = page.d.find_element("css selector", "#results tr.fit-first td")
    assert first.text == "1 w1000rpm" and first.get_attribute("title") == "file point 0000"
    status(broker, "idle", "r-result", "run completed")


#: the results box: where it is scrolled, and where its rows are (px from the box's top, under its column heads)
RESULTS_BOX = (
    "const body = document.getElementById('results'), box = body.closest('.scroll');"
    " const top = box.getBoundingClientRect().top + box.querySelector('thead').getBoundingClientRect().height;"
    " return {scroll: box.scrollTop, max: box.scrollHeight - box.clientHeight,"
    " rows: [...body.querySelectorAll('tr.run-row, tr.fit-first')].map(r => [r.children[0].textContent,"
    " Math.round(r.getBoundingClientRect().top - top)])};"
)


def under_the_heads(box: dict, i: int) -> bool:
    """Row ``i`` in view under the column heads: at their foot, or below it with the box scrolled to its end."""
    offset = box["rows"][i][1]
    return abs(offset) <= 1 or (offset > 0 and box["scroll"] >= box["max"] - 1 and offset < 300)


def test_the_results_box_follows_the_newest_result_until_scrolled_by_hand(broker, dashboard, browsers):
    """Over a shift the table outgrows its box: a run's results were under the earlier runs', out of sight at
    the run's end. The box brings each new result (a new run's row) under its column heads; scrolled by hand
    it stays where the person put it."""
    page = signed_in(browsers, dashboard)
    coefficients = {
        k: 1e7 for k in ("Kxx", "Kxy", "Kyx", "Kyy", "Cxx", "Cxy", "Cyx", "Cyy", "Dxx", "Dxy", "Dyx", "Dyy")
    }
    row = {"lms": "piezo", "model": "kcd11", "freq_dep": "none", "coefficients": coefficients}

    def publish(run: str, index: int) -> None:
        result = {"run_id": run, "index": index, "point": index, "label": f"w{index}", "identification": [row]}
        publish_as_service(broker, "result", json.loads(result_payload(run, result)))

    for run, rows in (("r-follow-1", 3), ("r-follow-2", 8)):  # from the second run on, a row names each run
        status(broker, "running", run)
        for index in range(3):
            publish(run, index)
        page.wait(lambda n=rows: len(page.d.execute_script(RESULTS_BOX)["rows"]) >= n, 10, f"{rows} rows")
        status(broker, "idle", run, "run completed")
    box = page.d.execute_script(RESULTS_BOX)
    assert box["max"] > 500, box  # the table outgrew its box
    assert box["rows"][-1][0] == "3 w2" and under_the_heads(box, -1), box  # the newest in view
    page.d.execute_script("document.getElementById('results').closest('.scroll').scrollTop = 0")  # by hand
    page.wait(lambda: page.d.execute_script(RESULTS_BOX)["scroll"] == 0, 5, "the box at its top")
    status(broker, "running", "r-follow-3")
    publish("r-follow-3", 0)
    page.wait(lambda: page.d.execute_script(RESULTS_BOX)["rows"][-2][0] == "run r-follow-3", 10, "the third run")
    assert page.d.execute_script(RESULTS_BOX)["scroll"] == 0  # left where the person put it (scrolled with the row)
    page.d.execute_script(
        "const b = document.getElementById('results').closest('.scroll'); b.scrollTop = b.scrollHeight"
    )
    publish("r-follow-3", 1)  # back at the end: it follows again
    page.wait(lambda: page.d.execute_script(RESULTS_BOX)["rows"][-1][0] == "2 w1", 10, "the newest result")
    box = page.d.execute_script(RESULTS_BOX)
    assert under_the_heads(box, -1), box["rows"][-4:]
    status(broker, "idle", "r-follow-3", "run completed")


#: the events list's items: [time, text after it]
EVENTS = "return [...document.querySelectorAll('#events li')].map(li => [li.textContent.slice(0, 8), li.textContent.slice(9)])"


def test_a_results_warning_keeps_its_time_through_a_reload(broker, dashboard, browsers):
    """A result's fit warning was listed at the time the page drew it: a page reloaded minutes later listed it at
    the reload's time, under older items, as if just said. It keeps the time the dashboard got the result, and
    the list stays newest first."""
    page = signed_in(browsers, dashboard)
    status(broker, "running", "r-said")
    row = {"lms": "piezo", "model": "kc7", "freq_dep": "none", "coefficients": {"Kxx": 1e7}, "warnings": ["bad fit"]}
    result = {"run_id": "r-said", "index": 0, "point": 0, "label": "w1000rpm", "identification": [row]}
    publish_as_service(broker, "result", json.loads(result_payload("r-said", result)))
    words = "⚠ point 1 piezo kc7: bad fit"
    page.wait(lambda: any(text == words for _, text in page.d.execute_script(EVENTS)), 10, "the fit warning")
    said = next(clock for clock, text in page.d.execute_script(EVENTS) if text == words)
    page.wait(lambda: page.d.execute_script("return orbitPlots.clockOf(new Date())") != said, 5, "the clock to move on")
    status(broker, "idle", "r-said", "run completed")  # an item listed after it (its status dated in January)
    page.wait(lambda: "run r-said completed" in page.text("events"), 10, "the run's end")
    page.d.refresh()
    page.signed_in()
    page.wait(lambda: any(text == words for _, text in page.d.execute_script(EVENTS)), 10, "the warning again")
    listed = page.d.execute_script(EVENTS)
    assert [clock for clock, text in listed if text == words] == [said], listed
    times = page.d.execute_script(
        "return [...document.querySelectorAll('#events li')].map(li => Number(li.dataset.at))"
    )
    assert times == sorted(times, reverse=True), listed  # newest first, by the times they were said
