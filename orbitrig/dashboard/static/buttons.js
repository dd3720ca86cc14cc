// The run's state badge and which of Start, Pause and Resume apply in the state shown
// (docs/dashboard.md: Commands, STOP and ABORT). Stop and ABORT are never disabled: the service
// always takes them (with no run they stop the drives). Loaded after words.js, before app.js.
"use strict";

const stateBadge = (() => {
  // an interlock's suspension (orbitrig.run.control: a `paused` status saying "suspended by interlock: ...")
  function suspended(s) { return !!s && s.state === RunState.PAUSED && (s.message || "").startsWith(StatusSaid.SUSPENDED); }

  // a pause asked of a waiting or suspended run and not reached yet, as its status says it (orbitrig.run.control's
  // held_words: "...; pause requested by ada: the run pauses once manual:0000 is confirmed", "...; pause requested
  // by ada: the run stays paused once the interlock clears"): null, or who asked ("" when not named)
  const PAUSE_ASKED = new RegExp(StatusSaid.PAUSE_REQUESTED + "(?: by (.+?))?: the run (?:pauses|stays paused)");
  function pauseRequested(s) {
    const said = s.state === RunState.WAITING || suspended(s) ? PAUSE_ASKED.exec(s.message || "") : null;
    return said ? said[1] || "" : null;
  }

  // `message` of status `s` without the pause pending it says (a waiting or suspended status's own words)
  function ownWords(s, message) { return pauseRequested(s) !== null ? message.split(StatusSaid.PAUSE_REQUESTED)[0] : message; }

  // how the last run ended and when, with no run under way: the run's closing status (`idle`, its message
  // `run <outcome>...`, or `faulted`: it failed) at its `since`, else the ready status's last_run as the store
  // recorded it (a service restarted since); null when neither says (a run still recorded as running)
  function lastEnd(s) {
    if (s.state === RunState.FAULTED) return s.run_id ? [Outcome.FAILED, s.since] : null;
    if (s.state !== RunState.IDLE) return null;
    if (s.run_id) {
      const said = /^run (\w+)/.exec(s.message || ""), outcome = said && Object.values(Outcome).includes(said[1]);
      return [outcome ? said[1] : "ended", s.since];
    }
    const last = s.last_run;
    return last && last.ended_at ? [last.outcome === StoredStatus.UNKNOWN ? "ended" : last.outcome, last.ended_at] : null;
  }

  // a time on the badge: 12:03 today (the page's local time), 2026-12-05 12:03 another day
  function whenText(iso) { return orbitPlots.dateTimeOf(iso) ? orbitPlots.shortTime(iso, true) : ""; }

  // the badge says which pause holds the run: "suspended: interlock" in the alarm colour, or the state; with
  // no run under way, how the last one ended and when ("idle — last run completed 12:03"); a pause asked of a
  // waiting or suspended run and not reached yet, and whoever asked it (another page, the terminal): "waiting —
  // pause requested by ada", "suspended: interlock — pause requested by ada"
  // the words of status `s`'s state, the badge's and the header's rig selector's: "suspended: interlock" for an
  // interlock's suspension, LINK_LOST while `unknown` (an offline whose truth is not known: app.js offlineUnknown),
  // else the state ("paused", "running", ...)
  function word(s, unknown) { return unknown ? LINK_LOST : suspended(s) ? "suspended: interlock" : s.state; }

  // `unknown`: why the service's state is not known although `s` says offline (app.js offlineUnknown): the badge
  // says LINK_LOST in orange, not "offline" (the service gone), the reason in its tooltip
  function show(el, s, unknown) {
    const sus = suspended(s), end = lastEnd(s), asked = pauseRequested(s);
    el.textContent = word(s, unknown);
    el.className = "state s-" + (unknown ? "unknown" : sus ? "suspended" : s.state);
    el.title = unknown || (end ? "the last run " + end[0] + " at " + orbitPlots.localTime(end[1]) : "");
    if (unknown) return;
    const said = end ? " — last run " + end[0] + (whenText(end[1]) ? " " + whenText(end[1]) : "")
      : asked !== null ? " — pause requested" + (asked ? " by " + asked : "") : "";
    if (!said) return;
    const after = document.createElement("span");
    after.className = "state-end";
    after.textContent = said;
    el.appendChild(after);
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

  // why the dashboard server sends none of Start, Pause and Resume now, in its refusals' words (Refusal:
  // orbitrig.dashboard.commands.NOT_SENT_OFFLINE, and NO_BROKER with no broker link); UNKNOWN: the same offline while
  // the page does not know it true (app.js offlineUnknown), in the badge's words; CONNECTING: the page has not
  // heard yet whether the dashboard's broker link is up (its feed's first message says it)
  const NotSent = Object.freeze({OFFLINE: Refusal.SERVICE_OFFLINE + ": the dashboard sends it only STOP and ABORT",
    UNKNOWN: SERVICE_LINK_LOST + ": the dashboard sends it only STOP and ABORT",
    NO_BROKER: "the dashboard has " + Refusal.NO_BROKER,
    CONNECTING: "the dashboard's link to the broker is not up yet (connecting): try again when it is online"});

  // Start, Pause and Resume enabled or disabled (the reason in the tooltip): all disabled while the dashboard
  // server would not send them (`notSent`: why, NotSent), all enabled while the page does not know the rig's
  // state otherwise (`known` false: no status yet, the view stale): the service decides
  function apply(s, known, pauseAsked, notSent) {
    [["btn-start", Command.START], ["btn-pause", Command.PAUSE], ["btn-resume", Command.RESUME]].forEach(([id, cmd]) => {
      const reason = notSent || (known && s ? why(cmd, s, pauseAsked) : ""), b = document.getElementById(id);
      b.disabled = !!reason;
      b.title = reason ? "not now: " + reason : "";
    });
  }

  return {suspended, pauseRequested, ownWords, word, show, apply, NotSent};
})();
