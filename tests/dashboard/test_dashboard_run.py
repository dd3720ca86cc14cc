"""The page in a real headless chromium against a real authenticated mosquitto
and `orbitrig serve --sim`: an operator runs the demo matrix; a viewer, signed
in at the same time in another browser, finds every command refused."""

from __future__ import annotations

import json
import os
import re
import shutil
import time
from pathlib import Path

import pytest
from orbitrig.analysis.typeset import force_html
from orbitrig.load_systems import LMS
from orbitrig.cli.sweep_summary import ND_NOTE
from support.dash_helpers import REPO, RIG, Page, ServiceHolder, card_shot, idle_page
from support.mqtt_helpers import ACCOUNTS

#: Set to a path (e.g. docs/dashboard.png) to keep the screenshot the test makes.
SCREENSHOT_ENV = "ORBITRIG_DASHBOARD_SCREENSHOT"

#: the demo matrix with shorter blocks (20 revolutions, not the rig's 50; a 0.5 s settle hold, not
#: 2 s), for a run watched to its end: the same point, orbit frequencies and fits in half the time
BRIEF = (
    (REPO / "config" / "matrices" / "demo.toml")
    .read_text()
    .replace('name = "demo"', 'name = "brief"\nrevolutions = 20\nsettle_hold_s = 0.5')
)


@pytest.fixture(scope="module")
def service(broker, tmp_path_factory):
    """The module's `serve --sim` on the shipped matrices and BRIEF."""
    work = tmp_path_factory.mktemp("serve")
    shutil.copytree(REPO / "config" / "matrices", work / "matrices")
    (work / "matrices" / "brief.toml").write_text(BRIEF)
    holder = ServiceHolder(broker, work, matrices=work / "matrices")
    yield holder
    holder.proc.stop()


