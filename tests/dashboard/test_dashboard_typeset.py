"""The page names what it shows as the report does, in a real chromium on a real authenticated
mosquitto, the rule taken from its one owner (orbitrig.analysis.typeset) through the dashboard
server (orbitrig.dashboard.lifted): the results table's coefficients K<sub>xx</sub>, K<sub>xy,1</sub>.
The broker's text never becomes markup: a name holding a tag is shown as the text it is.
The test publishes what the rig service does (as orbitrig-service, docs/protocols/mqtt.md)."""

from __future__ import annotations

import pytest
from support.dash_helpers import Page, dashboard_running, publish_as_service
from support.mqtt_helpers import ACCOUNTS

from orbitrig.analysis.typeset import entry_html

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
