// The live view: sign-in, the websocket feed from the dashboard server, rendering, commands.
// The password goes once to POST /api/login and is then cleared from the page; nothing is kept
// in the page's storage (the session cookie is HttpOnly).
"use strict";

const $ = id => document.getElementById(id);
// outcomes: the keys of the command outcomes shown (outcomeKey), so that a feed starting again shows none twice
// lastMsg, feedAt: when the feed's latest message came and when it connected, on the page's monotonic clock
// (performance.now(), ms: a wall clock stepped back, an NTP step, leaves a silent feed stale all the same); stale: the view is not the present;
// feedClosed: the feed's websocket closed (the dashboard server gone): stale at once, not after the silence
const st = {ws: null, retry: 0, lastActive: -Infinity, status: null, liveAt: null, replyTimeout: 3, tick: 3, outcomes: new Set(), eventKeys: new Set(),
  lastMsg: 0, feedAt: 0, stale: false, feedClosed: false, bannerText: null, names: {}, fitWarnings: new Map()};
// the server sends something at least every st.tick s (a tick, 3 by default): silent STALE_TICKS ticks (7 s),
// the view is stale; FEED_DEAD_TICKS (12 s), the feed is given up and connected again (a connection that died
// without closing)
const STALE_TICKS = 7 / 3, FEED_DEAD_TICKS = 4;

function fmt(v, digits) { return (v === null || v === undefined || !isFinite(v)) ? "—" : Number(v).toFixed(digits); }
// a value with its unit, or "—" alone when there is none (not "— Hz")
function withUnit(v, digits, unit) { const t = fmt(v, digits); return t === "—" ? t : t + " " + unit; }
function show(el, on) { el.hidden = !on; }
function clear(el) { while (el.firstChild) el.removeChild(el.firstChild); }
function sentence(words) { return words.charAt(0).toUpperCase() + words.slice(1); }  // words begun as a sentence
function cell(tr, text, cls) { const td = document.createElement("td"); td.textContent = text; if (cls) td.className = cls; tr.appendChild(td); return td; }
// a cell's text in pieces that each stay on one line (a narrow card wraps it between them only),
// the last in smaller type when `note`
function pieces(td, parts, note) {
  clear(td);
  parts.forEach((text, i) => {
    if (i) td.appendChild(document.createTextNode(" "));
    const span = document.createElement("span"); span.textContent = text;
    span.className = note && i === parts.length - 1 ? "piece note" : "piece"; td.appendChild(span);
  });
}

// `deadline` (ms): the request is given up after it (the promise rejects with an AbortError)
async function api(path, body, deadline) {
  const opts = body === undefined ? {credentials: "same-origin"} :
    {method: "POST", credentials: "same-origin", headers: {"Content-Type": "application/json"}, body: JSON.stringify(body)};
  if (deadline) opts.signal = AbortSignal.timeout(deadline);
  const r = await fetch(path, opts);
  let data = {};
  try { data = await r.json(); } catch (e) { /* empty */ }
  return {status: r.status, data};
}

// ---------------------------------------------------------------- sign-in
async function signIn(ev) {
  ev.preventDefault();
  const user = $("user").value.trim(), pw = $("password");
  $("signin-error").textContent = "";
  $("signin-btn").disabled = true;
  try {
    const r = await api("/api/login", {user, password: pw.value});
    pw.value = "";
    if (r.status !== 200) { $("signin-error").textContent = r.data.error || ("sign-in failed (" + r.status + ")"); return; }
    enter(r.data);
  } catch (e) {
    pw.value = "";
    $("signin-error").textContent = "dashboard server unreachable";
  } finally { $("signin-btn").disabled = false; }
}

function enter(who) {
  if (who.reply_timeout) st.replyTimeout = who.reply_timeout;
  if (who.tick) st.tick = who.tick;
  $("who").textContent = who.user;
  $("rig").textContent = who.prefix;
  show($("signin"), false); show($("app"), true);
  connect();
}

function leave(reason) {
  if (st.ws) { st.ws.onclose = null; st.ws.close(); st.ws = null; }
  st.lastMsg = 0; st.feedClosed = false; markStale(false);
  // an open modal dialog (the abort confirmation) would stay open unseen and block every click
  document.querySelectorAll("dialog[open]").forEach(d => d.close());
  show($("app"), false); show($("signin"), true);
  resetView();
  $("signin-error").textContent = reason || "";
}

// nothing of the previous person stays: the form, their commands' outcomes and refusals, and
// the rig's view (the next sign-in's feed draws it again from the server's snapshot)
function resetView() {
  $("user").value = ""; $("password").value = "";
  ["events", "matrix-names", "rig-select"].forEach(id => clear($(id)));
  ["cmd-result", "cmd-when", "who", "rig"].forEach(id => { $(id).textContent = ""; });
  // the previous session's broker link is not the next one's: connecting until its feed says
  $("link").textContent = BrokerLink.CONNECTING; $("link").className = "badge";
  st.rigs = {}; st.outcomes = new Set(); st.eventKeys = new Set();
  clearRigView();
}

// the Run card's message while the rig's service has published no status the dashboard has seen (its service
// not started since the broker started, or the page's feed just begun)
const NO_STATUS = "no status from the rig service yet: it has not connected to the broker";

// the view of one rig, emptied when the person leaves or watches another rig
function clearRigView() {
  resultTable.clearResults(); clear($("manual-table")); st.fitWarnings.clear();
  alarmList.showAlarms([]);
  clearRunView();
  ["alarm-result", "run-id", "run-what", "manual-step", "manual-motion"].forEach(id => { $(id).textContent = ""; });
  $("message").textContent = NO_STATUS; $("message").title = "";  // until the rig's first status: a blank card read as a rig with nothing to say
  $("state").textContent = "—"; $("state").className = "state";
  $("matrix").value = "demo"; st.matrixTyped = false;  // until a status names its run's matrix
  Object.assign(st, {status: null, statusLost: false, manual: null, viewRun: undefined, runWarnings: null, pauseAsked: null});
  showButtons();
  $("run-warnings").textContent = "—"; $("run-warnings").className = "";
  show($("manual"), false); show($("manual-none"), true);
  trends.trendClear(); trends.drawTrends();
  document.querySelectorAll("canvas").forEach(c => { orbitPlots.clearChart(c); c.dataset.updates = "0"; });
  banner(null);
}

