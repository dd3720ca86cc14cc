// The results table: one row per identified coefficient (named as the report names it, K<sub>xx</sub>:
// the server's typesetting, typeset.js) with its value, its expanded uncertainty
// U (its k in the cell's title: k_values, as the service publishes it: expanded_uncertainty) and its unit, MN/m, kN s/m or kg as
// the terminal shows them (displayUnit; the result's SI unit for a key of no matrix); a refused fit is
// one row with the reason. At most MAX_RESULT_ROWS rows are kept: the oldest points go first, each
// whole, and a row at the top says which points are no longer shown.
// Each point's result is shown once (a feed that starts again replaces the table: clearResults).
// The run of the rows: in the card's heading while the table holds one run; from a second run on,
// each run's rows are under a row naming it. A broker link gap whose results may be missing is a
// row of its own, where it happened.
"use strict";

const MAX_RESULT_ROWS = 2000;
// a coefficient not determined says so after its value, as the terminal's table and the report
// ("15.00 n.d.", not in red alone); the cell's tooltip says what it means (orbitrig.cli.sweep_summary.ND_NOTE)
const ND_MARK = " n.d.", ND_NOTE = "n.d. = not determined: the expanded uncertainty U exceeds the magnitude";
// what the table holds: the results shown (resultKey), the run of the latest, whether runs are marked
// and the points trimmed off the table (run -> {from, to, n}, point numbers as shown)
const shownResults = {keys: new Set(), lastRun: null, marked: false, trimmed: new Map()};

function fmtValue(v) {
  if (v === null || v === undefined || !isFinite(v)) return "—";
  const a = Math.abs(v);
  return a !== 0 && (a >= 1e4 || a < 1e-2) ? Number(v).toExponential(3) : Number(v).toPrecision(4);
}

// `v` rounded to `d` decimals (d < 0: to tens, hundreds) as Python's round and format do
// (orbitrig.analysis.rounding.at_decimals): on the double's exact decimal digits, an exact half to
// the even digit (toFixed and Math.round take it up: 1234.5 -> 1235, Python 1234); never "-0.00"
function atDecimals(v, d) {
  const [whole, frac] = Math.abs(v).toFixed(100).split("."), digits = whole + frac, keep = whole.length + d;
  const head = keep > 0 ? digits.slice(0, keep) : "0", rest = keep > 0 ? digits.slice(keep) : "0".repeat(-keep) + digits;
  const up = rest[0] > "5" || (rest[0] === "5" && (/[1-9]/.test(rest.slice(1)) || Number(head.slice(-1)) % 2 === 1));
  const n = (BigInt(head) + (up ? 1n : 0n)).toString().padStart(Math.max(d, 0) + 1, "0");
  const t = d > 0 ? n.slice(0, -d) + "." + n.slice(-d) : n + "0".repeat(n === "0" ? 0 : -d);
  return v < 0 && /[1-9]/.test(t) ? "-" + t : t;
}

// the decimal an uncertainty rounded to 2 significant digits ends at (0.8667 -> 2: 0.87; 0.0996 -> 2: 0.10;
// 31 -> 0), as the report and `orbitrig reduce` round (orbitrig.analysis.rounding.uncertainty_decimals);
// null where it is no usable uncertainty or its decimal is far from the table's (the 4 significant digits stay)
function uncertaintyDecimals(u) {
  if (u === null || u === undefined || !isFinite(u) || u <= 0) return null;
  const first = 1 - Math.floor(Math.log10(u)), d = 1 - Math.floor(Math.log10(Number(atDecimals(u, first))));
  return d >= -3 && d <= 6 ? d : null;
}

// a coefficient and its U (display unit) as the table writes them: U to 2 significant digits and the value to
// its decimal ("33.79", "0.87"; "-19", "30"), else each to 4 significant digits (fmtValue)
function valueAndU(v, u) {
  const d = isFinite(v) && v !== null && Math.abs(v) < 1e21 ? uncertaintyDecimals(u) : null;  // toFixed's range
  return d === null ? [fmtValue(v), fmtValue(u)] : [atDecimals(v, d), atDecimals(u, d)];
}

