// The results table: one row per identified coefficient with its value, its expanded uncertainty
// U (k = 2, as the service publishes it: expanded_uncertainty) and its SI unit; a refused fit is
// one row with the reason. At most MAX_RESULT_ROWS rows are kept (the oldest go first).
"use strict";

const MAX_RESULT_ROWS = 2000;

function fmtValue(v) {
  if (v === null || v === undefined || !isFinite(v)) return "—";
  const a = Math.abs(v);
  return a !== 0 && (a >= 1e4 || a < 1e-2) ? Number(v).toExponential(3) : Number(v).toPrecision(4);
}

// a result's `index` is 0-based (the run files' PPPP); the page counts points 1-based, as the progress does
function pointIndex(r) { return Number.isInteger(r.index) ? r.index : Number.isInteger(r.point) ? r.point : null; }
function pointText(r) { const i = pointIndex(r); return i === null ? "?" : String(i + 1); }
function pointFile(r) { const i = pointIndex(r); return i === null ? "" : "file point " + String(i).padStart(4, "0"); }

function fitRows(r, row) {
  const head = [{text: pointText(r) + (r.label ? " " + r.label : ""), title: pointFile(r)}, row.lms || "",
    (row.model || "") + (row.freq_dep && row.freq_dep !== "none" ? " " + row.freq_dep : "")];
  if (row.error) return [[...head, {text: "refused: " + row.error, cls: "out", span: 4}]];
  const c = row.coefficients || {}, eu = row.expanded_uncertainty || {}, U = eu.values || {};
  const units = row.units || {}, loose = new Set(row.not_determined || []);
  return Object.keys(c).map((k, i) => [...(i ? ["", "", ""] : head), {text: k},
    {text: fmtValue(c[k]), cls: loose.has(k) ? "out" : ""},
    {text: fmtValue(U[k]), title: eu.basis ? "k = " + eu.k + ", " + eu.basis : ""}, {text: units[k] || ""}]);
}

function showResult(r) {
  const body = document.getElementById("results");
  (r.warnings || []).forEach(w => addEvent("warn", "point " + pointText(r) + ": " + w));
  (r.identification || []).forEach(row => {
    const what = (row.lms || "") + " " + (row.model || "");
    if (row.error) addEvent("warn", "point " + pointText(r) + " " + what + ": " + row.error);
    (row.warnings || []).forEach(w => addEvent("warn", "point " + pointText(r) + " " + what + ": " + w));
    fitRows(r, row).forEach((cells, i) => {
      const tr = document.createElement("tr");
      if (i === 0) tr.className = "fit-first";
      cells.forEach(x => {
        const td = cell(tr, typeof x === "string" ? x : x.text, typeof x === "string" ? "" : x.cls);
        if (x.span) td.colSpan = x.span;
        if (x.title) td.title = x.title;
      });
      body.appendChild(tr);
    });
  });
  while (body.children.length > MAX_RESULT_ROWS) body.removeChild(body.firstChild);
}

window.resultTable = {showResult};
