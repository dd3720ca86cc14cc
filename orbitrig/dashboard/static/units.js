// The page's units at the edges, one owner as rigunits is Python's: SI comes in the feed, the page
// shows durations, temperatures, pressures and flow as the operator reads them.
// tests/dashboard/test_dashboard_units.py holds formatDuration equal to rigunits.format_duration.
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

// the shown unit of an SI value (K, Pa, m^3/s): v in SI -> v in that unit; a unit not here is SI itself
const SHOWN_IN = Object.freeze({"°C": v => v - 273.15, "MPa": v => v / 1e6, "l/min": v => v * 6e4});

// SI value `v` in the shown `unit` (null stays null)
function inShownUnit(v, unit) {
  if (v === null || v === undefined) return null;
  return unit in SHOWN_IN ? SHOWN_IN[unit](v) : v;
}
