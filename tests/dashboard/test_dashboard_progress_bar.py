"""The Run card's progress bar in a real chromium on a real authenticated mosquitto shows how much
of the run is measured as the run engine counts it (ProgressEvent.fraction, the progress payload's
`fraction`): a block whose acquisition is done counts whole, so at the end of point 1 of 3 the bar
stands at a third, not at a quarter (the last of four blocks counted as unfinished); the Revolutions
cell says the block's count of its target (`block_revolutions`: "25 of 50"), the Orbit block cell the
block under way of the point's blocks ("4 of 4"). The test
drives the engine's own ProgressMeter and publishes its payloads as the rig service does."""

from __future__ import annotations

import io
import json

import pytest
from support.dash_helpers import Page, dashboard_running, publish_as_service
from support.mqtt_helpers import ACCOUNTS

import orbitrig.service.protocol as proto
from orbitrig.cli.progress import SweepProgress
from orbitrig.cli.terminal import TerminalConsole
from orbitrig.run.events import ProgressEvent
from orbitrig.run.progress import ProgressMeter
from orbitrig.run.rig_io import TimeScale

BLOCKS, REVOLUTIONS = 4, 50


@pytest.fixture(scope="module")
def dashboard(broker, tmp_path_factory):
    """The dashboard alone on the broker: the test publishes what the rig service would."""
    with dashboard_running(broker.url, tmp_path_factory.mktemp("dashboard")) as dash:
        yield dash


def bar(page: Page) -> str:
    return page.d.execute_script("return document.getElementById('progress-bar').style.width")


def test_the_bar_counts_a_block_acquired_as_measured(broker, dashboard, browsers):
    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in("viewer", ACCOUNTS["viewer"])
    page.signed_in()
    page.wait_text("link", "online")
    status = {"state": "running", "run_id": "r-bar", "since": "2026-01-07T08:00:00.000Z", "message": "started"}
    publish_as_service(broker, "status", status, retain=True)
    page.wait_state("running", 10)

    sent: list[ProgressEvent] = []
    meter = ProgressMeter(sent.append, TimeScale(), every=0.0)
    meter.start("r-bar", 3, 600.0)
    meter.next_point(BLOCKS, "w1000rpm")

    def publish(ev: ProgressEvent) -> dict:
        body = json.loads(proto.progress_payload(ev))
        publish_as_service(broker, "progress", body, qos=0)
        return body

    for block in range(1, BLOCKS + 1):
        meter.block(block, REVOLUTIONS)
        for _ in range(REVOLUTIONS // 2 if block == 2 else REVOLUTIONS):
            meter.revolution()
        if block == 2:  # half of the second block's revolutions: 1.5 blocks of 4 of point 1 of 3
            body = publish(sent[-1])
            assert (body["block_revolutions"], body["fraction"]) == (REVOLUTIONS, 0.125), body
            page.wait(lambda: bar(page) == "12.5%", 10, "the bar at 1.5 blocks of 4 of point 1 of 3")
            assert page.text("revolutions") == f"{REVOLUTIONS // 2} of {REVOLUTIONS}"  # the block's count of its target
            for _ in range(REVOLUTIONS // 2):
                meter.revolution()
        meter.block_acquired()

    last = sent[-1]
    assert (last.point, last.frequency, last.revolutions, last.acquired, last.blocks_done) == (1, 4, 50, True, 4)
    body = publish(last)
    assert body["fraction"] == pytest.approx(1 / 3, abs=1e-4), body
    page.wait(lambda: bar(page) == "33.3%", 10, "the bar at point 1 of 3 measured")
    assert page.text("block") == "4 of 4" and page.text("point") == "1 / 3"
    # the count is of the point's blocks (orbit frequency x whirl direction), not of frequencies: named so
    # beside the orbit frequency, in the words of the terminal's bar (orbitrig.cli.progress)
    head = page.d.execute_script("return document.getElementById('block').previousElementSibling.textContent")
    bars = [t.description for t in SweepProgress(TerminalConsole(file=io.StringIO())).progress.tasks]
    assert head == "Orbit block" and "orbit blocks" in bars and "frequencies" not in bars, (head, bars)

    meter.spent(10.0)  # the step's end: nothing left unsent
    meter.next_point(BLOCKS, "w2000rpm")  # point 2 starts: still a third
    body = publish(sent[-1])
    assert (body["point"], body["frequency"], body["fraction"]) == (2, 0, pytest.approx(1 / 3, abs=1e-4))
    page.wait(lambda: page.text("point") == "2 / 3", 10, "point 2")
    assert bar(page) == "33.3%"
    assert (body["block_revolutions"], page.text("revolutions")) == (0, "0")  # no block yet: no target to name
