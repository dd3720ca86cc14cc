"""The real `orbitrig serve --sim` under a real mosquitto: nothing old in the live view.

- A manual setting is `measured` only from what the rig measures now: at the next point's
  wait, with both drives at standstill for the new orbit radius, the previous point's
  radius is not reported (the status and the live `settings_measured` say null).
- `orbit_hz` comes from the revolutions coming now only: null while the orbit drive
  stands, and never far from the orbit drive's actual speed.
- The live bands are the point being set up: right after the confirmation of the next
  point (the run held there by a pause), its recess pressure band, not the previous one's.
- In process (a RunEngine on the simulator, its LiveFeed): a verification that missed the
  orbit radius stops the drives for the hands; the radius it measured is not measured now.
"""

from __future__ import annotations

import math
import time

import pytest

from orbitrig import config as cfg
from orbitrig.run.plan import make_plan
from orbitrig.service import live as live_feed
from support.mqtt_helpers import MATRIX, RigClient, serving_sim, two_pressures
from support.sweep_helpers import running, small_matrix, wait_for

RIG = "fresh-rig"
#: two points differing in the orbit radius only (dynamic eccentricity 0.04, then 0.096):
#: both drives ramp to a confirmed standstill before the second (orbitrig.run.plan). 40
#: revolutions a block: about 0.2 s of wall time each at the service's speed-up, so the live
#: feed (every 0.2 s) sends during each block; the orbit frequency is current only then
#: (10 revolutions, 50 ms a block, sent during none of the four once the poll read each new
#: REF at once)
RADIUS = MATRIX.format(name="radius2", revs=40, ratios="[0.5, 0.8]", directions='["forward"]').replace(
    "dynamic_eccentricity = [0.096]", "dynamic_eccentricity = [0.04, 0.096]"
)
PRESSURE = two_pressures("pressure2")  # the drives keep turning between its points


@pytest.fixture(scope="module")
def service(broker, tmp_path_factory):
    yield from serving_sim(broker, tmp_path_factory, RIG, radius2=RADIUS, pressure2=PRESSURE)


@pytest.fixture
def rig(broker, service):
    rc = RigClient(broker, RIG, service)
    rc.ready(lambda s: s["state"] in ("idle", "faulted"))
    yield rc
    if service.proc.poll() is None and rc.watch.on("status")[-1].json()["state"] not in ("idle", "faulted"):
        mark = rc.watch.mark()
        rc.command({"cmd": "abort"})
        rc.status("idle", timeout=30, start=mark)
    rc.close()


def waiting_for(rig: RigClient, step: str, start: int, timeout: float = 90.0) -> dict:
    return rig.status(lambda s: s["state"] == "waiting" and s.get("step") == step, timeout, start=start)


def lives_for(rig: RigClient, seconds: float, start: int) -> list[dict]:
    """The live payloads from message `start` on, at least `seconds` s of them (5 a second)."""
    t0 = time.monotonic()
    rig.watch.wait_for(lambda m: m.t > t0 + seconds, seconds + 10, start=start, what=f"{seconds} s of messages")
    return [m.json() for m in rig.watch.on("live", start)]


def orbit_rpm(live: dict) -> float:
    return abs(live["drives"]["orbit"]["actual_rpm"])


@pytest.fixture(scope="module")
def radius_run(broker, service) -> dict:
    """A whole run of radius2, held at the second point's wait for 1.5 s: that wait's status,
    the live payloads sent during it, and every live payload of the run."""
    rig = RigClient(broker, RIG, service)
    try:
        rig.ready(lambda s: s["state"] in ("idle", "faulted"))
        mark = rig.watch.mark()
        assert rig.command({"cmd": "start", "matrix": "radius2"})["ok"] is True
        waiting_for(rig, "manual:0000", mark)
        assert rig.command({"cmd": "confirm", "step": "manual:0000"})["ok"] is True
        second = waiting_for(rig, "manual:0001", mark)
        m1 = rig.watch.mark()
        waited = [v for v in lives_for(rig, 1.5, m1) if "settings_measured" in v]  # sent while waiting
        assert rig.command({"cmd": "confirm", "step": "manual:0001"})["ok"] is True
        idle = rig.status("idle", start=mark, timeout=90)
        assert "completed" in idle["message"], idle
        return {"waiting": second, "waited": waited, "lives": [m.json() for m in rig.watch.on("live", mark)]}
    finally:
        rig.close()


