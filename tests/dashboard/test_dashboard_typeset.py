"""The page names what it shows as the report does, in a real chromium on a real authenticated
mosquitto, the rule taken from its one owner (orbitrig.analysis.typeset) through the dashboard
server (orbitrig.dashboard.lifted): the results table's coefficients K<sub>xx</sub>, K<sub>xy,1</sub>;
the event list's warnings (a note's, a fit's, a closing status's) with the columns they name lifted,
u<sub>*</sub>, γ²<sub>xFx</sub>, as the report's page writes them (message_html).
The broker's text never becomes markup: a name or message holding a tag is shown as the text it is.
The test publishes what the rig service does (as orbitrig-service, docs/protocols/mqtt.md)."""

from __future__ import annotations

import pytest
from support.dash_helpers import Page, dashboard_running, publish_as_service
from support.mqtt_helpers import ACCOUNTS

from orbitrig.analysis.typeset import entry_html, message_html

#: a key holding markup (a broken or hostile publisher): shown as text, nothing of it runs or loads
HOSTILE = '<img src=x onerror="window.__typesetHit = 1">'
KEYS = ["Kxx", "Cxy", "Kxy_1", "Zyx", HOSTILE]


@pytest.fixture(scope="module")
def dashboard(broker, tmp_path_factory):
    """The dashboard alone on the broker: the test publishes what the rig service would."""
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


def running_page(broker, browsers, dashboard, run_id: str) -> Page:
    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in("viewer", ACCOUNTS["viewer"])
    page.signed_in()
    page.wait_text("link", "online")
    status = {"state": "running", "run_id": run_id, "since": "2026-01-07T08:00:00.000Z", "message": "started"}
    publish_as_service(broker, "status", status, retain=True)
    page.wait_state("running", 10)
    return page


def coefficient_cells(page: Page) -> list[dict]:
    """The results table's coefficient column: each cell's HTML, text and tooltip."""
    return page.d.execute_script(
        "return [...document.querySelectorAll('#results tr')].filter(r => r.children.length >= 7)"
        ".map(r => r.children[3]).map(td => ({html: td.innerHTML, text: td.textContent, title: td.title}))"
    )


def test_the_results_table_names_the_coefficients_as_the_report_does(broker, dashboard, browsers):
    page = running_page(broker, browsers, dashboard, "r-names")
    fit = {
        "lms": "piezo",
        "model": "kc7",
        "freq_dep": "none",
        "method": "ols",
        "coefficients": {k: 1.5e7 for k in KEYS},
        "units": {k: "N/m" for k in KEYS},
    }
    publish_as_service(
        broker, "result", {"run_id": "r-names", "index": 0, "label": "w1000rpm", "identification": [fit]}
    )
    page.wait(lambda: len(coefficient_cells(page)) == len(KEYS), 10, "a row per coefficient")
    cells = coefficient_cells(page)
    assert [c["html"] for c in cells[:4]] == [entry_html(k) for k in KEYS[:4]]
    assert [c["html"] for c in cells[:4]] == ["K<sub>xx</sub>", "C<sub>xy</sub>", "K<sub>xy,1</sub>", "Z<sub>yx</sub>"]
    assert [c["title"] for c in cells[:4]] == KEYS[:4]  # the plain key (the files', the terminal's) in its tooltip
    # the hostile key: its text, no element made of it, nothing run
    assert cells[4]["text"] == HOSTILE and "<img" not in cells[4]["html"]
    assert page.d.execute_script("return document.querySelectorAll('#results img').length") == 0
    assert page.d.execute_script("return window.__typesetHit === undefined")


PIEZO = "bad fit: chi2 = 104.2 for 57 degrees of freedom: the residuals exceed the stated u_*"
COHERENCE = "coherence gamma2_xfx below 0.9 at 3 frequencies; gamma2_* of the others above"
#: a message holding markup, and a column it names
HOSTILE_NOTE = '<script>window.__typesetHit = 2</script><img src=x onerror="window.__typesetHit = 1"> u_x & more'


def event_items(page: Page) -> list[dict]:
    return page.d.execute_script(
        "return [...document.querySelectorAll('#events li')]"
        ".map(li => ({html: li.innerHTML, text: li.textContent, title: li.title}))"
    )


def owner_html(page: Page, message: str) -> str:
    """`message` as the owner typesets it (message_html), as the browser writes that HTML back."""
    script = "const t = document.createElement('template'); t.innerHTML = arguments[0]; return t.innerHTML;"
    return page.d.execute_script(script, message_html(message))


def listed(page: Page, message: str) -> dict | None:
    """The event whose HTML holds `message` as the owner typesets it."""
    html = owner_html(page, message)
    return next((e for e in event_items(page) if html in e["html"]), None)


