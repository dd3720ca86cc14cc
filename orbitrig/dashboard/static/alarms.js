// The alarm list: latched interlock trips and failed runs (from the dashboard server's "alarms"
// messages), each with its condition as far as the rig's statuses tell (active, cleared, unknown: with
// what it rests on when that is not the alarm's own run) and its acknowledgement (who, when) or an
// Acknowledge button. Unacknowledged alarms are also said where an operator looks whatever the page shows: in
// the sticky header (a flag that scrolls to the list) and in the tab's title (a tab in the background).
"use strict";

const PAGE_TITLE = document.title;

function showAlarms(list) {
  const body = document.getElementById("alarms"); clear(body);
  let open = 0;
  list.forEach(a => {
    const tr = document.createElement("tr"); tr.dataset.alarm = a.id;
    tr.className = a.acked_by ? "acked" : "unacked";
    if (!a.acked_by) open++;
    cell(tr, orbitPlots.localTime(a.since)); cell(tr, a.kind); cell(tr, a.text);
    cell(tr, a.condition + (a.note ? ": " + a.note : ""), a.condition === Condition.ACTIVE ? "out" : a.condition === Condition.UNKNOWN ? "unknown" : "");
    const ack = cell(tr, a.acked_by ? a.acked_by + ", " + orbitPlots.localTime(a.acked_at) : "");
    if (!a.acked_by) {
      const b = document.createElement("button"); b.textContent = "Acknowledge"; b.className = "ack";
      b.addEventListener("click", () => acknowledge(a.id));
      ack.appendChild(b);
    }
    body.appendChild(tr);
  });
  const badge = document.getElementById("alarm-count");
  badge.textContent = open ? open + " unacknowledged" : "none unacknowledged";
  badge.className = "badge " + (open ? "l-broker" : "l-online");
  const said = open + (open === 1 ? " unacknowledged alarm" : " unacknowledged alarms"), flag = document.getElementById("alarm-flag");
  flag.textContent = "⚠ " + open + (open === 1 ? " alarm" : " alarms"); flag.title = said + ": go to the alarm list";
  show(flag, open > 0);
  document.title = open ? "⚠ " + said + " — " + PAGE_TITLE : PAGE_TITLE;
  show(document.getElementById("alarms-empty"), list.length === 0);
}

async function acknowledge(id) {
  activity();
  const out = document.getElementById("alarm-result");
  out.className = "cmd-result"; out.textContent = "acknowledge: sent…";
  let r;
  try { r = await api("/api/ack", {alarm: id, rig: document.getElementById("rig").textContent}, 1000 * (2 * st.replyTimeout + 2)); }
  catch (e) { r = {status: 0, data: {ok: false, error: "acknowledge: no answer from the dashboard server: look at the list, try again"}}; }
  if (r.status === 401) { leave("session ended: sign in again"); return; }
  if (r.data.ok) { out.className = "cmd-result ok"; out.textContent = "acknowledge: done"; return; }
  out.className = "cmd-result refused"; out.textContent = r.data.error || "acknowledge: failed";
  addEvent("refused", out.textContent);
}

window.alarmList = {showAlarms};
