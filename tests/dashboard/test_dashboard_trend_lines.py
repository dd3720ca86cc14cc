"""A chart's lines differ in more than colour, in the real browser: each line of a trend chart and of an
averaged revolution's chart is drawn (and its legend entry too) in its own dash pattern, solid, dashed,
dotted, dash-dot, read back from the canvas's pixels whatever their colour; a line keeps its look while
another of its chart has no samples."""

from __future__ import annotations

from pathlib import Path

import orbitrig.dashboard

STATIC = Path(orbitrig.dashboard.__file__).parent / "static"

#: lines at levels between the grid lines, over 100 s in a trend chart (arguments[1] "trend") or over a revolution of 45
#: slots in N (an averaged revolution's); for each: the runs of drawn pixels (any colour) along the line's row in the
#: plot and along its legend entry's short line; then the canvas's data-dashes and data-series
DRAW = """
const canvas = document.createElement("canvas"), trend = arguments[1] === "trend"; document.body.appendChild(canvas);
canvas.width = 420; canvas.height = trend ? 180 : 220;
const lines = arguments[0], times = Array.from({length: 101}, (_, i) => i);
const series = lines.map(([name, line, v]) => ({name, line, points: times.map(t => [t, v]), values: Array(45).fill(v)}));
if (trend) orbitPlots.drawTrend(canvas, series, null, [0, 100]);
else orbitPlots.drawTraces(canvas, series, "N");
const ctx = canvas.getContext("2d"), m = {l: 52, r: 14, t: 22, b: 20}, h = canvas.height;
const y = orbitPlots.niceTicks(Math.min(...lines.map(l => l[2])), Math.max(...lines.map(l => l[2])), 4);
const drawn = (x0, x1, row) => {
  const rows = [row - 1, row, row + 1].map(r => ctx.getImageData(x0, r, x1 - x0, 1).data);
  return Array.from({length: x1 - x0}, (_, i) => Math.max(...rows.map(d => d[4 * i + 3])) > 60);
};
const runs = on => { const out = []; let n = 0; on.forEach(b => { if (b) n++; else if (n) { out.push(n); n = 0; } }); if (n) out.push(n); return out; };
ctx.font = "10px sans-serif";
let x = m.l;
return series.map(s => {
  const row = Math.round(h - m.b - (h - m.t - m.b) * (s.values[0] - y.lo) / (y.hi - y.lo));
  const plot = runs(drawn(m.l + 4, canvas.width - m.r - 8, row)), key = runs(drawn(x, x + 18, 9));
  x += 28 + ctx.measureText(s.name).width;
  return {plot, key};
}).concat([canvas.dataset.dashes, canvas.dataset.series]);
"""


def _draw(driver, lines, chart: str = "trend"):
    driver.get("about:blank")
    scripts = "\n".join((STATIC / f"{name}.js").read_text(encoding="utf-8") for name in ("units", "plots"))
    return driver.execute_script(scripts + "\n" + DRAW, lines, chart)


def _look(runs: list[int], whole: bool = True) -> str:
    """solid | dashed | dotted | dash-dot, from the lengths (px) of the drawn runs along a line; a plot's
    line (not `whole`) is judged on its inner runs, its ends cut by the plot area wherever the pattern is."""
    if len(runs) == 1 and runs[0] >= 17:
        return "solid"
    inner = runs if whole else runs[1:-1]
    long, short = [n for n in inner if n >= 5], [n for n in inner if n < 5]
    if long and short:
        return "dash-dot"
    return "dashed" if long else "dotted" if len(short) >= 3 else "?"


def test_each_line_and_its_legend_entry_have_their_own_dash_pattern(driver):
    *drawn, dashes, _ = _draw(
        driver, [["spin", 0, 1.3], ["spin set", 1, 2.3], ["orbit", 2, 3.6], ["orbit set", 3, 4.6]]
    )
    assert [_look(d["plot"], whole=False) for d in drawn] == ["solid", "dashed", "dotted", "dash-dot"], drawn
    assert [_look(d["key"]) for d in drawn] == ["solid", "dashed", "dotted", "dash-dot"], drawn
    assert dashes == "solid,7 3,2 2,9 3 2 3"


def test_a_line_keeps_its_look_while_another_has_no_samples(driver):
    *drawn, dashes, _ = _draw(driver, [["spin", 0, 1.3], ["orbit", 2, 3.6]])  # no set points in the window
    assert [_look(d["plot"], whole=False) for d in drawn] == ["solid", "dotted"] == [_look(d["key"]) for d in drawn], (
        drawn
    )
    assert dashes == "solid,2 2"


