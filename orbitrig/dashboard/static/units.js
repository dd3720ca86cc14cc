// The page's units at the edges, one owner as rigunits is Python's: SI comes in the feed, the page
// shows durations, speeds, temperatures, pressures, flow, lengths and the coefficients as the operator reads them.
// tests/dashboard/test_dashboard_units.py holds formatDuration, displayUnit and rpmText equal to
// rigunits.format_duration, rigunits.display_unit and rigunits.rpm_text.
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

// a speed `rpm` as the terminal says it (rigunits.rpm_text): the shortest decimal of its 6 significant
// digits ("1000 rpm", "999.9 rpm", "977.778 rpm"), `signed` (an orbit's whirl) "+569 rpm"; 0 is "0 rpm"
// ("+0 rpm"), never "-0"; "—" alone when there is none
function rpmText(rpm, signed) {
  const number = rpmNumber(rpm, signed);
  return number === "—" ? number : number + " rpm";
}

// the number of rpmText alone ("1000", "999.9"): a table whose head states the unit
function rpmNumber(rpm, signed) {
  if (rpm === null || rpm === undefined || !isFinite(rpm)) return "—";
  const v = Number(Number(rpm).toPrecision(6)) + 0, a = Math.abs(v);
  let text = String(v);
  if (a && (a < 1e-4 || a >= 1e6)) {  // Python's %g: an exponent of two digits at least
    const [m, e] = v.toExponential().split("e");
    text = m + "e" + e[0] + e.slice(1).padStart(2, "0");
  }
  return (signed && v >= 0 ? "+" : "") + text;
}
