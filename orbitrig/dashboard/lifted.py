"""The names a page shows typeset as the report writes them, made on the dashboard server by the
one owner of that rule (orbitrig.analysis.typeset, which the caller gives: the dashboard wing does
not import the analysis), sent beside the plain names in the feed's messages.

A result's feed message carries ``"entries"``: each coefficient key of its fits -> its HTML
(``Kxx`` -> ``K<sub>xx</sub>``, ``Kxy_1`` -> ``K<sub>xy,1</sub>``; another name escaped as it is).
The HTML is made here from text the broker brought, escaped by the owner; the page takes of it
only text and ``<sub>`` elements (static/typeset.js) and never inserts the broker's text as HTML.
"""

from __future__ import annotations

import html
from dataclasses import dataclass
from typing import Any, Callable


@dataclass(frozen=True)
class PageTypesetting:
    """How the page writes a coefficient's key (`entry_html`): the report's rule, given by the caller
    (orbitrig.analysis.typeset.entry_html); by default the name escaped as it is."""

    entry_html: Callable[[str], str] = html.escape


def _fits(result: dict) -> list[dict]:
    fits = result.get("identification")
    return [f for f in fits if isinstance(f, dict)] if isinstance(fits, list) else []


def result_entries(result: dict, typeset: PageTypesetting) -> dict[str, str]:
    """Each coefficient key of a result's fits -> its HTML (``{"Kxx": "K<sub>xx</sub>"}``)."""
    keys = {k for f in _fits(result) if isinstance(f.get("coefficients"), dict) for k in f["coefficients"]}
    return {k: typeset.entry_html(k) for k in sorted(keys) if isinstance(k, str)}


def typeset_result(result: dict, typeset: PageTypesetting) -> dict[str, Any]:
    """A result's feed message: the payload as it came (``data``) and its names typeset beside it."""
    return {"data": result, "entries": result_entries(result, typeset)}
