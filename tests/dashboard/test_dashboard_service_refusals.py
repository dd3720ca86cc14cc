"""A command the rig service refuses (a start with no such matrix) is
shown in a real chromium, against a real authenticated mosquitto and `orbitrig serve --sim`, as a
refusal an operator notices: the mark, the word REFUSED and who refused it before the service's
reason, in a box of its own (not a plain line of red text), listed under Warnings and refusals, and
said so again on a page loaded later; a start while a run is active is not sent (the button
disabled, saying why). Every outcome says when it came."""

from __future__ import annotations

import re

from support.dash_helpers import Page, idle_page

REFUSED = "✖ start: REFUSED by the rig service: "


def start(page: Page, matrix: str) -> str:
    page.el("matrix").clear()
    page.el("matrix").send_keys(matrix)
    return page.command("btn-start", "start")


def boxed(page: Page) -> tuple[str, str]:
    """The outcome line's background colour and left border width: a box, not plain text."""
    return tuple(
        page.d.execute_script(
            "const s = getComputedStyle(document.getElementById('cmd-result'));"
            "return [s.backgroundColor, s.borderLeftWidth];"
        )
    )


def test_the_services_refusals_are_shown_as_refusals_with_their_reason(dashboard, service, browsers):
    page = idle_page(browsers, dashboard)
    assert boxed(page) == ("rgba(0, 0, 0, 0)", "0px")  # nothing boxed before a refusal

    bad = start(page, "nosuch")
    reason = "no matrix 'nosuch' in the matrix folder (available: demo, designed, eccentricity, paper)"
    assert bad == REFUSED + reason, bad
    assert "by-service" in page.el("cmd-result").get_attribute("class")
    assert boxed(page) == ("rgb(255, 235, 238)", "4px")
    assert page.text("events").splitlines()[0].endswith("✖ start: REFUSED by the rig service: " + reason)
    page.wait_state("idle", 5)  # nothing started

    page.d.refresh()  # a page loaded later shows the session's latest outcome, still as a refusal
    page.signed_in()
    shown = page.wait_text("cmd-result", lambda t: t != "", 10)
    assert shown == REFUSED + reason + " (before this page was loaded)", shown  # its time on the line under it
    assert boxed(page) == ("rgb(255, 235, 238)", "4px")

    try:
        assert start(page, "demo") == "start: accepted"
        assert boxed(page) == ("rgba(0, 0, 0, 0)", "0px")  # an accepted command is not boxed
        page.wait_state("waiting")
        # a second start cannot apply: not sent, the button says why (a page whose state is not known sends
        # it, and the service refuses it: "a run is active (run R, state waiting): ...")
        page.wait(lambda: not page.el("btn-start").is_enabled(), 10, "start disabled")
        assert page.el("btn-start").get_attribute("title") == (
            "not now: a run is under way (waiting): stop or abort it before starting another"
        )
    finally:
        assert "accepted" in page.command("btn-abort", "abort:")
        page.wait_state("idle")


def test_an_outcome_says_when_it_came_also_after_a_reload(dashboard, service, browsers):
    """An outcome stays shown until the next command, hours later too (after an abort, across a service
    restart): the line under it says when it came, so that an old "abort: accepted" is not read as now."""
    page = idle_page(browsers, dashboard)
    assert "no matrix 'nosuch'" in start(page, "nosuch")
    when = page.text("cmd-when")
    clock = page.d.execute_script("return new Date().toTimeString().slice(0, 8)")
    assert re.fullmatch(r"at \d\d:\d\d:\d\d", when), when
    seconds = [sum(int(p) * f for p, f in zip(t.split(":"), (3600, 60, 1))) for t in (when[3:], clock)]
    assert 0 <= (seconds[1] - seconds[0]) % 86400 <= 3, (when, clock)
    page.d.refresh()  # the session's kept outcome, with the time it came, not the time of the reload
    page.signed_in()
    page.wait_text("cmd-when", when, 10)