def test_the_event_list_lifts_the_columns_a_message_names(broker, dashboard, browsers):
    page = running_page(broker, browsers, dashboard, "r-events")
    note = {"run_id": "r-events", "severity": "warning", "message": COHERENCE, "at": "2026-01-07T08:01:00.000Z"}
    publish_as_service(broker, "note", note, retain=True)
    fit = {"lms": "piezo", "model": "kc7", "freq_dep": "none", "method": "ols", "coefficients": {"Kxx": 1.5e7}}
    result = {"run_id": "r-events", "index": 0, "label": "w1000rpm", "identification": [{**fit, "warnings": [PIEZO]}]}
    publish_as_service(broker, "result", result)
    page.wait(lambda: listed(page, COHERENCE) and listed(page, PIEZO), 10, "the note and the fit warning lifted")
    assert message_html(COHERENCE).count("<sub>") == 2 and "\u03b3\u00b2<sub>xFx</sub>" in message_html(COHERENCE)
    assert message_html(PIEZO).endswith("u<sub>*</sub>")
    coherence, piezo = listed(page, COHERENCE), listed(page, PIEZO)
    lifted = "coherence \u03b3\u00b2xFx below 0.9 at 3 frequencies; \u03b3\u00b2* of the others above"
    assert coherence["text"].endswith("warning: run r-events: " + lifted), coherence
    assert coherence["title"] == "warning: run r-events: " + COHERENCE  # the plain words in the tooltip
    assert piezo["text"].endswith("point 1 piezo kc7: " + PIEZO.replace("u_*", "u*")), piezo

    closing = "run completed" + "; warning: " + "kc7 none ols, piezo: the residuals exceed the stated u_* uncertainties"
    status = {"state": "idle", "run_id": "r-events", "since": "2026-01-07T08:05:00.000Z", "message": closing}
    publish_as_service(broker, "status", status, retain=True)
    grouped = closing.split("; warning: ")[1]
    page.wait(lambda: listed(page, grouped) is not None, 10, "the closing status's grouped warning lifted")
    page.d.refresh()  # the server's snapshot typesets them again: the status's, the note's, the result's
    page.wait(lambda: all(listed(page, m) for m in (grouped, COHERENCE, PIEZO)), 15, "all lifted after a reload")


def test_a_message_holding_markup_is_shown_as_text(broker, dashboard, browsers):
    page = running_page(broker, browsers, dashboard, "r-hostile")
    note = {"run_id": "r-hostile", "severity": "warning", "message": HOSTILE_NOTE, "at": "2026-01-07T08:01:00.000Z"}
    publish_as_service(broker, "note", note, retain=True)
    fit = {"lms": "strain", "model": "kc7", "freq_dep": "none", "method": "ols", "error": HOSTILE_NOTE}
    publish_as_service(broker, "result", {"run_id": "r-hostile", "index": 2, "identification": [fit]})
    page.wait(lambda: sum(HOSTILE_NOTE[:20] in e["text"] for e in event_items(page)) == 2, 10, "both listed")
    for e in (e for e in event_items(page) if HOSTILE_NOTE[:20] in e["text"]):
        # the text as it came, its u_x lifted; no element of it but the subscript
        assert e["text"].endswith(HOSTILE_NOTE.replace("u_x", "ux")), e
        assert owner_html(page, HOSTILE_NOTE) in e["html"] and "<script" not in e["html"] and "<img" not in e["html"]
        assert e["html"].count("<") == 2 and "<sub>x</sub>" in e["html"], e  # the subscript alone
    assert page.d.execute_script("return document.querySelectorAll('#events script, #events img').length") == 0
    assert page.d.execute_script("return window.__typesetHit === undefined")


def test_the_run_cards_message_is_typeset_as_the_event_list(broker, dashboard, browsers):
    """The Run card shows a closing status's message whole, its grouped warning's u_* written u<sub>*</sub> as
    the same warning in the event list (one owner: static/typeset.js), the plain message in its tooltip."""
    page = running_page(broker, browsers, dashboard, "r-card")
    warning = "kc7 none ols, piezo: the residuals exceed the stated u_* uncertainties"
    closing = "run completed" + "; warning: " + warning
    status = {"state": "idle", "run_id": "r-card", "since": "2026-01-07T08:05:00.000Z", "message": closing}
    publish_as_service(broker, "status", status, retain=True)
    page.wait(lambda: listed(page, warning) is not None, 10, "the grouped warning listed")
    shown = page.d.execute_script(
        "const m = document.getElementById('message'); return {html: m.innerHTML, text: m.textContent, title: m.title}"
    )
    assert shown["html"] == "run completed; warning: " + owner_html(page, warning), shown
    assert shown["text"] == closing.replace("u_*", "u*") and shown["title"] == closing
    assert owner_html(page, warning) in listed(page, warning)["html"]  # the event list's, the same
