// The page's units at the edges, one owner as rigunits is Python's: SI comes in the feed, the page
// shows durations, temperatures, pressures, flow, lengths and the coefficients as the operator reads them.
// tests/dashboard/test_dashboard_units.py holds formatDuration and displayUnit equal to
// rigunits.format_duration and rigunits.display_unit.
// Loaded before the scripts that use it.
"use strict";

// a duration (s) as the terminal says it (rigunits.format_duration): m:ss under an hour, h:mm:ss
// from an hour on, rounded to the second as Python rounds, a half to the even second ("4:10",
// "1:06:40"; 0.5 s -> "0:00", 1.5 s -> "0:02")
function formatDuration(s) {
  const near = Math.round(s), whole = Math.abs(s % 1) === 0.5 && near % 2 ? near - 1 : near, h = Math.floor(whole / 3600), m = Math.floor(whole % 3600 / 60), sec = whole % 60;
  const two = n => (n < 10 ? "0" : "") + n;
  return h ? h + ":" + two(m) + ":" + two(sec) : m + ":" + two(sec);
}

// the shown unit of an SI value (K, Pa, m^3/s, m): v in SI -> v in that unit; a unit not here is SI itself
// (µm: rigunits.MICROMETRE, an orbit radius, a displacement)
const SHOWN_IN = Object.freeze({"°C": v => v - 273.15, "MPa": v => v / 1e6, "l/min": v => v * 6e4, "µm": v => v * 1e6});

// SI value `v` in the shown `unit` (null stays null)
function inShownUnit(v, unit) {
  if (v === null || v === undefined) return null;
  return unit in SHOWN_IN ? SHOWN_IN[unit](v) : v;
}

// the unit a person reads each matrix in and its scale, SI value x scale (rigunits.DISPLAY_UNITS):
// as the terminal's tables (identify, reduce, the sweep's closing table) and the report show them
const DISPLAY_UNITS = Object.freeze({K: ["MN/m", 1e-6], C: ["kN s/m", 1e-3], D: ["kg", 1]});

// [unit, scale] of coefficient `key` (rigunits.display_unit): "Kxx" -> ["MN/m", 1e-6]; the term of
// order r ("Kxx_2") multiplies Omega^r: ["MN/m (rad/s)^-2", 1e-6]; null for a key of no matrix
function displayUnit(key) {
  const shown = DISPLAY_UNITS[key[0]];
  if (!shown) return null;
  const order = key.split("_")[1];
  return [order ? shown[0] + " (rad/s)^-" + order : shown[0], shown[1]];
}
