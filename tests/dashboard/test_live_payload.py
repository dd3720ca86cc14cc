"""The service's side of the live view, on the wire (real mosquitto, `orbitrig
serve --sim`): `step` + `settings` on the waiting status, and `live` with the
spec's fields, at most 5 per second, one averaged revolution per channel in SI.
Plus the pure helpers of orbitrig.service.live against hand-checkable numbers."""

from __future__ import annotations

import math

import numpy as np

from support.dash_helpers import RIG
from support.mqtt_helpers import RigClient

from orbitrig.service.live import RevolutionAverage, _geometry

LIVE_KEYS = {
    "run_id",
    "point",
    "frequency",
    "direction",
    "revolutions",
    "orbit_hz",
    "spin_rpm",
    "drives",
    "aux",
    "waveforms",
    "units",
}
CHANNELS = ["fx_piezo", "fy_piezo", "fx_strain", "fy_strain", "x_a", "y_a", "x_b", "y_b"]


def test_waiting_status_and_live_topic(broker, service):
    rc = RigClient(broker, RIG)
    try:
        rc.status("idle", 60)
        mark = rc.watch.mark()
        assert rc.command({"cmd": "start", "matrix": "demo"})["ok"]
        waiting = rc.status("waiting", 60, start=mark)
        assert waiting["step"] == "manual:0000"
        settings = waiting["settings"]
        assert set(settings) == {"orbit_radius", "static_eccentricity", "recess_pressure", "pressure_ratio"}
        assert all(set(v) == {"value", "unit", "measured", "band"} for v in settings.values())
        assert settings["pressure_ratio"]["band"] == [
            settings["pressure_ratio"]["value"] - 0.05,
            settings["pressure_ratio"]["value"] + 0.05,
        ]
        assert (
            math.isclose(settings["orbit_radius"]["value"], 0.096 * 60e-6) and settings["orbit_radius"]["unit"] == "m"
        )
        assert (
            math.isclose(settings["recess_pressure"]["value"], 0.4826e6) and settings["recess_pressure"]["unit"] == "Pa"
        )
        assert rc.command({"cmd": "confirm", "step": "manual:0000"})["ok"]

        first = rc.watch.wait_for(
            lambda m: m.topic.endswith("/live") and len(m.json()["waveforms"]) == 8 and m.json()["revolutions"] >= 10,
            60,
            start=mark,
            what="live with waveforms",
        )
        n0 = rc.watch.mark()
        rc.watch.wait_for(lambda m: m.t > first.t + 3.0, 10, start=n0, what="3 s of messages")
        lives = [m for m in rc.watch.on("live", n0 - 1) if m.t <= first.t + 3.0]
        span = lives[-1].t - lives[0].t
        assert len(lives) >= 8, f"only {len(lives)} live messages in {span:.1f} s"
        gaps = np.diff([m.t for m in lives])  # as received: one late message shortens one gap, lengthens the next
        assert np.median(gaps) >= 0.2 * 0.9, f"{len(lives)} live messages in {span:.2f} s: at most 5 a second"
        assert len(lives) <= span / 0.2 + 3, f"{len(lives)} live messages in {span:.2f} s"  # bursts count too
        assert all(m.qos == 0 and not m.retain for m in lives)

        live = first.json()
        assert LIVE_KEYS <= set(live)
        assert live["run_id"] == waiting["run_id"] and live["direction"] in ("forward", "backward")
        assert live["units"]["fx_piezo"] == "N" and live["units"]["x_a"] == "m"
        assert set(live["waveforms"]) == set(CHANNELS)
        assert all(len(v) == 45 for v in live["waveforms"].values())  # 360 slots / 8 channels, sequential
        # the displacement waveforms in m: their first harmonic is the orbit radius asked (5.76 um)
        x = (np.array(live["waveforms"]["x_a"]) + np.array(live["waveforms"]["x_b"])) / 2
        assert 0.8 * 5.76e-6 < (x.max() - x.min()) / 2 < 1.2 * 5.76e-6
        assert abs(live["spin_rpm"] - 1000.0) < 5.0
        assert set(live["drives"]) >= {"spin", "orbit", "link_ok"}
        assert live["drives"]["spin"]["state"] == "running"
        assert 1.0e5 < live["aux"]["p_supply"] < 1.0e7  # Pa
        assert 280.0 < live["aux"]["t_supply"] < 400.0  # K
        assert live["bands"]["p_supply"] == [0.2e6, 8.0e6]
        assert rc.command({"cmd": "abort"})["ok"]
        rc.status("idle", 60)
    finally:
        rc.close()


def test_revolution_average_is_the_mean_in_engineering_units():
    avg = RevolutionAverage(gains=[0.1, 5e-9], offsets=[1.0, 0.0])
    assert avg.mean() is None
    slots = np.array([[0, 2], [1, 3]])
    avg.add(np.array([[10, 20], [100, 200]]), slots, 0.05)
    avg.add(np.array([[30, 40], [300, 400]]), slots, None)
    np.testing.assert_allclose(avg.mean(), [[0.1 * 20 + 1, 0.1 * 30 + 1], [5e-9 * 200, 5e-9 * 300]])
    assert avg.count == 2 and avg.period_s == 0.05
    avg.reset()
    assert avg.mean() is None


def test_geometry_of_a_circular_orbit_with_a_static_offset():
    ch = {"x_a": 0, "y_a": 1, "x_b": 2, "y_b": 3}
    slots = np.array([np.arange(k, 360, 8) for k in (4, 5, 6, 7)])  # the probes' slots, sequential mode
    theta = slots * 2 * np.pi / 360
    R, x0, y0, c = 6e-6, 3e-6, -4e-6, 60e-6
    mean = np.array(
        [x0 + R * np.cos(theta[0]), y0 + R * np.sin(theta[1]), x0 + R * np.cos(theta[2]), y0 + R * np.sin(theta[3])]
    )
    geo = _geometry(mean, slots, ch, c)
    assert math.isclose(geo["orbit_radius"], R, rel_tol=1e-9)
    assert math.isclose(geo["static_eccentricity"], 5e-6 / c, rel_tol=1e-9)