def test_the_previous_points_radius_is_not_measured_now(radius_run):
    second = radius_run["waiting"]
    # the second point's orbit radius is set by hand with both drives at standstill
    assert "both drives at standstill" in second["message"], second
    settings = second["settings"]
    assert math.isclose(settings["orbit_radius"]["value"], 0.096 * 60e-6), settings  # the new radius asked
    assert settings["orbit_radius"]["measured"] is None, settings  # no revolution since: nothing measured now
    assert settings["static_eccentricity"]["measured"] is None, settings
    assert settings["recess_pressure"]["measured"] > 0.0, settings  # the CAN node's pressures: measured now
    assert len(radius_run["waited"]) >= 4, radius_run["waited"]
    for live in radius_run["waited"]:
        measured = live["settings_measured"]  # the page's manual panel follows these
        assert measured["orbit_radius"] is None and measured["static_eccentricity"] is None, measured
        assert measured["recess_pressure"] > 0.0, measured


def test_no_orbit_frequency_but_from_the_revolutions_coming_now(radius_run):
    assert len(radius_run["waited"]) >= 4, radius_run["waited"]
    for live in radius_run["waited"]:
        assert orbit_rpm(live) == 0.0, live["drives"]  # the orbit drive stands ...
        assert live["orbit_hz"] is None, live["orbit_hz"]  # ... so no orbit frequency
    # the whole run, the final stop included: an orbit frequency only with the orbit drive at it
    lives = radius_run["lives"]
    hz = [(v["orbit_hz"], orbit_rpm(v)) for v in lives if v["orbit_hz"] is not None]
    assert hz, "no orbit frequency published during the blocks"
    assert all(abs(f * 60.0 - rpm) <= 0.05 * rpm for f, rpm in hz), hz
    assert all(v["orbit_hz"] is None for v in lives if orbit_rpm(v) == 0.0)


def test_the_bands_are_the_point_being_set_up(rig):
    mark = rig.watch.mark()
    assert rig.command({"cmd": "start", "matrix": "pressure2"})["ok"] is True
    first = waiting_for(rig, "manual:0000", mark)
    assert rig.command({"cmd": "confirm", "step": "manual:0000"})["ok"] is True
    second = waiting_for(rig, "manual:0001", mark)
    before, now = first["settings"], second["settings"]
    assert before["recess_pressure"]["band"] != now["recess_pressure"]["band"], (before, now)

    # held right after the confirmation (a pause is honoured at the next safe point): the
    # second point is being set up, its first block not begun
    assert rig.command({"cmd": "pause"})["ok"] is True
    m2 = rig.watch.mark()
    assert rig.command({"cmd": "confirm", "step": "manual:0001"})["ok"] is True
    rig.status("paused", start=m2)
    m3 = rig.watch.mark()
    lives = lives_for(rig, 1.5, m3)
    assert len(lives) >= 4, lives
    for live in lives:
        assert live["bands"]["p_recess"] == now["recess_pressure"]["band"], (live["bands"], now)
        assert live["bands"]["beta"] == now["pressure_ratio"]["band"], (live["bands"], now)
    # the drives turned on (the orbit radius stays): the previous point's geometry was not this one's
    assert "the drives are turning" in second["message"], second
    assert now["orbit_radius"]["measured"] is None and now["static_eccentricity"]["measured"] is None, now
    assert rig.command({"cmd": "abort"})["ok"] is True
    rig.status("idle", start=mark, timeout=30)


async def test_a_missed_radius_is_not_measured_while_the_hands_correct_it(tmp_path):
    matrix = small_matrix(revolutions=6)
    async with running(tmp_path, matrix, confirm_mode="remote") as (sim, eng, rec, run):
        feed = live_feed.attach(eng, make_plan(matrix, cfg.load_rig()), lambda payload: None)
        assert feed is not None
        hands = eng.access.hands
        real = hands.set_manual

        async def mistaken(**settings):  # the operator's slip: 1.3 x the orbit radius asked
            return await real(**{**settings, "orbit_radius": 1.3 * settings["orbit_radius"]})

        hands.set_manual = mistaken
        await wait_for(lambda: eng.waiting_step == "manual:0000", what="the point's settings")
        eng.confirm("manual:0000")
        await wait_for(lambda: eng.waiting_step == "verify:0000", what="the verification prompt", timeout=90)
        assert "orbit radius 7." in eng.message and "both drives at standstill" in eng.message, eng.message
        settings = feed.waiting_fields("waiting")["settings"]
        assert settings["orbit_radius"]["measured"] is None, settings  # the block's radius, before the drives stopped
        assert settings["static_eccentricity"]["measured"] is None, settings
        assert settings["recess_pressure"]["measured"] > 0.0, settings
        live = feed.payload()
        assert live["settings_measured"]["orbit_radius"] is None, live["settings_measured"]
        assert live["orbit_hz"] is None and live["drives"]["orbit"]["actual_rpm"] == 0.0, live["drives"]
