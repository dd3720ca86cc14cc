"""The page's units (static/units.js) against rigunits, run in the real browser the dashboard
tests drive: the ETA the page shows is the terminal's (format_duration), so are the speeds
(rpm_text), the coefficients are shown in the terminal's units (display_unit), and the SI values of the CAN sensors, the manual
settings and the displacements are shown through one table of conversions."""

from __future__ import annotations

import re
from pathlib import Path

import orbitrig.dashboard
import pytest
from rigunits import DISPLAY_UNITS, MICROMETRE, MPA, RPM, UM, display_unit, format_duration, rpm_text

STATIC = Path(orbitrig.dashboard.__file__).parent / "static"
#: durations (s) across every form: under a minute, minutes, hours, the roundings at their edges
DURATIONS = [0, 0.4, 0.5, 1.5, 2.5, 9, 23, 59.4, 59.5, 60, 250, 599.5, 3599.4, 3599.5]
DURATIONS += [3600, 4000, 4000.49, 36000, 359999]


def _run(driver, script: str, *args):
    """`script` after units.js, in a blank page of the real browser."""
    driver.get("about:blank")
    return driver.execute_script((STATIC / "units.js").read_text(encoding="utf-8") + "\n" + script, *args)


def test_the_page_says_a_duration_as_the_terminal_does(driver):
    shown = _run(driver, "return arguments[0].map(formatDuration);", DURATIONS)
    assert shown == [format_duration(s) for s in DURATIONS]
    assert shown[DURATIONS.index(4000)] == "1:06:40" and shown[DURATIONS.index(250)] == "4:10"


#: speeds (rpm) as the feed gives them: set and read (the drives' 0.15 rpm steps), whirl signs, the edges of %g
SPEEDS = [1000.0, 999.9, 1000.05, 20.5, 977.7777777, 569.0, -977.7777777, 0.0, -0.0, 0.3 * 1000, 2500.0]
SPEEDS += [123456.7, 1234567.0, 0.00012, 0.000012, -3.0e-5]


def test_the_page_says_a_speed_as_the_terminal_does(driver):
    script = "return [false, true].map(s => arguments[0].map(v => rpmText(v, s))).concat([rpmText(null)],"
    script += " [arguments[0].map(v => rpmNumber(v)), rpmNumber(null)]);"
    shown = _run(driver, script, SPEEDS)
    assert shown[:2] == [[rpm_text(v * RPM, signed) for v in SPEEDS] for signed in (False, True)]
    assert (shown[0][0], shown[0][1], shown[1][6], shown[1][7], shown[2]) == (
        "1000 rpm",
        "999.9 rpm",
        "-977.778 rpm",
        "+0 rpm",
        "—",
    )
    assert shown[3] == [t.removesuffix(" rpm") for t in shown[0]] and shown[4] == "—"  # a table's cells


def test_the_page_shows_the_coefficients_in_the_terminals_units(driver):
    keys = ["Kxx", "Cxy", "Dyy", "Kxx_1", "Cyx_2", "Dxy_4", "residual_rms"]
    shown = _run(driver, "return [DISPLAY_UNITS, arguments[0].map(displayUnit)];", keys)
    assert shown[0] == {m: list(u) for m, u in DISPLAY_UNITS.items()}
    assert shown[1] == [list(display_unit(k)) for k in keys[:-1]] + [None]  # no matrix: the result's own unit
    assert shown[1][3] == ["MN/m (rad/s)^-1", 1e-6]


def test_the_page_converts_sensor_values_in_one_place(driver):
    shown = _run(
        driver,
        "return [inShownUnit(313.15, '°C'), inShownUnit(1.206e6, 'MPa'), inShownUnit(2.1e-5, 'l/min'),"
        " inShownUnit(0.4, ''), inShownUnit(null, 'MPa'), inShownUnit(5.76e-6, arguments[0])];",
        MICROMETRE,
    )
    assert shown[:5] == [313.15 - 273.15, 1.206e6 / MPA, 2.1e-5 * 6e4, 0.4, None]  # K, Pa, m^3/s in
    assert shown[5] == pytest.approx(5.76e-6 / UM, rel=1e-12)  # an orbit radius, a displacement (m) in


def test_no_other_script_formats_a_duration_or_converts_a_unit_itself():
    others = {p.name: p.read_text(encoding="utf-8") for p in STATIC.glob("*.js") if p.name != "units.js"}
    # a factor of its own: 273.15 (K), 1e6 (Pa, m), 6e4 (m^3/s), as a divisor, a multiplier or an argument
    own = re.compile(r"function formatDuration|273\.15|/ 1e6|\* 1e6|\* 6e4|[,(] ?1e-?6\b|\" h \"|\" min \"|, \"rpm\"\)")
    assert {name: own.findall(text) for name, text in others.items() if own.search(text)} == {}
    page = (STATIC / "index.html").read_text(encoding="utf-8")
    scripts = re.findall(r'<script src="/static/(\w+)\.js"', page)
    assert scripts.index("units") < min(scripts.index(s) for s in ("app", "trend"))  # loaded before its users