def test_operator_runs_the_demo_matrix(dashboard, service, browsers):
    page = idle_page(browsers, dashboard)
    assert page.text("link") == "online"
    page.el("matrix").clear()
    page.el("matrix").send_keys("demo")
    before = _layout(page)
    assert "accepted" in page.command("btn-start", "start:")

    # the run asks for the point's manual settings: asked and measured values, and Confirm;
    # the prompt appears in its own place: nothing else on the page moves
    page.wait_state("waiting")
    page.wait(lambda: page.el("manual").is_displayed(), 10, "the manual setting panel")
    assert _layout(page) == before
    step = page.text("manual-step")
    assert step == "manual:0000"
    assert page.text("run-what") == "matrix demo, started by operator"  # what runs, for whom: the status says
    # which operating point of the matrix: its label, as its result will name it
    label = page.wait_text("point-label", lambda t: re.fullmatch(r"w1000rpm_pr0\.4826MPa_b\S+_es\S+_ed\S+", t), 10)
    assert page.text("run-warnings") == "none in this run"
    rows = page.rows("manual-table", "setting")
    assert set(rows) == {"orbit_radius", "static_eccentricity", "recess_pressure", "pressure_ratio"}
    assert "5.76" in rows["orbit_radius"]  # demo: dynamic eccentricity 0.096 x clearance 60 um
    assert "4.90 … 6.62" in rows["orbit_radius"]  # the verification's band: +/- 15 %
    assert "0.4826" in rows["recess_pressure"]
    assert page.text("manual-motion") == "Both drives at standstill"  # as the service's prompt says it
    # the ETA stands still while the run waits for the operator's hands, and says so under it
    page.wait_text("eta-held", "(paused: waiting for the operator)", 10)
    assert re.fullmatch(r"\d+:\d\d", page.text("eta")), page.text("eta")  # m:ss, as the terminal
    # a pause asked while the run waits for the operator takes effect once the setting is confirmed: said so,
    # by the service's reply and the waiting status; a resume withdraws it
    held = "the run pauses once manual:0000 is confirmed"
    out = page.command("btn-pause", "pause:")
    assert out == f"pause: accepted: {held} (until then it waits for the operator; a resume withdraws the pause)", out
    page.wait_text("message", lambda t: t.endswith(f"; pause requested by operator: {held}"), 10)
    # the badge reads the service's own waiting words (orbitrig.run.control), not a copy of them
    page.wait_text("state", "waiting — pause requested by operator", 10)
    assert page.state() == "waiting" and page.el("manual").is_displayed()
    assert "resume: accepted" in page.command("btn-resume", "resume:")
    page.wait_text("message", lambda t: "pause" not in t and t.endswith("(confirm step 'manual:0000')"), 10)
    assert "confirm: accepted" in page.command("btn-confirm", "confirm:")
    page.wait_state("running")
    assert not page.el("manual").is_displayed()
    # what the run does now, not the answer it was given
    page.wait_text("message", f"confirmed manual:0000; measuring point 1 of 1: {label} (point 0000)", 10)
    page.wait_text("eta-held", "", 5)

    # progress and waveforms update
    page.wait_text("point", "1 / 1")
    page.wait(lambda: page.canvas_updates("plot-forces") >= 2, 30, "force waveforms")
    n0 = page.canvas_updates("plot-disp")
    revs0 = page.text("revolutions")
    page.wait(lambda: page.canvas_updates("plot-disp") >= n0 + 5, 10, "displacement waveforms updating")
    page.wait(lambda: page.text("revolutions") != revs0, 10, "revolutions counting")
    assert int(page.el("plot-forces").get_attribute("data-samples")) == 4 * 45  # 4 forces x 45 slots
    assert int(page.el("plot-orbit").get_attribute("data-samples")) == 45
    # each trace named in the legend and drawn in its own dash pattern, not told apart by colour alone
    lines = {
        i: [page.el(i).get_attribute(f"data-{a}") for a in ("series", "dashes")] for i in ("plot-forces", "plot-disp")
    }
    assert lines == {
        # the forces as the report names them, with their load measuring system (F<sub>x</sub> piezo)
        "plot-forces": [",".join(f"{force_html(a)} {lms}" for lms in LMS for a in "xy"), "solid,7 3,2 2,9 3 2 3"],
        "plot-disp": ["x plane A,y plane A,x plane B,y plane B", "solid,7 3,2 2,9 3 2 3"],
    }
    caption = page.d.execute_script("return document.getElementById('forces-caption').innerHTML")
    assert caption == f"Forces {force_html('x')}, {force_html('y')} (N)"
    assert page.text("op-spin").endswith(" rpm") and page.text("op-orbit").endswith(" rpm")
    # between orbit frequencies (the averaged revolutions not current) it says "—": a loaded
    # host may read it there, so it is waited for, as the trends below
    page.wait_text("op-orbit-hz", lambda t: t.endswith(" Hz"), 10)
    page.wait(lambda: "spin" in (page.el("trend-speed").get_attribute("data-series") or ""), 10, "the speed trend")
    drives = page.rows("drives", "drive")
    speeds = re.match(r"spin\s+(\d+(?:\.\d*[1-9])?)\s+(\d+(?:\.\d*[1-9])?)\s", drives["spin"])  # no "1000.0"
    assert speeds and all(abs(float(v) - 1000) <= 0.3 for v in speeds.groups()), drives  # the drive's 0.15 rpm steps
    assert "running" in drives["spin"]
    aux = page.rows("aux", "aux")
    assert "0.2000 … 8.0000" in aux["p_supply"]  # the supply pressure interlock band, MPa

    # pause (at the next safe point), resume, stop
    # accepted is not paused: the outcome says (the service's reply) the run goes on to its next safe point
    paused = page.command("btn-pause", "pause:")
    assert paused == "pause: accepted: the run pauses at its next safe point", paused
    page.wait_state("paused", 30)
    page.wait_text("eta-held", "(paused with the run)", 5)
    assert "resume: accepted" in page.command("btn-resume", "resume:")
    page.wait_state("running", 15)
    page.wait_text("eta-held", "", 5)
    assert "stop: accepted" in page.command("btn-stop", "stop:")
    page.wait_state("idle", 60)
    assert "stopped" in page.text("message")
    # how the run ended stays listed with the run's folder, which `orbitrig sweep --resume` takes up
    run_id = page.text("run-id")
    ended = [
        e
        for e in page.d.execute_script("return [...document.querySelectorAll('#events li')].map(li => li.textContent)")
        if f"run {run_id} stopped" in e
    ]
    folder = re.fullmatch(r".* is incomplete: .* \(run folder (/\S+)\)", ended[0]) if len(ended) == 1 else None
    assert folder and run_id in (Path(folder.group(1)) / "run.log").read_text(), ended


