// Trend charts: speeds, pressures, temperatures, flow and torque over the run or the last N minutes.
// The dashboard server keeps the history (bounded) and sends it on connect ("trend_history"), then
// every sample ("trend"), and its thinned view of the run again every 300 samples (recent: null).
// The page keeps at most RECENT_MAX recent samples and the server's run view plus at most
// RUN_TAIL_MAX samples since it.
"use strict";

const RECENT_MAX = 1800, RUN_TAIL_MAX = 600;
const trendState = {recent: [], run: [], runId: null, bands: {}};

// chart id -> [series: [key, label]] (each line drawn in its own colour and dash pattern: orbitPlots.drawTrend),
// unit text, value in shown unit, band key
const TREND_CHARTS = {
  "trend-speed": [[["spin_rpm", "spin"], ["spin_set_rpm", "spin set"], ["orbit_rpm", "orbit"], ["orbit_set_rpm", "orbit set"]], "rpm", v => v, null],
  "trend-supply": [[["p_supply", "supply"]], "MPa", SHOWN_IN.MPa, "p_supply"],
  "trend-recess": [[["p_recess_1", "recess 1"], ["p_recess_2", "recess 2"], ["p_recess_3", "recess 3"], ["p_recess_4", "recess 4"]], "MPa", SHOWN_IN.MPa, "p_recess"],
  "trend-temperature": [[["t_supply", "supply"], ["t_recess", "recess"], ["t_groove", "groove"]], "°C", SHOWN_IN["°C"], null],
  "trend-flow": [[["flow", "flow"]], "l/min", SHOWN_IN["l/min"], null],
  "trend-torque": [[["torque_spin", "spin"], ["torque_orbit", "orbit"]], "%", v => v, null],
};

function trendHistory(h) {
  trendState.runId = h.run_id;
  if (h.recent) trendState.recent = h.recent.slice(-RECENT_MAX);
  trendState.run = h.run || [];
  trendState.runKept = trendState.run.length;
  scheduleDraw();
}

function trendSample(s, runId) {
  if (runId !== trendState.runId) Object.assign(trendState, {runId, run: [], runKept: 0});  // a new run
  trendState.recent.push(s);
  if (trendState.recent.length > RECENT_MAX) trendState.recent.splice(0, trendState.recent.length - RECENT_MAX);
  trendState.run.push(s);
  const tail = trendState.run.length - (trendState.runKept || 0);  // samples since the server's view
  if (tail > RUN_TAIL_MAX) trendState.run.splice(trendState.runKept || 0, tail - RUN_TAIL_MAX);
  scheduleDraw();
}

// samples arriving together are drawn once, at the next frame
function scheduleDraw() {
  if (trendState.drawPending) return;
  trendState.drawPending = true;
  requestAnimationFrame(() => { trendState.drawPending = false; drawTrends(); });
}

// the window follows the clock also while no sample comes (a service that hangs, the run over): the latest
// samples move left, away from the right edge, instead of standing there as the present
const FOLLOW_CLOCK_MS = 2000;
setInterval(scheduleDraw, FOLLOW_CLOCK_MS);
// a window made wider or narrower: the charts drawn again at their new width (plots.js fitWidth), not stretched
window.addEventListener("resize", scheduleDraw);

function trendBands(bands) { trendState.bands = bands || {}; }

function trendWindow() {
  const sel = document.getElementById("trend-window").value;
  const now = Date.now() / 1000;
  if (sel === "run") {
    const data = trendState.run;
    const t0 = data.length ? data[0].t : now - 60;
    return [data, [t0, Math.max(now, t0 + 60)]];
  }
  return [trendState.recent, [now - Number(sel), now]];
}

function drawTrends() {
  const [all, win] = trendWindow();
  const data = all.filter(s => s.t >= win[0]);  // the axes and legends of what the window shows, not of older samples
  Object.entries(TREND_CHARTS).forEach(([id, [keys, , shown, bandKey]]) => {
    const series = keys.map(([key, label], line) => ({name: label, line,
      points: data.map(s => [s.t, s[key] === null || s[key] === undefined ? null : shown(s[key])])}))
      .filter(s => s.points.some(p => p[1] !== null));
    const raw = bandKey ? trendState.bands[bandKey] : null;
    const band = raw ? [shown(raw[0]), shown(raw[1])] : null;
    orbitPlots.drawTrend(document.getElementById(id), series, band, win);
  });
}

function trendClear() { Object.assign(trendState, {recent: [], run: [], runKept: 0, runId: null, bands: {}}); }

window.trends = {trendHistory, trendSample, trendBands, drawTrends, trendClear};
