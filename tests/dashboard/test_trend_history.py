"""The dashboard's trend history stays bounded over a month of samples and keeps the run's
shape: hand-checkable numbers, no browser."""

from __future__ import annotations

from orbitrig.dashboard.trend import TREND_KEYS, TrendHistory, sample_of

LIVE = {
    "run_id": "r1",
    "drives": {
        "spin": {"actual_rpm": 1000.0, "reference_rpm": 1000.0, "torque_pct": 12.5},
        "orbit": {"actual_rpm": -600.0, "reference_rpm": -600.0, "torque_pct": 3.0},
    },
    "aux": {"p_supply": 2.0e6, "p_recess_1": 0.48e6, "t_supply": 313.15, "flow": 1e-4, "beta": 0.4, "node_lost": False},
}


def test_a_sample_takes_speeds_torques_and_sensors_in_the_payloads_units():
    s = sample_of(LIVE, 1234.5)
    assert s["t"] == 1234.5 and s["spin_rpm"] == 1000.0 and s["orbit_set_rpm"] == -600.0
    assert s["torque_spin"] == 12.5 and s["p_supply"] == 2.0e6 and s["t_supply"] == 313.15
    assert s["p_recess_2"] is None and s["t_groove"] is None  # not in the payload: a gap, not a zero
    assert set(s) == {"t", *TREND_KEYS}
    assert sample_of({"drives": {"spin": None}, "aux": {"flow": float("nan"), "beta": True}}, 0)["flow"] is None


def test_a_month_of_samples_stays_within_its_bounds_and_covers_the_run():
    period, month = 300.0, 30 * 86400.0
    h = TrendHistory(period=period, recent_s=3600.0, run_cap=720)
    n = 0
    for k in range(int(month / period)):
        live = {**LIVE, "drives": {"spin": {"actual_rpm": 1000.0 + (k % 2) * 10.0}}}
        assert h.add(live, k * period) is not None
        assert h.add(live, k * period + 0.2 * period) is None  # faster than the period: not taken
        n += 1
    assert len(h.recent) == 12  # 3600 s / 300 s
    assert h.recent[-1]["t"] == (n - 1) * period and h.recent[0]["t"] == (n - 12) * period
    assert 360 <= len(h.run) < 720
    run = h.history()["run"]
    assert run[0]["t"] == 0.0 and run[-1]["t"] > month - 2 * h.run_step
    # every sample in a mean: the alternating 1000 / 1010 rpm becomes 1005 rpm (but where an odd
    # sample was left over at a merge: the means are per time step, not weighted by count)
    assert all(1000.0 <= s["spin_rpm"] <= 1010.0 for s in h.run)
    assert sum(abs(s["spin_rpm"] - 1005.0) < 1e-9 for s in h.run) >= 0.95 * len(h.run)
    steps = {round(b["t"] - a["t"]) for a, b in zip(h.run, h.run[1:])}
    assert steps == {round(h.run_step)}


def test_a_new_run_starts_a_new_run_view_and_a_seed_copies_the_history():
    h = TrendHistory(period=1.0)
    for k in range(5):
        h.add(LIVE, float(k))
    h.add({**LIVE, "run_id": "r2"}, 5.0)
    assert [s["t"] for s in h.history()["run"]] == [5.0] and len(h.recent) == 6 and h.history()["run_id"] == "r2"
    late = TrendHistory(period=1.0)
    late.seed(h)
    assert late.history() == h.history()
    assert late.add({**LIVE, "run_id": "r2"}, 5.5) is None  # the seed's last sample counts
