// Canvas plots of the live view: one averaged revolution, the orbit and trend charts.
// Axes use "nice" ticks (1, 2, 2.5, 5 x 10^n) covering the data; legends sit above the plot
// area, never over a trace.
"use strict";

const COLOURS = ["#1976d2", "#c62828", "#2e7d32", "#ef6c00", "#6a1b9a", "#00838f", "#5d4037", "#ad1457"];
// the k-th line of a chart (trend or averaged revolution) also has the k-th dash pattern (solid, dashed,
// dotted, dash-dot), in its legend too: no line is told from another by its colour alone (a reader who does
// not tell the colours apart, a grey print); a chart has at most as many lines as patterns
const DASHES = [[], [7, 3], [2, 2], [9, 3, 2, 3]];

// the colour and dash pattern of each of `series` by its `line` (its place among the chart's lines, so that
// each keeps its look while another is missing; its index when not given)
function looks(series) {
  const look = series.map((s, k) => (s.line === undefined ? k : s.line));
  return {colour: k => COLOURS[look[k] % COLOURS.length], dash: k => DASHES[look[k] % DASHES.length]};
}

// a line's name: its text, or [symbol, subscript, after] as the report names a force with its load measuring
// system (the hello's names, orbitrig.analysis.typeset.force_channels: ["F", "x", "piezo"]); its HTML form
// (F<sub>x</sub> piezo) is what a test reads of it
function nameHtml(n) { return Array.isArray(n) ? n[0] + "<sub>" + n[1] + "</sub>" + (n[2] ? " " + n[2] : "") : n; }

// `n` drawn from (x, y) at the legend's 10 px, a subscript at 8 px and lowered; returns its width (px)
function drawName(ctx, n, x, y) {
  const parts = Array.isArray(n) ? [[n[0], 10, 0], [n[1], 8, 3], [n[2] ? " " + n[2] : "", 10, 0]] : [[n, 10, 0]];
  let w = 0;
  parts.forEach(([text, px, down]) => {
    ctx.font = px + "px sans-serif"; ctx.fillText(text, x + w, y + down); w += ctx.measureText(text).width;
  });
  ctx.font = "10px sans-serif";
  return w;
}

// what a test reads of a chart's lines: their names and dash patterns ("solid", "7 3", ...), in drawing order
function markLines(canvas, series, dash) {
  canvas.dataset.series = series.map(s => nameHtml(s.name)).join(",");
  canvas.dataset.dashes = series.map((s, k) => dash(k).join(" ") || "solid").join(",");
}

// ticks covering [lo, hi]: about `target` round steps; returns {lo, hi, step, ticks}
function niceTicks(lo, hi, target) {
  target = target || 5;
  if (!isFinite(lo) || !isFinite(hi)) { lo = -1; hi = 1; }
  if (hi - lo < 1e-12 * Math.max(1, Math.abs(hi))) { const d = Math.abs(hi) * 0.1 || 1; lo -= d; hi += d; }
  const raw = (hi - lo) / target, mag = Math.pow(10, Math.floor(Math.log10(raw)));
  const step = [1, 2, 2.5, 5, 10].map(f => f * mag).find(s => s >= raw) || 10 * mag;
  const a = Math.floor(lo / step + 1e-9) * step, b = Math.ceil(hi / step - 1e-9) * step;
  const ticks = [];
  for (let v = a; v <= b + step * 1e-6; v += step) ticks.push(Math.abs(v) < step * 1e-9 ? 0 : v);
  return {lo: a, hi: b, step, ticks};
}

// a tick label with the digits its step needs (no raw extremes such as -2.94 or -1.8e-3)
function fmtTick(v, step) {
  if (Math.abs(v) < 1e-12) return "0";
  step = step || Math.abs(v);
  const e = Math.floor(Math.log10(step) + 1e-9), extra = Math.abs(step / Math.pow(10, e) - 2.5) < 1e-6 ? 1 : 0;
  if (Math.max(Math.abs(v), step) >= 1e5 || step < 1e-3) return v.toExponential(Math.max(0, Math.floor(Math.log10(Math.abs(v)) + 1e-9) - e + extra));
  return v.toFixed(Math.max(0, extra - e));
}

const MARGIN = {l: 52, r: 14, t: 22, b: 20};

// a chart as wide as its place on the page (class fluid: its figure's width, less the canvas's border) in
// whole pixels, its drawing as wide: drawn in the page's pixels, neither stretched nor blurred (the height is fixed)
function fitWidth(canvas) {
  if (!canvas.classList.contains("fluid")) return;
  const room = Math.floor(canvas.parentElement.getBoundingClientRect().width) - 2;
  if (room > 0 && canvas.width !== room) { canvas.width = room; canvas.style.width = room + "px"; }
}

