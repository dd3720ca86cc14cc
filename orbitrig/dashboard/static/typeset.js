// A name or message the dashboard server typeset by the report's rule (orbitrig.analysis.typeset:
// K<sub>xx</sub>, u<sub>x</sub>, γ²<sub>xFx</sub>; orbitrig.dashboard.lifted), as nodes to put in the page.
// The page has no copy of that rule: it takes the server's HTML, parsed inert (a template: nothing in
// it runs or loads), and keeps only its text and its <sub> elements, built anew from their text;
// anything else in it, or no HTML at all, and the plain text is shown as it is (never as HTML).
"use strict";

function typesetNodes(html, text) {
  if (typeof html !== "string") return [document.createTextNode(String(text))];
  const t = document.createElement("template");
  t.innerHTML = html;
  const out = [];
  for (const n of t.content.childNodes) {
    if (n.nodeType === Node.TEXT_NODE) out.push(document.createTextNode(n.textContent));
    else if (n.nodeName === "SUB" && !n.attributes.length && [...n.childNodes].every(c => c.nodeType === Node.TEXT_NODE)) {
      const sub = document.createElement("sub"); sub.textContent = n.textContent; out.push(sub);
    } else return [document.createTextNode(String(text))];
  }
  return out;
}

// `el` gets the typeset text; one with a subscript has its plain text in its tooltip (the name the files
// and the terminal use: Kxy_1, u_x)
function typesetInto(el, html, text) {
  const nodes = typesetNodes(html, text);
  el.append(...nodes);
  if (nodes.some(n => n.nodeName === "SUB") && !el.title) el.title = String(text);
  return el;
}

// `el` gets status message `message` whole (the Run card's), each of its parts (what it says, then each grouped
// warning, split at StatusSaid.GROUPED_WARNING as the server typeset them: `texts`) typeset as the event list
// shows it; its plain words in its tooltip when a part has a subscript
function typesetMessage(el, message, texts) {
  el.textContent = ""; el.title = "";
  message.split(StatusSaid.GROUPED_WARNING).forEach((part, i) => {
    if (i) el.append(StatusSaid.GROUPED_WARNING);
    typesetInto(el, texts ? texts[part] : undefined, part);
  });
  if (el.title) el.title = message;
  return el;
}

// `text` (a message the page lists) with its HTML from the feed message's `texts` (text -> HTML) when the
// server typeset it: a part of an event (addEvent); the text alone when it did not
function lifted(text, texts) {
  return texts && typeof texts[text] === "string" ? {text, html: texts[text]} : text;
}