// the view of one run (progress, ETA, live values, waveforms): emptied when the run ends or
// another run's status comes, so nothing of the previous run is shown as the present one's
function clearRunView() {
  showDrives({}); showAux({}, {});  // every row in place before the first live message: no jump
  ["point", "point-label", "block", "revolutions", "eta", "op-spin", "op-orbit", "op-orbit-hz", "op-direction"].forEach(id => { $(id).textContent = "—"; });
  $("progress-bar").style.width = "0";
  st.liveAt = null; st.etaS = null; $("eta-held").textContent = ""; showLiveAge();
  ["plot-forces", "plot-disp", "plot-orbit"].forEach(id => {
    const c = $(id); orbitPlots.clearChart(c); c.dataset.samples = "0";
  });
}

// a run has ended in these states (offline is not an end: the last values stay, ageing)
function runEnded(s) { return !!s && (s.state === RunState.IDLE || s.state === RunState.FAULTED); }

async function signOut() { await api("/api/logout", {}); leave("signed out"); }

// ---------------------------------------------------------------- feed
function connect() {
  const ws = new WebSocket((location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/api/feed");
  st.ws = ws; st.feedAt = performance.now();
  ws.onopen = () => { st.retry = 0; banner(null); };
  ws.onmessage = ev => { st.lastMsg = performance.now(); st.feedClosed = false; markStale(false); handle(JSON.parse(ev.data)); };
  ws.onclose = () => {
    st.ws = null; st.feedClosed = true; markStale(true);
    banner("offline: dashboard server unreachable — reconnecting"); setTimeout(reconnect, Math.min(5000, 500 * 2 ** st.retry++));
  };
}

async function reconnect() {
  try {
    const r = await api("/api/session", undefined, 4000);
    if (r.status === 401) { leave("session ended: sign in again"); return; }
    if (r.status === 200) { connect(); return; }
  } catch (e) { /* server still away */ }
  setTimeout(reconnect, Math.min(5000, 500 * 2 ** st.retry++));
}

function activity() {
  const now = performance.now();
  if (st.ws && st.ws.readyState === 1 && now - st.lastActive > 10000) { st.lastActive = now; st.ws.send('{"type": "active"}'); }
}

function banner(text) { st.bannerText = text || null; drawBanner(); }

// the stale warning goes before any other: nothing the page shows is known to be the present
function drawBanner() {
  let text = st.bannerText;
  if (st.stale && !st.feedClosed) {  // a closed feed says so itself (its banner)
    const live = st.ws && st.ws.readyState === 1 ? "" : " — reconnecting";
    text = "STALE: no data from the dashboard server for " + Math.round((performance.now() - st.lastMsg) / 1000) + " s" + live +
      " — what this page shows may not be the present";
  }
  $("offline-banner").textContent = text || ""; show($("offline-banner"), !!text);
}

function markStale(on) {
  if (on === st.stale) return;
  st.stale = on; $("app").classList.toggle("stale", on); drawBanner(); showButtons();
}

// every 0.5 s: a feed silent for STALE_TICKS ticks greys the view; silent for FEED_DEAD_TICKS (since its latest message or
// its connection) it is closed and connected again, as a closed one is
function watchFeed() {
  if (!st.lastMsg) return;
  const now = performance.now();
  markStale(st.feedClosed || now - st.lastMsg > 1000 * STALE_TICKS * st.tick);
  if (st.stale) drawBanner();
  if (st.ws && now - Math.max(st.lastMsg, st.feedAt) > 1000 * FEED_DEAD_TICKS * st.tick) {
    const ws = st.ws; st.ws = null;
    ws.onclose = ws.onmessage = null;
    try { ws.close(); } catch (e) { /* already gone */ }
    reconnect();
  }
}

// a feed starts with the session's snapshot (hello first), which replaces what the page showed: the
// results come again (the table is emptied), events and outcomes already listed are not listed twice
function handle(msg) {
  switch (msg.type) {
    case FeedType.HELLO: $("who").textContent = msg.user; $("rig").textContent = msg.prefix; st.replyTimeout = msg.reply_timeout || st.replyTimeout; st.tick = msg.tick || st.tick; showNames(msg.names); resultTable.clearResults(); break;
    case FeedType.RIGS: showRigs(msg.data); break;
    case FeedType.RIG: clearRigView(); $("rig").textContent = msg.prefix; showRigs(st.rigs || {}); break;
    case FeedType.LINK: showLink(msg.link); break;
    case FeedType.STATUS: showStatus(msg.data, msg.texts, !!msg.link_lost); break;
    case FeedType.ENDING: statusEvents(msg.data, msg.texts, null); break;  // how a run ended, kept by the session
    case FeedType.PROGRESS: showProgress(msg.data); break;
    case FeedType.LIVE: showLive(msg.data, msg.age_s); break;
    case FeedType.RESULT: resultTable.showResult(msg.data, msg.entries, msg.texts, msg.at); break;
    case FeedType.NOTE: showNote(msg.data, msg.texts); break;
    case FeedType.GAP: showLinkGap(msg.data); break;
    case FeedType.TREND: trends.trendSample(msg.sample, msg.run_id); break;
    case FeedType.TREND_HISTORY: trends.trendHistory(msg.data); break;
    case FeedType.ALARMS: alarmList.showAlarms(msg.data); break;
    case FeedType.OUTCOMES: msg.data.filter(o => !st.outcomes.has(outcomeKey(o.cmd, o))).forEach(o => showOutcome(o.cmd, o, o.at)); break;
    case FeedType.OUTCOME: showOutcome(msg.data.cmd, msg.data); break;  // a late reply to a stop or abort
    case FeedType.TICK: break;  // the feed is alive (each message counts: watchFeed)
    case FeedType.SIGNED_OUT: leave("session ended: " + msg.reason); break;
  }
  if (msg.non_finite) saidNonFinite(msg.type, msg.non_finite);
}

// a payload that came with NaN or infinity (not JSON: a publisher other than the rig service, or an older one):
// the dashboard server read those fields as null, shown as not known; listed once per kind and fields
function saidNonFinite(kind, fields) {
  const key = ["non_finite", kind, ...fields].join("|");
  addEvent("warn", "the " + kind + " published came with NaN or infinity in " + fields.join(", ")
    + ": shown as not known (the rig service publishes none: another publisher, or an older service)", false, undefined, key);
}

// the rigs on the broker (id -> {state, message, last_will, link_lost} of its latest status: link_lost, the
// dashboard server's reading of it, offlineUnknown) in the header's selector, each state in the badge's words
// (nameRigStates); the one watched selected
function showRigs(rigs) {
  st.rigs = rigs;
  const sel = $("rig-select"), current = ($("rig").textContent || "").split("/").pop();
  clear(sel);
  const ids = Object.keys(rigs);
  if (current && !ids.includes(current)) ids.unshift(current);
  ids.forEach(id => {
    const o = document.createElement("option"); o.value = id; o.selected = id === current;
    sel.appendChild(o);
  });
  nameRigStates();
}

// each rig's state in the selector as the badge says it (stateBadge.word): an offline not known true says
// LINK_LOST, as the badge does, as the dashboard server reads it (offlineUnknown: the watched rig's status; another's
// as listed, its last will told from the service's own offline), the reason in the option's tooltip
function nameRigStates() {
  const rigs = st.rigs || {}, current = ($("rig").textContent || "").split("/").pop();
  [...$("rig-select").options].forEach(o => {
    const s = rigs[o.value];
    const unknown = o.value === current && st.status ? offlineUnknown(st.status) : offlineUnknown(s, !!s && !!s.link_lost);
    o.textContent = o.value + " (" + (s ? stateBadge.word(s, !!unknown) : "no status") + ")";
    o.title = unknown;
  });
}

async function selectRig() {
  activity();
  const r = await api("/api/rig", {rig: $("rig-select").value});
  if (r.status === 401) { leave("session ended: sign in again"); return; }
  if (!r.data.ok) { $("cmd-result").className = "cmd-result refused"; $("cmd-result").textContent = "rig: " + r.data.error; }
}

function showLink(link) {
  const el = $("link");
  el.textContent = link;
  el.className = "badge " + (link === BrokerLink.ONLINE ? "l-online" : "l-broker");
  banner(link !== BrokerLink.ONLINE ? "offline: broker unreachable — reconnecting" : serviceBanner());
  showServiceState();
  nameRigStates();  // the other rigs' too, with no status of the rig watched yet (showServiceState names them then)
  showButtons();
  abortQuestion();
}

// why the rig service's state is not known although its status `s` says offline ("" when it is known): this page's
// own broker link is down (its status is the last heard), or `lost`, the dashboard server's reading sent with the
// status (the watched rig's by default; orbitrig.dashboard.link_lost): the broker's last will (an `offline` with
// `last_will`, docs/protocols/mqtt.md) came with a broker outage the server's session saw, until 10 s after its
// link was back. The broker publishes the will as it stops and keeps it until the service reconnects, while the
// run goes on on the rig: the service's link to the broker was lost, not necessarily the service. The server's
// refusals say it by the same reading, and so does a page loaded at any time
function offlineUnknown(s, lost = st.statusLost) {
  if (!s || s.state !== RunState.OFFLINE) return "";
  if ($("link").textContent === BrokerLink.UNREACHABLE) {
    return "the rig service's state is unknown: the dashboard's link to the broker is down; " + RUN_MAY_GO_ON;
  }
  return s.last_will && lost ? "the rig service's state is unknown: its " + LOST_IN_OUTAGE + " (the broker published its" +
    " last will); " + RUN_MAY_GO_ON + ": its statuses say its state when it reconnects" : "";
}

// the banner the rig service's status makes while the page's own broker link is up
function serviceBanner() {
  const s = st.status;
  if (!s || s.state !== RunState.OFFLINE) return null;
  return offlineUnknown(s) ? "the rig service's " + LOST_IN_OUTAGE + ": its state is unknown until it reconnects"
    : "offline: the rig service is not connected";
}

// the Run card's badge and message of the rig's status: its state and the service's message whole (typeset:
// typesetMessage), or that the service's state is not known (offlineUnknown) with what its status said
function showServiceState() {
  const s = st.status;
  if (!s) return;
  const unknown = offlineUnknown(s), el = $("message");
  stateBadge.show($("state"), s, unknown);
  nameRigStates();
  typesetMessage(el, s.message || "", st.statusTexts);
  if (unknown) el.prepend(unknown + ". Its last status said: ");
  showLastRun(s);
}

// ---------------------------------------------------------------- run state
// `lost`: the dashboard server's reading of an offline `s` (offlineUnknown)
function showStatus(s, texts, lost) {
  const prev = st.status;
  Object.assign(st, {status: s, statusTexts: texts, statusLost: lost});
  showServiceState();
  // an offline status (the broker's last will) names the run of the service's connection, an earlier one or
  // none: the run on view keeps its id and what it runs, as it keeps its point and ETA
  if (s.state !== RunState.OFFLINE || st.viewRun === undefined) {
    $("run-id").textContent = s.run_id || "";
    // what the run runs and for whom (every status of a run started by this service names them)
    $("run-what").textContent = s.matrix ? "matrix " + s.matrix + (s.by ? ", started by " + s.by : "") : "";
    // the matrix field says the matrix of the rig's run (under way, or the latest ended), not demo in a new tab,
    // unless the operator has typed in it since the page showed the rig
    if (s.matrix && !st.matrixTyped) $("matrix").value = s.matrix;
  }
  if ($("link").textContent === BrokerLink.ONLINE) banner(serviceBanner());
  statusEvents(s, texts, prev);
  // an offline status changes no run (its run_id may be the last will's: the run of the service's connection):
  // the view stays, its live values ageing, and goes on when the service is back with the same run
  if (s.state !== RunState.OFFLINE) {
    if (runEnded(s) || s.run_id !== st.viewRun) clearRunView();
    st.viewRun = s.run_id;
  }
  if (s.state === RunState.IDLE && (s.message || "").includes(Outcome.COMPLETED)) $("progress-bar").style.width = "100%";
  // the point the status names (under way, or between points the next one), none in the closing ramp
  if (!runEnded(s) && s.state !== RunState.OFFLINE) showPointLabel(s.point_label, s.between_points);
  if (s.state !== RunState.OFFLINE) runWarnings(s.run_id, (s.notes || {}).said || 0);
  showManual(s);
  showEta();
  followPause(s);
  abortQuestion();  // an open confirmation follows the rig's state
}

// the events status `s` makes (`prev`: the status before it, null when not known): how a run ended, with its
// closing status's grouped fit warnings ("run completed; warning: ...; warning: ...") as events of their own, a
// fault, an interlock's or a lost link's words (a suspension's status said again with a pause pending is listed
// once: its own words). A run's end is listed at its time (the closing status's since), also when a page
// (re)loaded later lists it from the session's kept endings (FeedType.ENDING)
function statusEvents(s, texts, prev) {
  const [all, ...warnings] = (s.message || "").split(StatusSaid.GROUPED_WARNING), said = stateBadge.ownWords(s, all);
  const warn = s.state === RunState.FAULTED || /interlock|not met|failed|lost/i.test(said);
  const key = ["status", s.run_id, s.since, said].join("|"), at = runEnded(s) ? s.since : undefined;
  // how a run ended stays listed: the next status (the service going offline, the next run) replaces the message
  if (s.state === RunState.IDLE && s.run_id && said.startsWith("run ")) {
    addEvent(said.startsWith("run " + Outcome.COMPLETED) ? "info" : "warn", "run " + s.run_id + " " + said.slice(4)
      + (s.folder ? " (run folder " + s.folder + ")" : ""), false, s.since, key);
  } else if (warn && !(prev && prev.message === s.message)) addEvent("warn", [s.state + ": ", lifted(said, texts)], false, at, key);
  warnings.forEach(w => addEvent("warn", ["run " + (s.run_id || "") + ": warning: ", lifted(w, texts)], false, at, ["run warning", s.run_id, w].join("|")));
}

// a pause accepted and not yet reached (the run it was asked of): this page's accepted pause, or the waiting or
// suspended status saying one was asked (orbitrig.run.control's held words); gone once the run pauses or ends
function followPause(s) {
  if (s.state === RunState.WAITING || stateBadge.suspended(s)) st.pauseAsked = stateBadge.pauseRequested(s) !== null ? s.run_id : null;
  else if (s.state === RunState.OFFLINE) { /* changes no run */ }
  else if (s.run_id !== st.pauseAsked || runEnded(s) || (s.state === RunState.PAUSED && !stateBadge.suspended(s))) st.pauseAsked = null;
  showButtons();
}

// which commands apply in the state shown, known while the broker link is up, the service online and the view
// fresh; with the link down or the service offline the dashboard server sends none of Start, Pause and Resume
// (unless the view is stale: what the page shows is then not known to be the present, and the server decides);
// while the link is connecting (the page's feed has not said it yet: since the page loaded or a sign-in) none
// is known to go, stale or not
function showButtons() {
  const s = st.status, link = $("link").textContent, offline = !!s && s.state === RunState.OFFLINE;
  const notSent = link === BrokerLink.CONNECTING ? stateBadge.NotSent.CONNECTING : st.stale ? ""
    : link === BrokerLink.UNREACHABLE ? stateBadge.NotSent.NO_BROKER
    : offline ? (offlineUnknown(s) ? stateBadge.NotSent.UNKNOWN : stateBadge.NotSent.OFFLINE) : "";
  const known = !!s && !offline && link === BrokerLink.ONLINE && !st.stale;
  stateBadge.apply(s, known, !!s && !!s.run_id && st.pauseAsked === s.run_id, notSent);
}

// the ABORT confirmation names the rig it goes to (the one the page shows: several may share the broker) and
// what it stops there now: the run under way and its state, or no run (both drives' emergency stop all the same),
// or a rig service offline (the drives may not hear it: the rig's own emergency stop), said as the badge says it
// (LINK_LOST while that offline is not known true: offlineUnknown)
function abortQuestion() {
  const rig = ($("rig").textContent || "").split("/").pop(), s = st.status, q = $("abort-question");
  const underWay = s && s.run_id && !runEnded(s) && s.state !== RunState.OFFLINE;
  const b = document.createElement("b");
  b.textContent = underWay ? "Abort run " + s.run_id + " on rig " + rig + "?" : "Emergency stop on rig " + rig + "?";
  const said = underWay ? " It is " + s.state + ": both drives ramp to zero at once (emergency ramp)."
    : s && s.state === RunState.OFFLINE ? " " + sentence(offlineUnknown(s) ? SERVICE_LINK_LOST : Refusal.SERVICE_OFFLINE)
      + ": it may not hear the abort; if the drives turn, " + Refusal.EMERGENCY_STOP + "."
    : " No run is under way there" + (s ? " (" + s.state + ")" : "") + ": both drives get an emergency stop (OFF3) all the same.";
  clear(q); q.append(b, said);
}

// how the last run ended as the store recorded it (the ready status's last_run, read by a service (re)started
// since): under the message while no run is named, so that a page opened after a restart says it
function showLastRun(s) {
  const last = s.state === RunState.IDLE && !s.run_id ? s.last_run : null;
  if (!last) return;
  const line = document.createElement("div");
  line.id = "last-run"; line.className = "last-run";
  const end = last.outcome === StoredStatus.RUNNING
    ? "is still recorded as running (the service stopped during it; orbitrig sweep --resume continues it)"
    : last.outcome + (last.ended_at ? " at " + orbitPlots.localTime(last.ended_at) : "");  // local, as the alarms
  line.textContent = "last run " + last.run_id + " " + end + ", folder " + last.folder;
  line.title = last.message || "";  // the message its status was recorded with (who stopped it, and why)
  $("message").appendChild(line);
}

// which operating point of the matrix is under way (its label, as its result names it): the status's and
// the progress's point_label; between points (a pause before the next, its resume) the next one, said so
function showPointLabel(label, next) {
  const el = $("point-label"), text = label ? (next ? "next: " : "") + label : "—";
  el.textContent = text; el.title = label ? text : "the operating point's label, as its result names it";
}

// setting -> [label, shown unit (SHOWN_IN), digits]; a ratio says of what ("(e/C)", as the service's prompt)
const SETTING_LABEL = {orbit_radius: ["orbit radius", "µm", 2], static_eccentricity: ["static eccentricity (e/C)", "", 3],
  recess_pressure: ["recess pressure", "MPa", 4], pressure_ratio: ["pressure ratio", "", 3]};

// the asked settings of a waiting status; measured values follow the live payload (highlighted outside their band)
function showManual(s) {
  const waiting = s.state === RunState.WAITING && s.step;
  show($("manual"), !!waiting); show($("manual-none"), !waiting);
  $("manual-card").classList.toggle("asking", !!waiting);
  st.manual = waiting ? s.settings || {} : null;
  $("manual-step").textContent = waiting ? s.step : "";
  if (!waiting) return;
  showMotion(s.message || "");
  const body = $("manual-table"); clear(body);
  Object.entries(st.manual).forEach(([name, v]) => {
    const [text, unit, d] = SETTING_LABEL[name] || [name, v.unit, 4], shown = x => fmt(inShownUnit(x, unit), d);
    const tr = document.createElement("tr"); tr.dataset.setting = name;
    cell(tr, text + (unit ? " (" + unit + ")" : ""));
    cell(tr, v.value === null ? "—" : shown(v.value));
    cell(tr, ""); pieces(cell(tr, ""), v.band ? [shown(v.band[0]) + " …", shown(v.band[1])] : []);
    body.appendChild(tr);
  });
  showMeasured(Object.fromEntries(Object.entries(st.manual).map(([n, v]) => [n, v.measured])));
}

// whether the drives turn, as the service's waiting message says it ("...; the drives are turning:
// spin 1000 rpm, orbit 500 rpm (confirm step 'manual:0001')"): shown in the panel itself, for the
// person about to put hands on the rig; nothing shown when the message does not say
const MOTION = /^(both drives at standstill|the drives are turning\b.*|the drives' speeds not read yet)$/;

function showMotion(message) {
  const said = message.replace(/\s*\(confirm step '[^']*'\)\s*$/, "").split("; ").pop().trim();
  const motion = MOTION.test(said) ? said : "";
  const el = $("manual-motion");
  el.textContent = sentence(motion);
  el.className = "motion" + (motion.startsWith("the drives are turning") ? " turning" : motion.startsWith("the drives'") ? " unknown" : "");
}

function showMeasured(measured) {
  if (!st.manual) return;
  document.querySelectorAll("#manual-table tr").forEach(tr => {
    const name = tr.dataset.setting, v = st.manual[name], m = measured[name], td = tr.children[2];
    if (m === undefined) return;
    const [, unit, d] = SETTING_LABEL[name] || [name, "", 4], shown = fmt(inShownUnit(m, unit), d);
    const out = m !== null && v && v.band && (m < v.band[0] || m > v.band[1]);
    if (m === null) pieces(td, ["not measured yet"], true);
    else if (out) pieces(td, [shown, "(outside the band)"], true);
    else pieces(td, [shown]);
    td.className = out ? "out" : "";
    tr.classList.toggle("outside", !!out);
  });
}

function showProgress(p) {
  if (runEnded(st.status)) return;  // late: the run is over
  $("point").textContent = p.point + " / " + p.points;
  if (p.point_label) showPointLabel(p.point_label);
  // the block under way of the point's blocks (one per orbit frequency and whirl direction: the progress's
  // `frequency` of `frequencies`), as the terminal's "orbit blocks" bar counts them; not a frequency
  $("block").textContent = p.frequency + " of " + p.frequencies;
  $("revolutions").textContent = revolutionsText(p.revolutions, p.block_revolutions);
  st.etaS = p.eta_s; showEta();
  // how much of the run's points is measured, as the service counts it (its `fraction`: a block whose
  // acquisition is done counts whole; orbitrig.run.events.ProgressEvent.fraction, the terminal's count too)
  const done = typeof p.fraction === "number" && isFinite(p.fraction) ? p.fraction : 0;
  $("progress-bar").style.width = (100 * Math.min(1, Math.max(0, done))).toFixed(1) + "%";
}

// the block's revolutions of its target ("31 of 50"; `block_revolutions`: 0 before the point's first
// block, absent from a service that does not send it: the count alone)
function revolutionsText(n, target) {
  return typeof target === "number" && target > 0 ? n + " of " + target : String(n);
}

// the plan's rig time left, and under it why it stands still while the run waits for the operator
// or is paused (EtaHeld, from the run's state): "4:10" as the terminal's bar (formatDuration),
// "(paused: waiting for the operator)"
// A run's progress comes with its live values: while those are old (liveOld) the point, block, ETA and bar are
// the last known, greyed, and the line under the ETA says so ("(the last known, 6 s old: not the present)")
function showEta() {
  const known = st.etaS !== null && st.etaS !== undefined, age = liveOld();
  const held = known && st.status ? EtaHeld[Object.keys(RunState).find(k => RunState[k] === st.status.state)] : undefined;
  $("eta").textContent = known ? formatDuration(st.etaS) : "—";
  $("eta-held").textContent = age ? "(the last known, " + Math.round(age) + " s old: not the present)" : held ? "(" + held + ")" : "";
}

// ---------------------------------------------------------------- live
// averaged revolution chart id -> [[channel (docs/interfaces.md), its legend entry], ...], shown unit; each line
// in its own colour and dash pattern (orbitPlots.drawTraces), kept while another channel is missing
// (no entry: the name the hello gives it, as the report names it: F<sub>x</sub> piezo)
const REVOLUTION_CHARTS = {
  "plot-forces": [[["fx_piezo"], ["fy_piezo"], ["fx_strain"], ["fy_strain"]], "N"],
  "plot-disp": [[["x_a", "x plane A"], ["y_a", "y plane A"], ["x_b", "x plane B"], ["y_b", "y plane B"]], "µm"],
};

// the channels' names as the report writes them (the hello's: channel -> [symbol, subscript, system]); the
// forces' chart caption names its forces so: "Forces F<sub>x</sub>, F<sub>y</sub> (N)"
function showNames(names) {
  st.names = names || {};
  const caption = $("forces-caption"), seen = new Set();
  clear(caption); caption.append("Forces ");
  REVOLUTION_CHARTS["plot-forces"][0].map(([n]) => st.names[n]).filter(p => p).forEach(([symbol, sub]) => {
    if (seen.has(symbol + sub)) return;
    const el = document.createElement("sub"); el.textContent = sub;
    caption.append(seen.size ? ", " + symbol : symbol, el); seen.add(symbol + sub);
  });
  caption.append(" (N)");
}

// `age` (s): how old the payload is when it comes (a page's first feed replays the last one)
function showLive(d, age) {
  if (runEnded(st.status)) return;  // late: the run is over
  st.liveAt = performance.now() - 1000 * Math.max(0, age || 0);  // monotonic, as the feed's times
  showLiveAge();
  const orbit = (d.drives || {}).orbit;
  $("op-spin").textContent = rpmText(d.spin_rpm);
  $("op-orbit").textContent = rpmText(orbit ? orbit.actual_rpm : null);
  $("op-orbit-hz").textContent = withUnit(d.orbit_hz, 2, "Hz");
  $("op-direction").textContent = d.direction || "—";
  showDrives(d.drives || {});
  showAux(d.aux || {}, d.bands || {});
  trends.trendBands(d.bands);
  if (d.settings_measured) showMeasured(d.settings_measured);
  const w = d.waveforms || {};
  Object.entries(REVOLUTION_CHARTS).forEach(([id, [channels, unit]]) => {
    const series = channels.map(([n, name], line) => ({name: name || st.names[n] || n, line, values: w[n]})).filter(s => s.values);
    if (series.length) orbitPlots.drawTraces($(id), series, unit);
  });
  if (w.x_a && w.y_a && w.x_b && w.y_b) {
    const x = w.x_a.map((v, i) => (v + w.x_b[i]) / 2), y = w.y_a.map((v, i) => (v + w.y_b[i]) / 2);
    orbitPlots.drawOrbit($("plot-orbit"), x, y);
  }
}

// the live payload comes 5 times a second while a run is under way (docs/protocols/mqtt.md): one older than
// LIVE_OLD_S (a hung service before its last will, a stalled acquisition) is not the present: the live values
// (Run card, drives, sensors, averaged revolution) are greyed and each card says how old they are
const LIVE_OLD_S = 3;

// the live payload's age (s), null before the first
function liveAge() { return st.liveAt === null ? null : (performance.now() - st.liveAt) / 1000; }

// the live payload's age (s) when it is older than LIVE_OLD_S, else null
function liveOld() {
  const age = liveAge();
  return age !== null && age > LIVE_OLD_S ? age : null;
}

function showLiveAge() {
  const age = liveAge(), old = liveOld() !== null;
  const note = old ? "(the last live values, " + Math.round(age) + " s old: not the present)" : "";
  $("live-age").textContent = age === null ? "—" : age.toFixed(1) + " s ago" + (old ? ": not the present" : "");
  $("app").classList.toggle("live-old", old);
  document.querySelectorAll(".live-note").forEach(el => { el.textContent = note; });
  showEta();
}

function showDrives(dr) {
  const body = $("drives"); clear(body);
  ["spin", "orbit"].forEach(name => {
    const d = dr[name], tr = document.createElement("tr"); tr.dataset.drive = name;
    cell(tr, name);
    cell(tr, d ? rpmNumber(d.reference_rpm) : "—"); cell(tr, d ? rpmNumber(d.actual_rpm) : "—");
    cell(tr, d ? fmt(d.torque_pct, 1) : "—"); cell(tr, d ? d.state : (dr.link_ok === false ? "link lost" : "—"));
    cell(tr, d ? (d.fault_code ? d.fault + " (" + d.fault_code + ")" : "none") : "—", d && d.fault_code ? "out" : "");
    body.appendChild(tr);
  });
}

const AUX = [["t_supply", "supply temperature", "°C"], ["t_recess", "recess temperature", "°C"], ["t_groove", "groove temperature", "°C"],
  ["p_supply", "supply pressure", "MPa"], ["p_recess_1", "recess pressure 1", "MPa"], ["p_recess_2", "recess pressure 2", "MPa"],
  ["p_recess_3", "recess pressure 3", "MPa"], ["p_recess_4", "recess pressure 4", "MPa"], ["beta", "pressure ratio", ""], ["flow", "flow", "l/min"]];

function showAux(a, bands) {
  const body = $("aux"); clear(body);
  AUX.forEach(([key, text, unit]) => {
    const band = bands[key] || (key.startsWith("p_recess") ? bands.p_recess : null);
    const v = inShownUnit(a[key], unit), digits = unit === "MPa" ? 4 : unit === "" ? 3 : 2;
    const tr = document.createElement("tr"); tr.dataset.aux = key;
    cell(tr, text + (unit ? " (" + unit + ")" : ""));
    const out = band && a[key] !== null && a[key] !== undefined && (a[key] < band[0] || a[key] > band[1]);
    pieces(cell(tr, "", out ? "out" : ""), out ? [fmt(v, digits), "(outside the band)"] : [fmt(v, digits)], out);  // in words, not in red alone
    cell(tr, band ? fmt(inShownUnit(band[0], unit), digits) + " … " + fmt(inShownUnit(band[1], unit), digits) : "");
    body.appendChild(tr);
  });
  // what the CAN node's flags say of these values: shown in the card, the values greyed when not current
  const said = [a.node_lost && "CAN sensor node lost: the values are the last it sent, not the present",
    a.sensor_fault && "the CAN node reports a faulty sensor", a.pump_off && "the supply pump is off"].filter(Boolean);
  $("aux-state").textContent = said.join("; ");
  body.classList.toggle("stale", !!a.node_lost);
  if (a.node_lost) addEvent("warn", "CAN sensor node lost", true);
}

// ---------------------------------------------------------------- times
// every 0.5 s: once the browser's day has changed (midnight, a machine woken the next day), the times shown
// without their date (orbitPlots.shortTime: the events, the command outcome's, the Run card's latest warning, the
// badge's last run, the results' gap rows) are said again, with it: an item of 23:50 reads "2026-12-06 23:50:00" after midnight
function redate() {
  const today = orbitPlots.dateTimeOf(Date.now()).slice(0, 10);
  if (st.today === today) return;
  st.today = today;
  document.querySelectorAll("#events li").forEach(li => { li.firstChild.textContent = orbitPlots.shortTime(Number(li.dataset.at)); });
  const when = $("cmd-when");
  if (when.textContent) when.textContent = "at " + orbitPlots.shortTime(Number(when.dataset.at));
  resultTable.redateGaps();
  showServiceState();
  if (st.runWarnings) runWarnings(st.runWarnings.runId, 0);
}

// ---------------------------------------------------------------- events
// `at`: when it happened (ISO-8601; default now); `key`: what it is, listed once (a feed starting again
// hands on the same warnings and outcomes)
// what an event's kind looks like in words as well as colour: a warning's or a refusal's mark after its time
const EVENT_MARK = {warn: "⚠ ", refused: "✖ "};

const EVENTS_SHOWN = 100, EVENT_KEYS_KEPT = 5000;  // the list's items; the keys of those listed this session

function addEvent(kind, text, once, at, key) {
  const list = $("events"), parts = Array.isArray(text) ? text : [text];
  const plain = parts.map(p => typeof p === "string" ? p : p.text).join("");
  if (once && list.firstChild && list.firstChild.dataset.text === plain) return;
  if (key !== undefined && st.eventKeys.has(key)) return;
  const li = document.createElement("li"); li.className = kind; li.dataset.text = plain;
  if (key !== undefined) { li.dataset.key = key; st.eventKeys.add(key); }
  // the keys listed stay known after their items leave the list (EVENTS_SHOWN): a reconnecting feed's snapshot
  // hands the rig's latest warnings on again, and one trimmed would come back at the top as if it were new
  if (st.eventKeys.size > EVENT_KEYS_KEPT) st.eventKeys.delete(st.eventKeys.values().next().value);
  const when = at ? new Date(at) : new Date();
  li.append(orbitPlots.shortTime(when), " " + (EVENT_MARK[kind] || ""));  // its time a text of its own (redate)
  // a message typeset by the server (typeset.js: its text and subscripts only), the rest as text
  parts.forEach(p => { if (typeof p === "string") li.append(p); else typesetInto(li, p.html, p.text); });
  if (li.title) li.title = plain;  // a typeset message's plain words (u_*, gamma2_xfx) in its tooltip
  // newest first by its time (a reload's snapshot hands on results, warnings and statuses of different times)
  li.dataset.at = String(when.getTime());
  list.insertBefore(li, [...list.children].find(e => Number(e.dataset.at) <= when.getTime()) || null);
  while (list.children.length > EVENTS_SHOWN) list.removeChild(list.lastChild);
}

// a warning of the run (<prefix>/note: something gone wrong that the run survived), said as one in words, at
// the time the service stamped it; `withheld`: warnings before it the service did not publish (its rate limit),
// of the kinds `withheld_kinds` names (kind -> count). A warning of another run than the one the status names
// (the broker's retained copy of an earlier run's last warning: a dashboard started, a page loaded, after it) says so,
// with its date: listed as it comes, it would pass for the present run's
function showNote(n, texts) {  // the run's closing note says its withheld warnings in its message: not again
  const kinds = Object.entries(n.withheld_kinds || {}).map(([kind, count]) => kind + " " + count).join(", ");
  const withheld = n.withheld && !n.closing ? " (" + n.withheld + " earlier warnings not published" + (kinds ? ": " + kinds : "")
    + "; see the run's run.log)" : "";
  const now = st.status && st.status.run_id, earlier = st.status && n.run_id !== now;
  const old = earlier ? " (an earlier run's warning, said " + orbitPlots.localTime(n.at) + ": "
    + (now ? "not run " + now + "'s" : "no run since the service started") + ")" : "";
  addEvent("warn", ["warning: run " + (n.run_id || "") + ": ", lifted(n.message, texts), withheld + old], false, n.at,
    ["note", n.run_id, n.at, n.message].join("|"));
  if (st.status && !earlier) runWarnings(n.run_id, n.said || 1, n.at);
}

// the Run card's count of the warnings of the run the status names (`said`: the run's so far, from its latest
// note or its closing status; `at`: when the latest was said), so that they are seen without the list below;
// with the fit warnings its results brought (fitWarning), listed there too: "none" says neither kind
function runWarnings(runId, said, at) {
  const w = st.runWarnings && st.runWarnings.runId === runId ? st.runWarnings : {runId, said: 0, at: null};
  st.runWarnings = {runId, said: Math.max(w.said, said), at: at || w.at};
  const el = $("run-warnings"), n = st.runWarnings.said, latest = st.runWarnings.at;
  const fits = (st.fitWarnings.get(runId) || new Set()).size, f = fits + (fits === 1 ? " fit warning" : " fit warnings");
  const notes = n + (n === 1 ? " warning" : " warnings") + " in this run"
    + (latest ? ", the latest at " + orbitPlots.shortTime(latest) : "");
  el.textContent = !runId ? "—" : n === 0 && fits === 0 ? "none in this run"
    : "⚠ " + (n === 0 ? f + " in this run" : notes + (fits ? ", and " + f : "")) + ": listed under Warnings and refusals";
  el.className = (n > 0 || fits > 0) && runId ? "warn" : "";
}

// a fit warning (or refusal) of a result of run `runId`, listed under Warnings and refusals (`key`: which, listed
// once): counted on the Run card while the status names that run
function fitWarning(runId, key) {
  if (!st.fitWarnings.has(runId)) st.fitWarnings.set(runId, new Set());
  st.fitWarnings.get(runId).add(key);
  if (st.status && st.status.run_id === runId) runWarnings(runId, 0);
}

// the broker link was down from gap.from to gap.to: what was published meanwhile came after (the broker
// kept the session's messages), or results may be missing (a row of the results table says where); with
// `dropped`: this page read its feed too slowly, and the dashboard server left out progress and trend points
// put from gap.from to gap.to (kind -> count), every result, warning, alarm and status came
function showLinkGap(gap) {
  if (gap.dropped) { showFeedBehind(gap); return; }
  const span = orbitPlots.shortTime(gap.from) + " to " + orbitPlots.shortTime(gap.to);
  if (!gap.caught_up) resultTable.showGap(gap);
  addEvent(gap.caught_up ? "info" : "warn", "broker link down from " + span + (gap.caught_up ?
    ": the broker kept what was published meanwhile (results caught up)" : ": results published meanwhile may be missing"), false, gap.to, "gap|" + gap.from);
}

function showFeedBehind(gap) {
  const words = {[FeedType.PROGRESS]: "progress update", [FeedType.TREND]: "trend point"};  // "s" after all but 1
  const left = Object.keys(gap.dropped).sort().map(kind => { const n = gap.dropped[kind];
    return n + " " + (words[kind] ? words[kind] + (n === 1 ? "" : "s") : kind); }).join(", ");
  addEvent("info", "this page fell behind its feed from " + orbitPlots.shortTime(gap.from) + " to " + orbitPlots.shortTime(gap.to) +
    ": not shown " + left + " (every result, warning, alarm and status came)", false, gap.to, "behind|" + gap.from);
}

// ---------------------------------------------------------------- commands
// what to do when a command's outcome is unknown, as the dashboard server's outcomes say it (orbitrig.dashboard.commands.unknown)
function advice(cmd) {
  return cmd === Command.STOP || cmd === Command.ABORT ? Refusal.CHECK_STATE + "; " + Refusal.EMERGENCY : Refusal.CHECK_STATE;
}

// the command goes with the rig this page shows: the server refuses it if the session watches
// another by now, but for a stop or abort, which goes to the rig this page shows. The request is given up after the server's own waits (the broker's
// acknowledgement, the service's reply) and 2 s more: then nobody knows whether it went.
async function send(cmd, extra) {
  activity();
  const out = $("cmd-result"), deadline = 2 * st.replyTimeout + 2;
  out.className = "cmd-result"; out.textContent = cmd + ": sending…"; $("cmd-when").textContent = "";
  let r;
  try { r = await api("/api/cmd", Object.assign({cmd, rig: $("rig").textContent}, extra || {}), 1000 * deadline); }
  catch (e) {
    const why = e && e.name === "TimeoutError" ? "no answer from the dashboard within " + deadline + " s" : "dashboard server unreachable";
    r = {status: 0, data: {ok: false, error: why + ": " + Refusal.OUTCOME_UNKNOWN + " (the command may have been sent) — " + advice(cmd)}};
  }
  if (r.status === 401) {
    const urgent = cmd === Command.STOP || cmd === Command.ABORT;
    leave(urgent ? "session ended: " + cmd.toUpperCase() + " NOT SENT — sign in and send it again, or " + Refusal.EMERGENCY_STOP :
      "session ended: sign in again (" + cmd + " not sent)");
    return;
  }
  showOutcome(cmd, r.data);
}

// an accepted pause is not a paused run: the run goes on to its next safe point (seconds), until its status says
// paused; the service's reply says when (its `detail`: once the manual setting waited for is confirmed), this
// only for a reply that does not
function pending(cmd, at) {
  const state = st.status && st.status.state;
  return cmd === Command.PAUSE && !at && (state === RunState.RUNNING || state === RunState.WAITING) ?
    " — the run pauses at its next safe point (the state then says paused)" : "";
}

// an outcome the session keeps (its command and time, `at`): the same in the server's answer and its snapshot
function outcomeKey(cmd, data) { return data.at ? cmd + "|" + data.at : undefined; }

// a command's outcome ({ok, error, at, rig}); `at` (ISO-8601): one the session kept from before this page was
// loaded; `rig`: the rig a stop or abort went to while the session watched another (named in the outcome)
function showOutcome(cmd, data, at) {
  const out = $("cmd-result"), earlier = at ? " (before this page was loaded)" : "";  // when: the line under it
  const key = outcomeKey(cmd, data), label = data.rig ? cmd + " to rig " + data.rig : cmd;
  if (key) st.outcomes.add(key);
  // when it came (the session's time of it, else now): an outcome stays shown until the next command
  const when = $("cmd-when"), t = new Date(at || data.at || Date.now());
  when.dataset.at = String(t.getTime()); when.textContent = "at " + orbitPlots.shortTime(t);
  if (data.ok) {  // with what the service did, when it says (an abort no run carried out)
    if (!at && (cmd === Command.PAUSE || cmd === Command.RESUME) && st.status) {  // a resume withdraws a pause
      st.pauseAsked = cmd === Command.PAUSE ? st.status.run_id : null; showButtons();
    }
    out.className = "cmd-result ok"; out.textContent = label + ": accepted" + (data.detail ? ": " + data.detail : pending(cmd, at)) + earlier;
    if (data.detail && cmd !== Command.PAUSE) addEvent("info", label + ": " + data.detail, false, at, key);  // a pause's: its status says it
    return;
  }
  const error = data.error || "failed";  // the server's reasons leave the name to the page: prefixed once
  // the rig service's own refusal (a run active, a bad matrix) said as one, in words and the mark, not in red alone
  const text = data.refused ? label + ": REFUSED by the rig service: " + error
    : error.startsWith(cmd + ":") ? error : label + ": " + error;
  out.className = "cmd-result refused" + (data.refused ? " by-service" : "");
  out.textContent = (data.refused ? EVENT_MARK.refused : "") + text + earlier;
  addEvent("refused", text, false, at, key);
  const names = /available: ([^)]*)\)/.exec(data.error || "");
  if (names) fillMatrices(names[1].split(", "));
}

function fillMatrices(names) {
  const dl = $("matrix-names"); clear(dl);
  names.forEach(n => { const o = document.createElement("option"); o.value = n; dl.appendChild(o); });
}

function wire() {
  $("signin-form").addEventListener("submit", signIn);
  $("signout").addEventListener("click", signOut);
  $("btn-start").addEventListener("click", () => { st.matrixTyped = false; send(Command.START, {matrix: $("matrix").value.trim()}); });
  $("matrix").addEventListener("input", () => { st.matrixTyped = true; });
  $("btn-pause").addEventListener("click", () => send(Command.PAUSE));
  $("btn-resume").addEventListener("click", () => send(Command.RESUME));
  $("btn-stop").addEventListener("click", () => send(Command.STOP));
  $("btn-abort").addEventListener("click", () => { abortQuestion(); $("abort-dialog").showModal(); });
  $("abort-cancel").addEventListener("click", () => $("abort-dialog").close());
  $("abort-confirm").addEventListener("click", () => { $("abort-dialog").close(); send(Command.ABORT); });
  $("trend-window").addEventListener("change", () => trends.drawTrends());
  $("rig-select").addEventListener("change", selectRig);
  $("btn-confirm").addEventListener("click", () => send(Command.CONFIRM, {step: $("manual-step").textContent}));
  ["keydown", "pointerdown", "pointermove", "wheel"].forEach(t => document.addEventListener(t, activity, {passive: true}));
  setInterval(watchFeed, 500);
  setInterval(showLiveAge, 500);
  setInterval(redate, 500);
  // the header and banner's height (more lines in a narrow window, a banner or none): the alarm flag scrolls the
  // alarms' heading to just under them, not under them
  new ResizeObserver(([e]) => document.documentElement.style.setProperty("--top-height", e.target.offsetHeight + "px"))
    .observe(document.querySelector(".top"));
}

async function boot() {
  wire();
  try {
    const r = await api("/api/session");
    if (r.status === 200) { enter(r.data); return; }
  } catch (e) { /* not reachable: show the sign-in */ }
  leave("");
}

boot();
