"""The Run card's state badge and the Commands card's buttons follow the rig's status, in a real
chromium on a real authenticated mosquitto. The test publishes the statuses the rig service does
(as orbitrig-service, in its words: orbitrig.run.control): an interlock's suspension is told from
an operator's pause at a glance ("suspended: interlock" in the alarm colour); Start, Pause and
Resume are disabled, their tooltip saying why, where they cannot apply, and while the dashboard
server would not send them (the service offline, its own broker link down); Stop and ABORT never are."""

from __future__ import annotations

import datetime as dt
import json

import pytest
from support.dash_helpers import RIG, Page, dashboard_running, publish_as_service
from support.mqtt_helpers import ACCOUNTS

RUN = "sim-rig@2026-12-07T04:00:00.000Z"
CAN = "suspended by interlock: CAN sensor node lost (no heartbeat 0x701 for 1.5 s)"
ALARM_RED, PAUSE_YELLOW = "rgb(198, 40, 40)", "rgb(249, 168, 37)"
BUTTONS = ("btn-start", "btn-pause", "btn-resume", "btn-stop", "btn-abort")


@pytest.fixture(scope="module")
def dashboard(relay, tmp_path_factory):
    """The dashboard alone on the broker, through a relay the test can cut."""
    with dashboard_running(relay.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


@pytest.fixture
def page(browsers, dashboard) -> Page:
    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in("operator", ACCOUNTS["operator"])
    page.signed_in()
    page.wait_text("link", "online")
    return page


def status(broker, state: str, message: str, since: str, run_id: str | None = RUN, **extra) -> None:
    body = {"state": state, "run_id": run_id, "since": since, "message": message, **extra}
    publish_as_service(broker, "status", body, retain=True)


def badge(page: Page) -> tuple[str, str]:
    """The badge's text and background colour."""
    return page.d.execute_script(
        "const b = document.getElementById('state'); return [b.textContent, getComputedStyle(b).backgroundColor];"
    )


def buttons(page: Page) -> dict[str, str]:
    """{button: "on", or the tooltip of a disabled one}."""
    return page.d.execute_script(
        "const out = {}; arguments[0].forEach(id => { const b = document.getElementById(id);"
        " out[id] = b.disabled ? b.title : 'on'; }); return out;",
        list(BUTTONS),
    )


def test_the_badge_tells_an_interlocks_suspension_from_an_operators_pause(broker, page):
    status(broker, "running", "measuring point 1 of 2: w1000rpm (point 0000)", "2026-12-07T04:00:01.000Z")
    page.wait(lambda: badge(page)[0] == "running", 10, "running")
    status(broker, "paused", "paused at a safe point (by ada)", "2026-12-07T04:00:02.000Z")
    page.wait(lambda: badge(page) == ["paused", PAUSE_YELLOW], 10, "the operator's pause")
    status(broker, "paused", CAN, "2026-12-07T04:00:03.000Z")
    page.wait(lambda: badge(page) == ["suspended: interlock", ALARM_RED], 10, "the suspension")
    assert page.text("message") == CAN  # the message says the cause, whole
    status(broker, "running", "interlock cleared (can_heartbeat): settling", "2026-12-07T04:00:04.000Z")
    page.wait(lambda: badge(page)[0] == "running", 10, "running again")


def selector(page: Page) -> list[str]:
    """The header's rig selector's options as shown."""
    return page.d.execute_script("return [...document.getElementById('rig-select').options].map(o => o.text)")


def test_the_rig_selector_says_the_state_in_the_badges_words(broker, page):
    """The header's rig selector words a rig's state as the badge does: a suspension is
    `suspended: interlock` there too (before the mend: `dash-rig (paused)` beside the badge's words),
    an operator's pause `paused`, another rig's suspension (its own retained status) the same."""
    status(broker, "paused", "paused at a safe point (by ada)", "2026-12-07T04:00:11.000Z")
    page.wait(lambda: f"{RIG} (paused)" in selector(page), 10, "the operator's pause listed")
    status(broker, "paused", CAN, "2026-12-07T04:00:12.000Z")
    page.wait(lambda: badge(page)[0] == "suspended: interlock", 10, "the suspension on the badge")
    page.wait(lambda: f"{RIG} (suspended: interlock)" in selector(page), 10, "the suspension listed")
    other = {"state": "paused", "run_id": "r-other", "since": "2026-12-07T04:00:13.000Z", "message": CAN}
    done = broker.pub("orbitrig/rig-s/status", json.dumps(other), user="orbitrig-service", retain=True)
    assert done.returncode == 0, done.stderr
    try:
        page.wait(lambda: "rig-s (suspended: interlock)" in selector(page), 10, "another rig's suspension listed")
    finally:
        broker.pub("orbitrig/rig-s/status", "", user="orbitrig-service", retain=True)  # clears the retained
    status(broker, "running", "interlock cleared (can_heartbeat): settling", "2026-12-07T04:00:14.000Z")
    page.wait(lambda: f"{RIG} (running)" in selector(page), 10, "running again")


def test_the_badge_says_a_pause_asked_elsewhere_of_a_waiting_run(broker, page):
    """A pause another operator asked while the run waits for a manual setting (the service says it in the
    waiting status) is on the badge before the run pauses, with who asked; a resume withdrawing it clears it."""
    asking = "set by hand and confirm: orbit radius 5.76 µm (confirm step 'manual:0001')"
    status(broker, "waiting", asking, "2026-12-07T04:00:05.000Z")
    page.wait(lambda: badge(page)[0] == "waiting", 10, "waiting")
    asked = f"{asking}; pause requested by ada: the run pauses once manual:0001 is confirmed"
    status(broker, "waiting", asked, "2026-12-07T04:00:05.000Z")
    page.wait(lambda: badge(page)[0] == "waiting — pause requested by ada", 10, "the pause asked elsewhere")
    assert page.state() == "waiting" and buttons(page)["btn-resume"] == "on"  # a resume withdraws it
    status(broker, "waiting", asking, "2026-12-07T04:00:05.000Z")
    page.wait(lambda: badge(page)[0] == "waiting", 10, "the pause withdrawn")


def test_the_badge_says_a_pause_asked_elsewhere_of_a_suspended_run(broker, page):
    """A pause another supervisor asked during an interlock's suspension (the service says it in the suspension's
    status, said again) is on the badge with who asked, and Resume is enabled (it withdraws the pause); the
    suspension is one event and one alarm in its own words, also when the first status seen says the pause;
    a resume withdrawing it clears it from the badge."""
    since = "2026-12-07T04:00:06.000Z"
    asked = f"{CAN}; pause requested by ada: the run stays paused once the interlock clears"
    status(broker, "paused", asked, since)  # the first the page and the alarm book see of the suspension
    page.wait(lambda: badge(page) == ["suspended: interlock — pause requested by ada", ALARM_RED], 10, "the pause")
    assert page.text("message") == asked  # the message says the cause and the pause, whole
    assert buttons(page)["btn-resume"] == "on" and buttons(page)["btn-pause"] == "on"
    status(broker, "paused", CAN, since)  # a resume withdrew it: the same status said again without it
    page.wait(lambda: badge(page) == ["suspended: interlock", ALARM_RED], 10, "the pause withdrawn")
    assert buttons(page)["btn-resume"] == "not now: suspended by interlock: the run resumes by itself when that clears"
    status(broker, "paused", asked, since)
    page.wait(lambda: badge(page)[0] == "suspended: interlock — pause requested by ada", 10, "asked again")
    listed = page.d.execute_script(
        "return [...document.querySelectorAll('#events li')].map(li => li.dataset.text).filter(t => t.includes(arguments[0]))",
        CAN,
    )
    assert listed == [f"paused: {CAN}"]  # one event: the suspension's own words
    row = "const r = [...document.querySelectorAll('#alarms tr')].find(r => r.dataset.alarm === arguments[0]);"
    page.wait(lambda: page.d.execute_script(row + " return !!r;", f"{RUN}@{since}"), 10, "the alarm listed")
    alarm = page.d.execute_script(row + " return r.innerText;", f"{RUN}@{since}")
    assert CAN.split(": ", 1)[1] in alarm and "pause" not in alarm, alarm


def local(iso: str, form: str) -> str:
    """``iso`` (UTC) in the local time of the page (the browser runs in this process's time zone)."""
    return dt.datetime.fromisoformat(iso.replace("Z", "+00:00")).astimezone().strftime(form)


def test_the_badge_says_how_and_when_the_last_run_ended(broker, page):
    now = dt.datetime.now(dt.timezone.utc)
    ended = now.isoformat(timespec="milliseconds").replace("+00:00", "Z")
    today = local(ended, "%H:%M")  # the run ended today: the time alone
    status(broker, "running", "measuring point 2 of 2: w1000rpm (point 0001)", ended)
    page.wait(lambda: badge(page)[0] == "running", 10, "running: the state alone")
    where = "return ['run-id', 'message'].map(id => document.getElementById(id).getBoundingClientRect().top)"
    before = page.d.execute_script(where)
    for message, outcome in (
        ("run completed; warning: kc8, piezo: condition number 3.1e6 at 1 of 2 points (0) - Kxy", "completed"),
        ("run aborted: aborted by ada; point 0001 (2 of 20 blocks stored) is incomplete", "aborted"),
        ("run of 'demo' cancelled; its drives' closing stop: standstill confirmed", "ended"),
    ):
        status(broker, "idle", message, ended)
        page.wait(lambda o=outcome: badge(page)[0] == f"idle — last run {o} {today}", 10, f"idle after {outcome}")
        assert page.state() == "idle"
        assert page.d.execute_script(where) == before  # the longer badge moves nothing in the card
    assert page.el("state").get_attribute("title") == f"the last run ended at {local(ended, '%Y-%m-%d %H:%M:%S')}"
    status(broker, "faulted", "run of 'demo' failed: drive fault", ended)
    page.wait(lambda: badge(page) == [f"faulted — last run failed {today}", ALARM_RED], 10, "faulted")
    # after a restart the ready status says how the store recorded the last run (another day: with its date)
    before = (now - dt.timedelta(days=2)).isoformat(timespec="milliseconds").replace("+00:00", "Z")
    last = {"run_id": RUN, "outcome": "stopped", "message": "stopped by ada", "folder": "/runs/x", "ended_at": before}
    status(broker, "idle", "service ready", ended, None, last_run=last)
    page.wait(lambda: badge(page)[0] == f"idle — last run stopped {local(before, '%Y-%m-%d %H:%M')}", 10, "ready")
    odd = "2026-13-45T99:00:00.000Z"  # an end the browser cannot read as a time: said as it came, not dropped
    status(broker, "idle", "service ready", ended, None, last_run={**last, "ended_at": odd})
    page.wait(lambda: badge(page)[0] == "idle — last run stopped", 10, "an unreadable end: no time on the badge")
    assert page.el("state").get_attribute("title") == f"the last run stopped at {odd}"
    assert page.text("last-run") == f"last run {RUN} stopped at {odd}, folder /runs/x"
    status(broker, "idle", "service ready", ended, None, last_run=None)  # no run in the runs folder
    page.wait(lambda: badge(page)[0] == "idle", 10, "idle alone")


IDLE_ON = {"btn-start": "on", "btn-stop": "on", "btn-abort": "on"}
NOT_NOW_OFFLINE = "not now: the rig service is offline: the dashboard sends it only STOP and ABORT"
NOT_NOW_NO_BROKER = "not now: the dashboard has no connection to the broker: try again when it is back"
UNDER_WAY = "not now: a run is under way ({}): stop or abort it before starting another"
STATES = [  # (state, message, run, the buttons)
    (
        "idle",
        "service ready",
        None,
        {
            **IDLE_ON,
            "btn-pause": "not now: no run is under way (idle)",
            "btn-resume": "not now: no run is under way (idle)",
        },
    ),
    (
        "running",
        "measuring point 1 of 2",
        RUN,
        {"btn-start": UNDER_WAY.format("running"), "btn-pause": "on", "btn-resume": "not now: the run is not paused"},
    ),
    (
        "waiting",
        "set manual:0001",
        RUN,
        {"btn-start": UNDER_WAY.format("waiting"), "btn-pause": "on", "btn-resume": "not now: the run is not paused"},
    ),
    (
        "waiting",
        "set manual:0001; pause requested by ada: the run pauses once manual:0001 is confirmed",
        RUN,
        {"btn-start": UNDER_WAY.format("waiting"), "btn-pause": "on", "btn-resume": "on"},
    ),  # a resume withdraws it
    (
        "paused",
        "paused at a safe point (by ada)",
        RUN,
        {
            "btn-start": UNDER_WAY.format("paused"),
            "btn-pause": "not now: the run is paused: resume to go on",
            "btn-resume": "on",
        },
    ),
    (
        "paused",
        CAN,
        RUN,
        {
            "btn-start": UNDER_WAY.format("paused"),
            "btn-pause": "on",
            "btn-resume": "not now: suspended by interlock: the run resumes by itself when that clears",
        },
    ),
    (
        "stopping",
        "stopping: stopped by ada",
        RUN,
        {
            "btn-start": UNDER_WAY.format("stopping"),
            "btn-pause": "not now: the run is stopping",
            "btn-resume": "not now: the run is stopping",
        },
    ),
    (
        "faulted",
        "run of 'demo' failed: drive fault",
        RUN,
        {
            **IDLE_ON,
            "btn-pause": "not now: no run is under way (faulted)",
            "btn-resume": "not now: no run is under way (faulted)",
        },
    ),
    # the dashboard server would send none of them ("not sent: the rig service is offline"): disabled, not enabled
    # for a click that can only be refused
    ("offline", "rig service stopped", None, dict.fromkeys(BUTTONS[:3], NOT_NOW_OFFLINE)),
]


def test_the_buttons_that_cannot_apply_are_disabled_and_say_why(broker, relay, page):
    for n, (state, message, run, expected) in enumerate(STATES):
        want = {"btn-stop": "on", "btn-abort": "on", **expected}  # never disabled
        status(broker, state, message, f"2026-12-07T04:01:{n:02d}.000Z", run)
        page.wait(lambda m=message, w=want: page.text("message") == m and buttons(page) == w, 10, f"{state}: {want}")

    status(broker, "running", "measuring point 1 of 2", "2026-12-07T04:02:00.000Z")
    page.wait(lambda: buttons(page)["btn-start"] != "on", 10, "start disabled while running")
    relay.cut()  # the dashboard server sends nothing but STOP and ABORT until its link is back
    try:
        want = {**dict.fromkeys(BUTTONS[:3], NOT_NOW_NO_BROKER), "btn-stop": "on", "btn-abort": "on"}
        page.wait(lambda: buttons(page) == want, 15, "start, pause and resume disabled, the link down")
    finally:
        relay.restore()
    page.wait_text("link", "online", 30)
    page.wait(lambda: buttons(page)["btn-start"] != "on", 10, "start disabled again")