function frame(ctx, w, h, y, xticks, m) {
  m = m || MARGIN;
  ctx.clearRect(0, 0, w, h);
  ctx.strokeStyle = "#cfd8dc"; ctx.fillStyle = "#546e7a"; ctx.font = "10px sans-serif"; ctx.lineWidth = 1;
  ctx.strokeRect(m.l, m.t, w - m.l - m.r, h - m.t - m.b);
  ctx.textAlign = "right"; ctx.textBaseline = "middle";
  y.ticks.forEach(v => {
    const py = h - m.b - (h - m.t - m.b) * (v - y.lo) / (y.hi - y.lo);
    ctx.beginPath(); ctx.moveTo(m.l, py); ctx.lineTo(w - m.r, py); ctx.stroke();
    ctx.fillText(fmtTick(v, y.step), m.l - 4, py);
  });
  ctx.textBaseline = "alphabetic"; ctx.textAlign = "left";
  // the first label starts at its tick, the last ends at it, the others centred under theirs but kept inside the
  // canvas (a tick near an edge: its label's half past the margin was cut, "07:18:3"); their extents in px in
  // data-xlabels ("left..right,...")
  const extents = xticks.map(([frac, text]) => {
    const x = m.l + (w - m.l - m.r) * frac, tw = ctx.measureText(text).width;
    const left = frac <= 0 ? x : frac >= 1 ? x - tw : Math.min(Math.max(x - tw / 2, 2), w - tw - 2);
    ctx.fillText(text, left, h - m.b + 15);
    return left.toFixed(1) + ".." + (left + tw).toFixed(1);
  });
  ctx.canvas.dataset.xlabels = extents.join(",");
}

// legend in the top margin, left to right: each name after a short line in its colour and, with
// `dashes`, its dash pattern
function legend(ctx, names, colours, dashes) {
  let x = MARGIN.l;
  ctx.font = "10px sans-serif"; ctx.textBaseline = "middle"; ctx.lineWidth = 2;
  names.forEach((n, k) => {
    ctx.strokeStyle = colours[k]; ctx.setLineDash(dashes ? dashes[k] : []);
    ctx.beginPath(); ctx.moveTo(x, 9.5); ctx.lineTo(x + 18, 9.5); ctx.stroke();
    ctx.fillStyle = "#37474f";
    x += 28 + drawName(ctx, n, x + 21, 10);
  });
  ctx.setLineDash([]); ctx.textBaseline = "alphabetic";
}

function mark(canvas, samples, y) {
  canvas.dataset.updates = String(Number(canvas.dataset.updates || 0) + 1);
  canvas.dataset.samples = String(samples);
  canvas.dataset.ticks = y.ticks.map(v => fmtTick(v, y.step)).join(" ");
}

// series: [{name, values, line}], values (SI) over one revolution (samples evenly spread over 360 deg), drawn in
// `unit` (inShownUnit); the k-th in COLOURS[line] and DASHES[line] (line: as drawTrend's), its legend entry too
function drawTraces(canvas, series, unit) {
  const again = () => drawTraces(canvas, series, unit);  // this drawing, as a resize repeats it (tracesShown)
  fitWidth(canvas);
  const ctx = canvas.getContext("2d"), w = canvas.width, h = canvas.height, m = MARGIN;
  let lo = Infinity, hi = -Infinity;
  series = series.map(s => ({name: s.name, line: s.line, values: s.values.map(v => inShownUnit(v, unit))}));
  series.forEach(s => s.values.forEach(v => { if (v !== null) { lo = Math.min(lo, v); hi = Math.max(hi, v); } }));
  const y = niceTicks(lo, hi, 4), {colour, dash} = looks(series);
  frame(ctx, w, h, y, [[0, "0°"], [0.25, "90°"], [0.5, "180°"], [0.75, "270°"], [1, "360°"]]);
  series.forEach((s, k) => {
    const n = s.values.length;
    ctx.strokeStyle = colour(k); ctx.lineWidth = 1.5; ctx.setLineDash(dash(k)); ctx.beginPath();
    s.values.forEach((v, i) => {
      const x = m.l + (w - m.l - m.r) * i / Math.max(1, n), py = h - m.b - (h - m.t - m.b) * (v - y.lo) / (y.hi - y.lo);
      i ? ctx.lineTo(x, py) : ctx.moveTo(x, py);
    });
    ctx.stroke();
  });
  ctx.setLineDash([]);
  legend(ctx, series.map(s => s.name), series.map((s, k) => colour(k)), series.map((s, k) => dash(k)));
  mark(canvas, series.reduce((a, s) => a + s.values.length, 0), y);
  markLines(canvas, series, dash);
  if (canvas.classList.contains("fluid")) tracesShown.set(canvas, again);
}