def _frequency(page: Page) -> int:
    """The progress's orbit block ordinal in its point (0 before the first)."""
    text = page.text("block").split(" of ")[0].strip()
    return int(text) if text.isdigit() else 0


def _layout(page: Page) -> dict[str, tuple[int, int]]:
    """(left, top) of every card but the manual setting's own, in page pixels."""
    return page.d.execute_script(
        "const out = {}; document.querySelectorAll('main > section').forEach((s, i) => {"
        " const r = s.getBoundingClientRect(); out[s.id || s.className + i] = [Math.round(r.left), Math.round(r.top)]; });"
        " return out;"
    )


def test_viewer_sees_everything_and_commands_nothing(dashboard, service, browsers, tmp_path):
    operator = Page(browsers(), dashboard.url, dashboard)
    operator.sign_in("operator", ACCOUNTS["operator"])
    operator.signed_in()
    operator.wait_state("idle", 60)
    viewer = Page(browsers(), dashboard.url, dashboard)
    viewer.sign_in("viewer", ACCOUNTS["viewer"])
    viewer.signed_in()
    assert viewer.text("who") == "viewer" and operator.text("who") == "operator"

    operator.el("matrix").clear()
    operator.el("matrix").send_keys("brief")  # watched to its end: the demo's point in short blocks
    operator.command("btn-start", "start: accepted")
    viewer.wait_state("waiting")
    viewer.wait(lambda: viewer.el("manual").is_displayed(), 10, "the viewer's manual setting panel")

    # (Start and Resume cannot apply while the run waits: disabled, not sent)
    viewer.wait(
        lambda: not viewer.el("btn-start").is_enabled() and not viewer.el("btn-resume").is_enabled(), 10, "disabled"
    )
    for button in ("btn-confirm", "btn-pause", "btn-stop", "btn-abort"):
        outcome = viewer.command(button, "refused: not authorised")
        assert "'viewer' may not command this rig" in outcome, outcome
    events = viewer.text("events")
    assert events.count("refused: not authorised") == 4
    refusals = [line for line in events.splitlines() if "refused: not authorised" in line]
    assert all(line[9:].startswith("✖ ") for line in refusals), refusals  # in a mark as well as in red
    assert viewer.state() == "waiting" and operator.state() == "waiting"  # nothing changed

    operator.command("btn-confirm", "confirm: accepted")
    viewer.wait_state("running", 15)
    viewer.wait(lambda: viewer.canvas_updates("plot-orbit") >= 3, 30, "the viewer's orbit plot")
    # the page during the run (the README's picture): live values, drives, sensors, waveforms
    operator.wait(lambda: operator.canvas_updates("plot-orbit") >= 3, 30, "the operator's orbit plot")
    operator.wait(lambda: _frequency(operator) >= 6 or operator.state() != "running", 30, "half the run's trends")
    shot = Path(os.environ.get(SCREENSHOT_ENV) or tmp_path / "dashboard.png")
    if not shot.is_absolute():
        shot = REPO / shot
    operator.d.execute_script(
        "const s = document.getElementById('trend-window'); s.value = 'run';"
        "s.dispatchEvent(new Event('change')); window.scrollTo(0, 0)"
    )
    time.sleep(0.2)
    operator.screenshot(shot)
    assert shot.stat().st_size > 20_000
    # the demo point completes: both load measuring systems x both models, one row per coefficient
    # with its value, U (its k in the title) and unit, as the terminal shows them (MN/m, kN s/m)
    fits = "#results tr.fit-first"
    viewer.wait(lambda: len(viewer.d.find_elements("css selector", fits)) == 4, 90, "4 fits in the results")
    viewer.wait_state("idle", 30)
    operator.wait(lambda: len(operator.d.find_elements("css selector", fits)) >= 4, 10, "the operator's results")
    assert len(operator.d.find_elements("css selector", fits)) == 4, operator.text("results")  # each once
    text = operator.text("results")
    assert "piezo" in text and "strain" in text
    assert re.search(r"\bKxx\s-?[\d.]+(e[+-]\d+)?\s[\d.]+(e[+-]\d+)?\sMN/m\b", text), text
    assert re.search(r"\bCxx\s-?[\d.]+(e[+-]\d+)?\s[\d.]+(e[+-]\d+)?\skN s/m\b", text), text
    card_shot(operator, "trends-card", "trends", tmp_path)  # the demo run's trends