// a result's `index` is 0-based (the run files' PPPP); the page counts points 1-based, as the progress does
function pointIndex(r) { return Number.isInteger(r.index) ? r.index : Number.isInteger(r.point) ? r.point : null; }
function pointText(r) { const i = pointIndex(r); return i === null ? "?" : String(i + 1); }
// the run files' name of the point, as the service names it (`point_name`: orbitrig.store.layout.point_name)
function pointFile(r) { return typeof r.point_name === "string" ? "file point " + r.point_name : ""; }
// one point's result: its run, point and fits (the broker may hand a result on again after a reconnection)
function resultKey(r) {
  const fits = (r.identification || []).map(row => [row.lms, row.model, row.freq_dep, row.method].join(" "));
  return [r.run_id, pointIndex(r), r.label, ...fits].join("|");
}

// `entries`: each coefficient key -> its name as the report writes it (K<sub>xx</sub>), made by the server
// (orbitrig.dashboard.lifted; the feed's result message), shown through typesetInto
function fitRows(r, row, entries) {
  const head = [{text: pointText(r) + (r.label ? " " + r.label : ""), title: pointFile(r)}, row.lms || "",
    (row.model || "") + (row.freq_dep && row.freq_dep !== "none" ? " " + row.freq_dep : "")];
  if (row.error) return [[...head, {text: "refused: " + row.error, cls: "out", span: 4}]];
  const c = row.coefficients || {}, eu = row.expanded_uncertainty || {}, U = eu.values || {};
  const units = row.units || {}, loose = new Set(row.not_determined || []);
  return Object.keys(c).map((k, i) => {
    const [unit, scale] = displayUnit(k) || [units[k] || "", 1], inUnit = v => v === null || v === undefined ? v : v * scale;
    const [value, u] = valueAndU(inUnit(c[k]), inUnit(U[k]));
    return [...(i ? ["", "", ""] : head), {text: k, html: entries[k]}, loose.has(k) ? {text: value + ND_MARK, cls: "out", title: ND_NOTE} : {text: value},
      {text: u, title: eu.basis ? "k = " + Number((eu.k_values || {})[k] ?? eu.k).toPrecision(3) + ", " + eu.basis : ""}, {text: unit}];
  });
}

// a row across the table (a run's name, a gap)
function wideRow(cls, text) {
  const tr = document.createElement("tr"); tr.className = cls;
  cell(tr, text).colSpan = 7;
  return tr;
}

function runRow(run) { const tr = wideRow("run-row", run ? "run " + run : "run not named"); tr.dataset.run = run; return tr; }

function showRuns() {  // and, while the table is empty, that it holds only what came since the sign-in
  document.getElementById("results-empty").hidden = document.getElementById("results").children.length > 0;
  document.getElementById("results-run").textContent = shownResults.lastRun !== null && !shownResults.marked ? "run " + (shownResults.lastRun || "not named") : "";
}

// the rows of a run other than the latest's come under a row naming their run (the first run's too)
function markRun(body, run) {
  if (shownResults.lastRun !== null && run !== shownResults.lastRun) {
    if (!shownResults.marked) body.insertBefore(runRow(shownResults.lastRun), body.firstChild);
    shownResults.marked = true;
    body.appendChild(runRow(run));
  }
  shownResults.lastRun = run;
  showRuns();
}

// a fit's warnings once each: the row's own; of the result's `warnings` (every fit's, prefixed by its fit)
// only those no row says. Each is listed once also when the feed hands the result on again (its key).
// `texts`: each message -> its HTML, typeset by the server (the feed's result message)
// `at`: when the dashboard server got the result (its warnings are listed at that time, also after a reload)
function resultWarnings(r, texts, at) {
  const said = [], point = "point " + pointText(r), warn = (text, what) => {
    const key = ["result", r.run_id, pointIndex(r), what, text].join("|");
    addEvent("warn", [point + what + ": ", lifted(text, texts)], false, at, key);
    fitWarning(r.run_id, key);  // counted on the Run card
  };
  (r.identification || []).forEach(row => {
    const what = " " + (row.lms || "") + " " + (row.model || "");
    if (row.error) warn(row.error, what);
    (row.warnings || []).forEach(w => { said.push(w); warn(w, what); });
  });
  (r.warnings || []).filter(w => !said.some(s => w === s || w.endsWith(": " + s))).forEach(w => warn(w, ""));
}

// The results box follows the newest result (its first row, or its run's row, under the box's column heads) while
// the person has not scrolled it elsewhere: at a run's end its results are in view, not the shift's first run's.
// Scrolled by hand it stays until scrolled back to its end. `at`: where it was last brought (px).
const resultsView = {at: 0};

function resultsBox() { return document.getElementById("results").closest(".scroll"); }

