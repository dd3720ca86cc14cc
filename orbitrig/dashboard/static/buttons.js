// The run's state badge (docs/dashboard.md: Run state and message). Loaded after words.js, before app.js.
"use strict";

const stateBadge = (() => {
  // an interlock's suspension (orbitrig.run.control: a `paused` status saying "suspended by interlock: ...")
  function suspended(s) { return !!s && s.state === RunState.PAUSED && (s.message || "").startsWith(StatusSaid.SUSPENDED); }

  // the badge says which pause holds the run: "suspended: interlock" in the alarm colour, or the state
  function show(el, s) {
    const sus = suspended(s);
    el.textContent = sus ? "suspended: interlock" : s.state;
    el.className = "state s-" + (sus ? "suspended" : s.state);
  }

  return {suspended, show};
})();
