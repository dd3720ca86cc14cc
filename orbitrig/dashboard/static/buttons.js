// The run's state badge and which of Start, Pause and Resume apply in the state shown
// (docs/dashboard.md: Commands, STOP and ABORT). Stop and ABORT are never disabled: the service
// always takes them (with no run they stop the drives). Loaded after words.js, before app.js.
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

  // why a command cannot apply in status `s`, or "" when it may (the service decides); `pauseAsked`: a pause
  // accepted and not yet reached is known (the resume withdraws it)
  function why(cmd, s, pauseAsked) {
    const state = s.state, sus = suspended(s);
    const noRun = state === RunState.IDLE || state === RunState.FAULTED;
    if (cmd === Command.START) return noRun ? "" : "a run is under way (" + state + "): stop or abort it before starting another";
    if (noRun) return "no run is under way (" + state + ")";
    if (state === RunState.STOPPING) return "the run is stopping";
    if (cmd === Command.PAUSE) return state !== RunState.PAUSED || sus ? "" : "the run is paused: resume to go on";
    if (pauseAsked || (state === RunState.PAUSED && !sus)) return "";
    return sus ? "suspended by interlock: the run resumes by itself when that clears" : "the run is not paused";
  }

  // Start, Pause and Resume enabled or disabled (the reason in the tooltip); all enabled while the page does
  // not know the rig's state (no status, the service offline, the broker link down): the service decides
  function apply(s, known, pauseAsked) {
    [["btn-start", Command.START], ["btn-pause", Command.PAUSE], ["btn-resume", Command.RESUME]].forEach(([id, cmd]) => {
      const reason = known && s ? why(cmd, s, pauseAsked) : "", b = document.getElementById(id);
      b.disabled = !!reason;
      b.title = reason ? "not now: " + reason : "";
    });
  }

  return {suspended, show, apply};
})();
