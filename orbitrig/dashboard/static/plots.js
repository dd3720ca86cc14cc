// Small canvas plots of the averaged revolution (no library: the rig PC is offline).
"use strict";

const COLOURS = ["#1976d2", "#c62828", "#2e7d32", "#ef6c00", "#6a1b9a", "#00838f", "#5d4037", "#ad1457"];

function niceRange(lo, hi) {
  if (!isFinite(lo) || !isFinite(hi)) return [-1, 1];
  if (hi - lo < 1e-12 * Math.max(1, Math.abs(hi))) { const d = Math.abs(hi) * 0.1 || 1; return [lo - d, hi + d]; }
  const pad = (hi - lo) * 0.08;
  return [lo - pad, hi + pad];
}

function fmtTick(v) {
  const a = Math.abs(v);
  return a === 0 ? "0" : (a >= 1e4 || a < 1e-2) ? v.toExponential(1) : v.toPrecision(3);
}

function frame(ctx, w, h, m, ylo, yhi, xlabels) {
  ctx.clearRect(0, 0, w, h);
  ctx.strokeStyle = "#cfd8dc"; ctx.fillStyle = "#546e7a"; ctx.font = "10px sans-serif";
  ctx.strokeRect(m.l, m.t, w - m.l - m.r, h - m.t - m.b);
  for (let i = 0; i <= 4; i++) {
    const v = ylo + (yhi - ylo) * i / 4, y = h - m.b - (h - m.t - m.b) * i / 4;
    ctx.beginPath(); ctx.moveTo(m.l, y); ctx.lineTo(w - m.r, y); ctx.stroke();
    ctx.fillText(fmtTick(v), 2, y + 3);
  }
  xlabels.forEach(([frac, text]) => ctx.fillText(text, m.l + (w - m.l - m.r) * frac - 8, h - 4));
}

// series: [{name, values}], values over one revolution (samples evenly spread over 360 deg)
function drawTraces(canvas, series, scale) {
  const ctx = canvas.getContext("2d"), w = canvas.width, h = canvas.height;
  const m = {l: 44, r: 8, t: 8, b: 18};
  let lo = Infinity, hi = -Infinity;
  series.forEach(s => s.values.forEach(v => { if (v !== null) { lo = Math.min(lo, v * scale); hi = Math.max(hi, v * scale); } }));
  [lo, hi] = niceRange(lo, hi);
  frame(ctx, w, h, m, lo, hi, [[0, "0°"], [0.25, "90°"], [0.5, "180°"], [0.75, "270°"], [1, "360°"]]);
  series.forEach((s, k) => {
    const n = s.values.length;
    ctx.strokeStyle = COLOURS[k % COLOURS.length]; ctx.lineWidth = 1.5; ctx.beginPath();
    s.values.forEach((v, i) => {
      const x = m.l + (w - m.l - m.r) * i / Math.max(1, n), y = h - m.b - (h - m.t - m.b) * (v * scale - lo) / (hi - lo);
      i ? ctx.lineTo(x, y) : ctx.moveTo(x, y);
    });
    ctx.stroke();
    ctx.fillStyle = COLOURS[k % COLOURS.length]; ctx.fillText(s.name, w - m.r - 70, m.t + 12 + 11 * k);
  });
  canvas.dataset.updates = String(Number(canvas.dataset.updates || 0) + 1);
  canvas.dataset.samples = String(series.reduce((a, s) => a + s.values.length, 0));
}

// x, y: displacements over one revolution (m); drawn in um, equal axes, closed curve
function drawOrbit(canvas, x, y) {
  const ctx = canvas.getContext("2d"), w = canvas.width, h = canvas.height;
  const m = {l: 44, r: 8, t: 8, b: 18};
  const xs = x.map(v => v * 1e6), ys = y.map(v => v * 1e6);
  const r = Math.max(1e-3, ...xs.map(Math.abs), ...ys.map(Math.abs)) * 1.1;
  frame(ctx, w, h, m, -r, r, [[0, fmtTick(-r)], [0.5, "0"], [1, fmtTick(r)]]);
  const px = v => m.l + (w - m.l - m.r) * (v + r) / (2 * r), py = v => h - m.b - (h - m.t - m.b) * (v + r) / (2 * r);
  ctx.strokeStyle = "#1976d2"; ctx.lineWidth = 1.8; ctx.beginPath();
  xs.forEach((v, i) => (i ? ctx.lineTo(px(v), py(ys[i])) : ctx.moveTo(px(v), py(ys[i]))));
  ctx.closePath(); ctx.stroke();
  ctx.fillStyle = "#c62828"; ctx.beginPath(); ctx.arc(px(xs[0] || 0), py(ys[0] || 0), 3, 0, 2 * Math.PI); ctx.fill();
  canvas.dataset.updates = String(Number(canvas.dataset.updates || 0) + 1);
  canvas.dataset.samples = String(xs.length);
}

window.orbitPlots = {drawTraces, drawOrbit};