def test_each_trace_of_an_averaged_revolution_has_its_own_dash_pattern_and_name(driver):
    forces = [["Fx piezo", 0, 130.0], ["Fy piezo", 1, 230.0], ["Fx strain", 2, 360.0], ["Fy strain", 3, 460.0]]
    *drawn, dashes, names = _draw(driver, forces, "revolution")
    assert [_look(d["plot"], whole=False) for d in drawn] == ["solid", "dashed", "dotted", "dash-dot"], drawn
    assert [_look(d["key"]) for d in drawn] == ["solid", "dashed", "dotted", "dash-dot"], drawn
    assert (dashes, names) == ("solid,7 3,2 2,9 3 2 3", "Fx piezo,Fy piezo,Fx strain,Fy strain")
    # a channel missing from the payload: the others keep their looks
    *drawn, dashes, names = _draw(driver, [forces[1], forces[3]], "revolution")
    assert [_look(d["plot"], whole=False) for d in drawn] == ["dashed", "dash-dot"] == [_look(d["key"]) for d in drawn]
    assert (dashes, names) == ("7 3,9 3 2 3", "Fy piezo,Fy strain")


#: a trend over 50.1 s whose last tick (10 s steps) falls 0.6 s before the window's end, near the right edge: the
#: ink of the time labels' band (the canvas's bottom margin) per column, and the labels' extents (data-xlabels)
EDGE_LABEL = """
const canvas = document.createElement("canvas"); document.body.appendChild(canvas);
canvas.width = 420; canvas.height = 180;
const t0 = 1765000000.5, t1 = t0 + 50.1, points = Array.from({length: 51}, (_, i) => [t0 + i, 1.0 + 0.01 * i]);
orbitPlots.drawTrend(canvas, [{name: "spin", line: 0, points}], null, [t0, t1]);
const band = canvas.getContext("2d").getImageData(0, canvas.height - 16, canvas.width, 16).data;
const ink = Array.from({length: canvas.width}, (_, x) => {
  let on = 0; for (let r = 0; r < 16; r++) if (band[4 * (r * canvas.width + x) + 3] > 60) on++; return on; });
return [ink, canvas.dataset.xlabels || ""];
"""


def test_a_time_label_near_the_right_edge_is_drawn_whole(driver):
    """A tick a little before the window's end had its label centred under it, its end cut by the canvas's
    edge (docs/dashboard.png's 'whole run' charts: '07:18:3'); it is kept inside the canvas."""
    driver.get("about:blank")
    scripts = "\n".join((STATIC / f"{name}.js").read_text(encoding="utf-8") for name in ("units", "plots"))
    ink, extents = driver.execute_script(scripts + "\n" + EDGE_LABEL)
    assert sum(ink[-60:]) > 0  # the last label is drawn near the edge
    assert ink[-1] == 0 and ink[-2] == 0, ink[-12:]  # and ends before it, not cut
    spans = [tuple(float(v) for v in e.split("..")) for e in extents.split(",")]
    assert len(spans) == 5 and all(0 <= a < b <= 418 for a, b in spans), extents


#: the labels of a trend's time axis over [arguments[0], arguments[1]] (s since the epoch), in the page's zone
TIME_LABELS = "return orbitPlots.timeTicks(arguments[0], arguments[1]).map(([, text]) => text);"
DEC_6 = 1796515200  # 2026-12-06T00:00:00Z


def _time_labels(driver, zone: str, t0: float, t1: float) -> list[str]:
    driver.execute_cdp_cmd("Emulation.setTimezoneOverride", {"timezoneId": zone})
    try:
        scripts = "\n".join((STATIC / f"{name}.js").read_text(encoding="utf-8") for name in ("units", "plots"))
        return driver.execute_script(scripts + "\n" + TIME_LABELS, t0, t1)
    finally:
        driver.execute_cdp_cmd("Emulation.setTimezoneOverride", {"timezoneId": ""})


def test_the_time_axis_ticks_round_times_of_the_pages_clock_and_names_the_days(driver):
    """A trend's time ticks fall on round times of the browser's clock, not of UTC (in a zone half an hour
    off, 6 h ticked 01:30, 02:30, ...); over days a tick at midnight says its date, and a month-long run's
    whole view has a few dated ticks (it had 30, each '19:00' in New York, one over the other)."""
    driver.get("about:blank")
    kolkata = _time_labels(driver, "Asia/Kolkata", DEC_6, DEC_6 + 6 * 3600)  # 05:30 to 11:30 there
    assert kolkata == ["06:00", "07:00", "08:00", "09:00", "10:00", "11:00"], kolkata
    two_days = _time_labels(driver, "America/New_York", DEC_6, DEC_6 + 2 * 86400)  # 12-05 19:00 to 12-07 19:00
    assert two_days == ["2026-12-06", "12:00", "2026-12-07", "12:00"], two_days
    month = _time_labels(driver, "America/New_York", DEC_6, DEC_6 + 30 * 86400)
    assert month == ["2026-12-17", "2026-12-31"], month  # every 14 days: at most 4 dates fit a chart
    short = _time_labels(driver, "Europe/Berlin", DEC_6 + 600, DEC_6 + 600 + 50)  # 01:10:00 to 01:10:50 there
    assert short == ["01:10:00", "01:10:10", "01:10:20", "01:10:30", "01:10:40", "01:10:50"], short