// the last drawing of each chart of drawTraces as wide as its place: a window made wider or narrower draws them
// again at their new width (once a frame), also while no live payload comes (the last values kept, ageing);
// the trends: trend.js
const tracesShown = new Map();
let tracesPending = false;
window.addEventListener("resize", () => {
  if (tracesPending) return;
  tracesPending = true;
  requestAnimationFrame(() => { tracesPending = false; tracesShown.forEach(draw => draw()); });
});

// a chart emptied (the run's view cleared: its end, another rig): nothing in it, nor drawn again on a resize
function clearChart(canvas) {
  canvas.getContext("2d").clearRect(0, 0, canvas.width, canvas.height);
  tracesShown.delete(canvas);
}

// margins that leave a square plot area in a w x h canvas (the wider side's margins grow alike)
function squareMargin(w, h) {
  const pw = w - MARGIN.l - MARGIN.r, ph = h - MARGIN.t - MARGIN.b, dx = Math.max(0, pw - ph) / 2, dy = Math.max(0, ph - pw) / 2;
  return {l: MARGIN.l + dx, r: MARGIN.r + dx, t: MARGIN.t + dy, b: MARGIN.b + dy};
}

// x, y: displacements over one revolution (m); drawn in um, equal axes (a circular orbit is drawn
// round: the same pixels per um across and up), closed curve
function drawOrbit(canvas, x, y) {
  const ctx = canvas.getContext("2d"), w = canvas.width, h = canvas.height, m = squareMargin(w, h);
  const xs = x.map(v => inShownUnit(v, "µm")), ys = y.map(v => inShownUnit(v, "µm"));
  const r = Math.max(1e-3, ...xs.map(Math.abs), ...ys.map(Math.abs));
  const ax = niceTicks(-r, r, 4);
  frame(ctx, w, h, ax, ax.ticks.map(v => [(v - ax.lo) / (ax.hi - ax.lo), fmtTick(v, ax.step)]), m);
  const px = v => m.l + (w - m.l - m.r) * (v - ax.lo) / (ax.hi - ax.lo), py = v => h - m.b - (h - m.t - m.b) * (v - ax.lo) / (ax.hi - ax.lo);
  ctx.strokeStyle = "#1976d2"; ctx.lineWidth = 1.8; ctx.beginPath();
  xs.forEach((v, i) => (i ? ctx.lineTo(px(v), py(ys[i])) : ctx.moveTo(px(v), py(ys[i]))));
  ctx.closePath(); ctx.stroke();
  ctx.fillStyle = "#c62828"; ctx.beginPath(); ctx.arc(px(xs[0] || 0), py(ys[0] || 0), 3, 0, 2 * Math.PI); ctx.fill();
  mark(canvas, xs.length, ax);
}

function clockText(t, seconds) { const d = new Date(t * 1000); return d.toTimeString().slice(0, seconds ? 8 : 5); }

// the page's clock, the same everywhere (axes, alarms, events): local time, 24 h, the date as
// 2026-12-05 (no browser locale's order: 12/5 is not read alike by everyone)
function clockOf(when) { return new Date(when).toTimeString().slice(0, 8); }
function dateTimeOf(when) {
  const d = new Date(when), two = n => String(n).padStart(2, "0");
  return isNaN(d) ? null : d.getFullYear() + "-" + two(d.getMonth() + 1) + "-" + two(d.getDate()) + " " + clockOf(d);
}
// a time the page shows in its clock: an ISO time as dateTimeOf writes it, a text the browser cannot read
// as it came (said, not lost), nothing as "—"
function localTime(when) { return dateTimeOf(when) || when || "—"; }
// a time where room is short (the events, the command's outcome, the state badge): the clock alone when it is the
// browser's today, with its date another day (2026-12-05 13:14:27), so that after midnight yesterday's items do not
// read as later today; `minutes`: without the seconds. The page says these again when its day changes (app.js)
function shortTime(when, minutes) {
  const full = dateTimeOf(when);
  if (!full) return localTime(when);
  const t = full.slice(0, minutes ? 16 : 19);
  return full.slice(0, 10) === dateTimeOf(Date.now()).slice(0, 10) ? t.slice(11) : t;
}