// whether the box is where it was last brought, or at its end: read before a result's rows go in
function following() {
  const box = resultsBox();
  return Math.abs(box.scrollTop - resultsView.at) < 2 || box.scrollTop + box.clientHeight >= box.scrollHeight - 2;
}

function followNewest(row) {
  const box = resultsBox();
  if (!row.isConnected) return;
  const head = box.querySelector("thead").getBoundingClientRect().height;
  box.scrollTop += row.getBoundingClientRect().top - box.getBoundingClientRect().top - head;
  resultsView.at = box.scrollTop;
}

function showResult(r, entries, texts, at) {
  const body = document.getElementById("results"), key = resultKey(r);
  if (shownResults.keys.has(key)) return;
  shownResults.keys.add(key);
  const run = r.run_id || "", last = body.lastElementChild, follow = following();
  markRun(body, run);
  resultWarnings(r, texts, at);
  (r.identification || []).forEach(row => {
    fitRows(r, row, entries || {}).forEach((cells, i) => {
      const tr = document.createElement("tr");
      if (i === 0) tr.className = "fit-first";
      tr.dataset.run = run; tr.dataset.point = key; tr.dataset.num = pointText(r);
      cells.forEach(x => {
        const td = x.html !== undefined ? typesetInto(cell(tr, ""), x.html, x.text)
          : cell(tr, typeof x === "string" ? x : x.text, typeof x === "string" ? "" : x.cls);
        if (x.span) td.colSpan = x.span;
        if (x.title) td.title = x.title;
      });
      body.appendChild(tr);
    });
  });
  const first = last ? last.nextElementSibling : body.firstElementChild;
  trimResults(body);
  showRuns();
  if (first && follow) followNewest(first);
}

// the oldest points go, each with all its rows (two rows are kept for the trim row and the oldest run's name)
function trimResults(body) {
  const said = body.querySelector("tr.trim-row");
  if (said) body.removeChild(said);
  while (body.children.length > MAX_RESULT_ROWS - 2) {
    const first = body.firstElementChild, point = first.dataset.point;
    if (point !== undefined) trimmedPoint(first);
    do body.removeChild(body.firstElementChild);
    while (point !== undefined && body.firstElementChild && body.firstElementChild.dataset.point === point);
  }
  const first = body.firstElementChild;  // the oldest run kept keeps its name
  if (shownResults.marked && first && first.className !== "run-row" && first.dataset.run !== undefined) body.insertBefore(runRow(first.dataset.run), first);
  if (shownResults.trimmed.size) body.insertBefore(trimRow(), body.firstChild);
}

function trimmedPoint(tr) {
  const run = tr.dataset.run || "", num = Number(tr.dataset.num) || 0, t = shownResults.trimmed.get(run);
  if (!t) shownResults.trimmed.set(run, {from: num, to: num, n: 1});
  else Object.assign(t, {from: Math.min(t.from, num), to: Math.max(t.to, num), n: t.n + 1});
}

function trimRow() {
  const parts = [...shownResults.trimmed].map(([run, t]) => (run ? "run " + run + ": " : "") +
    (t.n === 1 ? "point " + t.from : "points " + t.from + " to " + t.to + " (" + t.n + " points)"));
  return wideRow("trim-row", "not shown (the table keeps the latest " + MAX_RESULT_ROWS + " rows): " + parts.join("; "));
}

// what a gap row says, its times as the events say them (orbitPlots.shortTime: dated another day)
function gapWords(from, to) {
  return "results published between " + orbitPlots.shortTime(from) + " and " + orbitPlots.shortTime(to)
    + " may be missing: the dashboard's broker link was down and the broker did not keep them";
}

// the broker link was down from gap.from to gap.to and the broker did not keep the session's messages
function resultsGap(gap) {
  const body = document.getElementById("results");
  const tr = wideRow("gap-row", gapWords(gap.from, gap.to));
  tr.dataset.gap = gap.from; tr.dataset.to = gap.to;
  body.appendChild(tr);
  trimResults(body);
  showRuns();
}

// the gap rows said again (the page's day has changed: app.js redate), so that yesterday's carry their date
function redateGaps() {
  document.querySelectorAll("#results tr.gap-row").forEach(tr => { tr.firstChild.textContent = gapWords(tr.dataset.gap, tr.dataset.to); });
}

function clearResults() {
  clear(document.getElementById("results"));
  Object.assign(shownResults, {keys: new Set(), lastRun: null, marked: false, trimmed: new Map()});
  resultsView.at = 0;
  showRuns();
}

window.resultTable = {showResult, showGap: resultsGap, redateGaps, clearResults};
