"""The names and messages a page shows typeset as the report writes them, made on the dashboard
server by the one owner of that rule (orbitrig.analysis.typeset, which the caller gives: the
dashboard wing does not import the analysis), sent beside the plain text in the feed's messages.

A result's feed message carries ``"entries"``: each coefficient key of its fits -> its HTML
(``Kxx`` -> ``K<sub>xx</sub>``, ``Kxy_1`` -> ``K<sub>xy,1</sub>``; another name escaped as it is);
a result's, a note's and a status's carry ``"texts"``: each message the page lists of it (a fit's
warning or refusal; the note's message; the status's message and its grouped warnings, split at
protocol.GROUPED_WARNING as the page splits them) -> its HTML, the uncertainty and coherence
columns it names lifted (``u_*`` -> ``u<sub>*</sub>``, ``gamma2_xfx`` -> ``γ²<sub>xFx</sub>``).
The HTML is made here from text the broker brought, escaped by the owner; the page takes of it
only text and ``<sub>`` elements (static/typeset.js) and never inserts the broker's text as HTML.
"""

from __future__ import annotations

import html
from dataclasses import dataclass
from typing import Any, Callable

import orbitrig.service.protocol as proto


@dataclass(frozen=True)
class PageTypesetting:
    """How the page writes a coefficient's key (`entry_html`) and a message (`message_html`): the
    report's rules, given by the caller (orbitrig.analysis.typeset.entry_html, message_html); by
    default the text escaped as it is."""

    entry_html: Callable[[str], str] = html.escape
    message_html: Callable[[str], str] = html.escape

    def texts(self, messages: list[Any]) -> dict[str, str]:
        """Each message (text; anything else left out) -> its HTML."""
        return {m: self.message_html(m) for m in messages if isinstance(m, str) and m}


def _fits(result: dict) -> list[dict]:
    fits = result.get("identification")
    return [f for f in fits if isinstance(f, dict)] if isinstance(fits, list) else []


def result_entries(result: dict, typeset: PageTypesetting) -> dict[str, str]:
    """Each coefficient key of a result's fits -> its HTML (``{"Kxx": "K<sub>xx</sub>"}``)."""
    keys = {k for f in _fits(result) if isinstance(f.get("coefficients"), dict) for k in f["coefficients"]}
    return {k: typeset.entry_html(k) for k in sorted(keys) if isinstance(k, str)}


def _strings(value: Any) -> list[Any]:
    return value if isinstance(value, list) else []


def result_messages(result: dict) -> list[Any]:
    """The messages the page lists of a result: each fit's refusal and warnings, the result's `warnings`."""
    out: list[Any] = []
    for f in _fits(result):
        out += [f.get("error"), *_strings(f.get("warnings"))]
    return out + _strings(result.get("warnings"))


def typeset_result(result: dict, typeset: PageTypesetting) -> dict[str, Any]:
    """A result's feed message: the payload as it came (``data``) and its names and messages typeset beside it."""
    return {"data": result, "entries": result_entries(result, typeset), "texts": typeset.texts(result_messages(result))}


def typeset_note(note: dict, typeset: PageTypesetting) -> dict[str, Any]:
    """A note's feed message: the payload as it came and its message typeset beside it."""
    return {"data": note, "texts": typeset.texts([note.get("message")])}


def typeset_status(status: dict, typeset: PageTypesetting) -> dict[str, Any]:
    """A status's feed message: the payload as it came and its message's parts typeset beside it (what
    it says, then each grouped warning of a closing status)."""
    message = status.get("message")
    parts = message.split(proto.GROUPED_WARNING) if isinstance(message, str) else []
    return {"data": status, "texts": typeset.texts(parts)}
