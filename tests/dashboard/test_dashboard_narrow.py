"""The page in a phone's window (390 x 844) and a small laptop's (1366 x 768) in a real chromium on a
real authenticated mosquitto: the header's ABORT and Sign out are in view, the page needs no
sideways scrolling and every card lies inside the window. The tests publish what the rig service
would (as orbitrig-service), a run waiting for the operator with an alarm latched."""

from __future__ import annotations

import pytest
from support.dash_helpers import Page, dashboard_running, publish_as_service
from support.mqtt_helpers import ACCOUNTS
from test_dashboard_layout import PROGRESS, live, waiting

SIZES = [(390, 844), (1366, 768)]

#: what lies outside the window's width: the page's own width past it, header items, cards
OUTSIDE_WINDOW = r"""
const w = document.documentElement.clientWidth, out = [];
if (document.documentElement.scrollWidth > w) out.push('page ' + document.documentElement.scrollWidth + ' px wide');
const boxes = [...document.querySelectorAll('header > *'), ...document.querySelectorAll('main > section')];
boxes.filter(e => e.getClientRects().length).forEach(e => {
  const r = e.getBoundingClientRect();
  if (r.left < -0.5 || r.right > w + 0.5)
    out.push((e.id || e.className || e.tagName.toLowerCase()) + ' ' + r.left.toFixed(1) + '..' + r.right.toFixed(1));
});
return out;"""

#: the alarms' card scrolled into view below the sticky header and banner, not under them
CARD_UNDER_THE_TOP = r"""
const c = document.getElementById('alarms-card').getBoundingClientRect();
return scrollY > 0 && c.top >= document.querySelector('.top').getBoundingClientRect().bottom && c.top < innerHeight / 2;"""

#: what a card draws past its edges (not inside a box of its own that scrolls or clips: the alarms' and
#: results' tables, a chart's figure): "card: element left..right (card left..right)"
OUTSIDE_CARDS = r"""
const out = [];
document.querySelectorAll('main > section').forEach(card => {
  const c = card.getBoundingClientRect(), name = card.id || card.className;
  card.querySelectorAll('*').forEach(e => {
    if (!e.getClientRects().length) return;
    for (let a = e.parentElement; a !== card; a = a.parentElement) if (getComputedStyle(a).overflowX !== 'visible') return;
    const r = e.getBoundingClientRect();
    if (r.width && (r.right > c.right + 0.5 || r.left < c.left - 0.5))
      out.push(name + ': ' + e.tagName.toLowerCase() + (e.id ? '#' + e.id : '') + ' ' + r.left.toFixed(1) + '..'
        + r.right.toFixed(1) + ' (card ' + c.left.toFixed(1) + '..' + c.right.toFixed(1) + ')');
  });
});
return out;"""


@pytest.fixture(scope="module")
def dashboard(broker, tmp_path_factory):
    """The dashboard alone on the broker (no rig service)."""
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}px")
def test_abort_and_every_card_are_in_a_narrow_window(broker, dashboard, browsers, size):
    """At 390 px the header ran past the window's right edge (ABORT and Sign out out of view, no way
    to scroll the sticky header to them) and the cards, at least 380 px wide, pushed the page sideways."""
    d = browsers()
    d.set_window_size(*size)
    page = Page(d, dashboard.url, dashboard)
    page.sign_in("operator", ACCOUNTS["operator"])
    page.signed_in()
    suspended = "suspended by interlock: supply pressure 0.1 MPa below 0.2 MPa"
    since = "2026-01-05T13:00:00.000Z"
    publish_as_service(
        broker, "status", {"state": "paused", "run_id": "r-narrow", "since": since, "message": suspended}
    )
    page.wait(lambda: page.el("alarm-flag").is_displayed(), 10, "the alarm flag in the header")
    assert d.execute_script(OUTSIDE_WINDOW) == []
    for button in ("btn-abort", "signout", "alarm-flag"):
        assert page.el(button).is_displayed()
    # the flag scrolls the alarms' card to just under the header and the banner, whatever their height (at 390 px
    # the header's three lines and the banner covered the card's heading)
    gone = {"state": "offline", "run_id": "r-narrow", "since": since, "message": "connection to the rig service lost"}
    publish_as_service(broker, "status", gone)
    page.wait(lambda: page.el("offline-banner").is_displayed(), 10, "the offline banner")
    page.el("alarm-flag").click()
    page.wait(lambda: d.execute_script(CARD_UNDER_THE_TOP), 5, "the alarms' card under the header and banner")
    publish_as_service(broker, "status", {"state": "idle", "run_id": None, "since": since, "message": "run stopped"})
    page.wait_state("idle", 10)


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}px")
def test_the_tables_of_a_waiting_run_fit_their_cards(broker, dashboard, browsers, size):
    """At 390 px the manual setting's bands and the drives' Fault column ran past their cards' edges (the
    cards' padding, at a laptop's width, left the tables too little room)."""
    d = browsers()
    d.set_window_size(*size)
    page = Page(d, dashboard.url, dashboard)
    page.sign_in("operator", ACCOUNTS["operator"])
    page.signed_in()
    publish_as_service(broker, "status", waiting())  # every measured value outside its band: the panel at its widest
    publish_as_service(broker, "progress", PROGRESS, qos=0)
    page.wait(lambda: page.el("manual").is_displayed(), 10, "the manual setting panel")
    publish_as_service(broker, "live", live(), qos=0)
    page.wait(lambda: page.rows("drives", "drive").get("spin", "").startswith("spin\t1000"), 10, "the drives' values")
    assert d.execute_script(OUTSIDE_CARDS) == []
    assert d.execute_script(OUTSIDE_WINDOW) == []
    since = "2026-01-05T13:00:00.000Z"
    publish_as_service(broker, "status", {"state": "idle", "run_id": None, "since": since, "message": "run stopped"})
    page.wait_state("idle", 10)
