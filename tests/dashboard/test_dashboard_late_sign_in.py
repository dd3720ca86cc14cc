"""A shift change in a real chromium against a real authenticated mosquitto and `orbitrig serve
--sim`: someone who signs in while the run waits for the operator's manual setting of its second
point sees where the run is (point, orbit block, ETA, the bar), although the service sends no
progress until that setting is confirmed: the retained status names the run's latest progress
(docs/protocols/mqtt.md); the progress itself is not retained."""

from __future__ import annotations

import re

import pytest
from support.dash_helpers import RIG, Page, ServiceHolder
from support.mqtt_helpers import ACCOUNTS, RigClient, retained, two_pressures


@pytest.fixture(scope="module")
def service(broker, tmp_path_factory):
    work = tmp_path_factory.mktemp("serve")
    (work / "matrices").mkdir()
    (work / "matrices" / "two.toml").write_text(two_pressures("two"))
    holder = ServiceHolder(broker, work, matrices=work / "matrices")
    yield holder
    holder.proc.stop()


@pytest.fixture
def waiting(broker, service):
    """The run of `two` waiting for the second point's manual setting: that status."""
    rig = RigClient(broker, RIG, service)
    try:
        rig.ready(lambda s: s["state"] in ("idle", "faulted"))
        mark = rig.watch.mark()
        assert rig.command({"cmd": "start", "matrix": "two"})["ok"] is True
        rig.status(lambda s: s.get("step") == "manual:0000", start=mark)
        assert rig.command({"cmd": "confirm", "step": "manual:0000"})["ok"] is True
        yield rig.status(lambda s: s.get("step") == "manual:0001", start=mark, timeout=60)
        mark = rig.watch.mark()
        assert rig.command({"cmd": "abort"})["ok"] is True
        rig.status("idle", start=mark, timeout=30)
    finally:
        rig.close()


def test_who_signs_in_while_the_run_waits_sees_its_point_and_block(broker, dashboard, waiting, browsers):
    assert retained(broker, f"orbitrig/{RIG}/progress", wait=1.0) is None  # the page has the status's alone
    page = Page(browsers(), dashboard.url, dashboard)  # a new session: its own broker connection
    page.sign_in("viewer", ACCOUNTS["viewer"])
    page.signed_in()
    page.wait_state("waiting")
    page.wait_text("point", "2 / 2", 10)
    assert page.text("block") == "0 of 2"  # the point's first block not begun
    assert page.text("point-label") == waiting["point_label"]
    assert re.fullmatch(r"\d+:\d\d", page.text("eta")), page.text("eta")
    bar = page.d.execute_script("return document.getElementById('progress-bar').style.width")
    assert bar == "50%", bar  # point 1 of 2 measured

    page.d.refresh()  # a page loaded again in that session: the same, from the server's snapshot
    page.signed_in()
    page.wait_text("point", "2 / 2", 10)
    assert page.text("block") == "0 of 2"
    assert re.fullmatch(r"\d+:\d\d", page.text("eta")), page.text("eta")
    bar = page.d.execute_script("return document.getElementById('progress-bar').style.width")
    assert bar == "50%", bar