const DAY = 86400;  // s
// s east of UTC of the page's clock at time t (s since the epoch): its zone's offset then (a half hour's too)
function zoneOffset(t) { return -60 * new Date(t * 1000).getTimezoneOffset(); }
// local clock ticks every 10, 15, 30 s, 1, 2, 5, 10, 15, 30 min or 1, 2, 6, 12 h over [t0, t1] (s since the
// epoch), at most 6, on round times of the page's clock (not of UTC: 14:00, not 14:30, in a zone half an hour
// off); over longer windows (a long run's whole view) every 1, 2, 7, 14, 28... days at local midnight, at most
// 4 (a date is wider than a time). A tick at local midnight is labelled with its date (2026-12-06): a chart
// over more than a day names the days, not the same "00:00" twice
function timeTicks(t0, t1) {
  const steps = [10, 15, 30, 60, 120, 300, 600, 900, 1800, 3600, 7200, 21600, 43200];
  const span = t1 - t0, days = [1, 2, 7, 14].map(n => n * DAY).find(s => span / s <= 4);
  const step = steps.find(s => span / s <= 6) || days || 28 * DAY * Math.ceil(span / (4 * 28 * DAY));
  const out = [], shift = zoneOffset(t0);
  for (let local = Math.ceil((t0 + shift) / step) * step; ; local += step) {
    const t = local - zoneOffset(local - shift);  // back to the epoch (the offset of a summer time begun since)
    if (t > t1) break;
    if (t >= t0) out.push([(t - t0) / (t1 - t0), local % DAY === 0 ? dateTimeOf(t * 1000).slice(0, 10) : clockText(t, step < 60)]);
  }
  return out;
}

// s: the longest time between two samples drawn joined: 3 times the usual step (the median; 1 s, or
// the run view's step), at least 5 s. A longer silence (no run, the broker link down) is left blank.
function gapAfter(series) {
  const steps = [];
  series.forEach(s => s.points.forEach(([t], i) => { if (i) steps.push(t - s.points[i - 1][0]); }));
  steps.sort((a, b) => a - b);
  return Math.max(5, 3 * (steps.length ? steps[steps.length >> 1] : 1));
}

// series: [{name, points: [[t, v], ...], line}], the k-th drawn in COLOURS[line] and DASHES[line] (line: its place
// among the chart's lines, so that each keeps its look while another has no samples; k when not given), band
// [lo, hi] or null (shaded), window [t0, t1] (s)
function drawTrend(canvas, series, band, win) {
  fitWidth(canvas);
  const ctx = canvas.getContext("2d"), w = canvas.width, h = canvas.height, m = MARGIN;
  let lo = Infinity, hi = -Infinity, n = 0;
  series.forEach(s => s.points.forEach(([, v]) => { if (v !== null) { lo = Math.min(lo, v); hi = Math.max(hi, v); n++; } }));
  if (band) { lo = Math.min(lo, band[0]); hi = Math.max(hi, band[1]); }
  const y = niceTicks(lo, hi, 4), [t0, t1] = win;
  frame(ctx, w, h, y, timeTicks(t0, t1));
  const px = t => m.l + (w - m.l - m.r) * (t - t0) / Math.max(1e-9, t1 - t0);
  const py = v => h - m.b - (h - m.t - m.b) * (v - y.lo) / (y.hi - y.lo);
  if (band) {
    ctx.fillStyle = "rgba(46,125,50,0.10)"; ctx.fillRect(m.l, py(band[1]), w - m.l - m.r, py(band[0]) - py(band[1]));
    ctx.strokeStyle = "rgba(46,125,50,0.6)"; ctx.setLineDash([3, 3]);
    [band[0], band[1]].forEach(v => { ctx.beginPath(); ctx.moveTo(m.l, py(v)); ctx.lineTo(w - m.r, py(v)); ctx.stroke(); });
  }
  const gap = gapAfter(series), pieces = [], {colour, dash} = looks(series);
  series.forEach((s, k) => {
    ctx.strokeStyle = colour(k); ctx.lineWidth = 1.5; ctx.setLineDash(dash(k));
    ctx.beginPath();
    let pen = false, last = null, drawn = 0;
    s.points.forEach(([t, v]) => {
      if (v === null || t < t0) { pen = false; return; }
      if (pen && t - last[0] > gap) pen = false;  // no samples in between (no run, no link): no line across
      if (!pen) drawn++;
      pen ? ctx.lineTo(px(t), py(v)) : ctx.moveTo(px(t), py(v)); pen = true; last = [t, v];
    });
    ctx.stroke();
    pieces.push(drawn);
    if (last) { ctx.fillStyle = colour(k); ctx.beginPath(); ctx.arc(px(last[0]), py(last[1]), 2.5, 0, 2 * Math.PI); ctx.fill(); }
  });
  ctx.setLineDash([]);
  legend(ctx, series.map(s => s.name), series.map((s, k) => colour(k)), series.map((s, k) => dash(k)));
  mark(canvas, n, y);
  canvas.dataset.pieces = pieces.join(",");
  markLines(canvas, series, dash);
  canvas.dataset.until = String(t1);  // the window's end (s since the epoch)
  canvas.dataset.band = band ? band.join(",") : "";
}

window.orbitPlots = {drawTraces, drawOrbit, drawTrend, clearChart, niceTicks, fmtTick, clockOf, dateTimeOf, localTime, shortTime, timeTicks};
