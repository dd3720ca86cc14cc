"""The page's ABORT with no run holding the drives, against a real authenticated mosquitto and
`orbitrig serve --sim` in headless chromium: the service sends both drives the emergency stop
over a link of its own (it knows the rig's drives from the start), and the page says what was
sent, in the command's outcome and in the event list, not a bare "accepted"."""

from __future__ import annotations

from support.dash_helpers import idle_page

SENT = "emergency stop (OFF3) sent to both drives over a link of the service's own (no run held them)"


def test_an_abort_with_no_run_says_the_emergency_stop_was_sent(dashboard, service, browsers):
    page = idle_page(browsers, dashboard)
    outcome = page.command("btn-abort", "abort:")
    assert outcome == f"abort: accepted: {SENT}", outcome
    assert f"abort: {SENT}" in page.text("events")
    assert "abort: no run holds the drives: emergency stop (OFF3) to both" in service.proc.text()