def test_results_show_values_u_and_units_as_they_arrive(broker, dashboard, browsers):
    """A result is drawn as it arrives: a row per coefficient with its value, U (95 %) and unit (the
    terminal's: MN/m, kN s/m, kg, rigunits.display_unit, where the result says N/m), a coefficient not
    determined marked "n.d." as the terminal marks it (ND_NOTE its tooltip); a refusal."""
    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in("viewer", ACCOUNTS["viewer"])
    page.signed_in()
    page.wait_text("link", "online")
    rows_before = len(page.d.find_elements("css selector", "#results tr"))
    # a new session's table is empty and says what it holds: the results from the sign-in on
    assert rows_before == 0 and page.el("results-empty").is_displayed()
    assert page.text("results-empty").startswith("No result since you signed in: those published before are in")
    result = {
        "run_id": "r-test",
        "index": 7,  # 0-based (file point 0007): the page counts it from 1, as the progress
        "point": 7,
        "label": "w1000rpm",
        "identification": [
            {
                "lms": "piezo",
                "model": "kc8",
                "freq_dep": "none",
                "method": "ols",
                "coefficients": {"Kxx": 1.5e7, "Cxx": 2.0e4, "Kyy": 3.3794e7, "Dxx": -19.24},
                "std_errors": {"Kxx": 1e5, "Cxx": 1e2, "Kyy": 4.3e5, "Dxx": 15.0},
                "confidence_95": {"Kxx": [1.48e7, 1.52e7], "Cxx": [1.98e4, 2.02e4]},
                "expanded_uncertainty": {
                    "k": 2,
                    "basis": "statistical",
                    "values": {"Kxx": 2e5, "Cxx": 2e2, "Kyy": 8.667e5, "Dxx": 29.78},
                },
                "units": {"Kxx": "N/m", "Cxx": "N s/m", "Kyy": "N/m", "Dxx": "kg"},
                "not_determined": ["Cxx"],
                "warnings": ["condition number 3.1e6: Kxy poorly determined"],
            },
            {"lms": "strain", "model": "kcd11", "error": "too few orbit frequencies: 2 < 3"},
        ],
    }
    done = broker.pub(f"orbitrig/{RIG}/result", json.dumps(result), user="orbitrig-service")
    assert done.returncode == 0, done.stderr
    page.wait(lambda: len(page.d.find_elements("css selector", "#results tr")) == rows_before + 5, 10, "5 rows")
    rows = page.d.execute_script(
        "return [...document.querySelectorAll('#results tr')].slice(-5).map(r => [...r.children].map(c => c.innerText))"
    )
    # U to 2 significant digits and the value to its decimal, as the report and `orbitrig reduce` round
    assert rows[0] == ["8 w1000rpm", "piezo", "kc8", "Kxx", "15.00", "0.20", "MN/m"]
    assert not page.el("results-empty").is_displayed()
    assert rows[1] == ["", "", "", "Cxx", "20.00 n.d.", "0.20", "kN s/m"]  # as the terminal says it, not red alone
    assert rows[2] == ["", "", "", "Kyy", "33.79", "0.87", "MN/m"]  # not 0.8667
    assert rows[3] == ["", "", "", "Dxx", "-19", "30", "kg"]  # not -19.24 beside 29.78
    head = page.d.execute_script("return [...document.querySelectorAll('table.results th')].map(c => c.innerText)")
    assert head[-3:] == ["Value", "U (95 %)", "Unit"]  # MN/m, kN s/m are not SI units: not "Unit (SI)"
    nd_title = "return [...document.querySelectorAll('#results tr')].slice(-5)[arguments[0]].children[4].title"
    assert page.d.execute_script(nd_title, 1) == ND_NOTE
    assert page.d.execute_script(nd_title, 0) == ""
    assert rows[4] == ["8 w1000rpm", "strain", "kcd11", "refused: too few orbit frequencies: 2 < 3"]
    events = page.text("events")
    assert "point 8 piezo kc8: condition number 3.1e6: Kxy poorly determined" in events
    assert "point 8 strain kcd11: too few orbit frequencies: 2 < 3" in events
