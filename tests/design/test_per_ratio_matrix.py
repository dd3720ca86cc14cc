"""Per-ratio revolutions and adaptive targets ([orbit] revolutions / target_pct, or a design's):
validation naming the key, the values following their ratios when sorted, the plan's
steps, durations and rules per block, and the storage estimate per block."""

from __future__ import annotations

import math

import pytest

from orbitrig import config as cfg
from orbitrig.errors import ConfigError
from orbitrig.run.plan import make_plan
from orbitrig.run.steps import Acquire
from orbitrig.run.averaging import averaging_rule
from orbitrig.store.estimate import block_bytes, point_bytes

from test_designed_matrix import with_orbit

RPM = 2 * math.pi / 60
RATIOS = "ratios = [1.2, 0.5, 0.8]"  # written out of order: the values follow their ratios


def load(tmp_path, orbit: str, extra: str = "") -> cfg.MatrixConfig:
    path = tmp_path / "m.toml"
    path.write_text(with_orbit(orbit, extra))
    return cfg.load_matrix(path)


def problem(tmp_path, orbit: str, extra: str = "") -> str:
    with pytest.raises(ConfigError) as err:
        load(tmp_path, orbit, extra)
    return str(err.value)


def acquires(mat) -> dict[str, Acquire]:
    return {s.block.tag: s for s in make_plan(mat, cfg.load_rig()).steps if isinstance(s, Acquire)}


@pytest.mark.parametrize(
    "orbit, extra, key, message",
    [
        (RATIOS + "\nrevolutions = [30, 40]", "", "orbit.revolutions", "has 2 values and 'ratios' 3"),
        (RATIOS + "\nrevolutions = [30, 1, 40]", "", "orbit.revolutions[1]", "greater than or equal to 2"),
        (RATIOS + "\nrevolutions = [30, 10001, 40]", "", "orbit.revolutions[1]", "less than or equal to 10000"),
        (RATIOS + "\nrevolutions = [30, 2.5, 40]", "", "orbit.revolutions[1]", "integer"),
        (
            "ratio_start = 0.3\nratio_stop = 1.2\ncount = 2\nrevolutions = [30, 40]",
            "",
            "orbit.revolutions",
            "needs 'ratios'",
        ),
        (
            RATIOS + "\nrevolutions = [30, 40, 50]",
            "top: revolutions = 40",
            "revolutions",
            "'orbit.revolutions' (one per ratio), not both",
        ),
        (
            RATIOS + "\ntarget_pct = [1, 2]",
            "[averaging]\nmin_revolutions = 5",
            "orbit.target_pct",
            "has 2 values and 'ratios' 3",
        ),
        (RATIOS + "\ntarget_pct = [1, 0, 2]", "[averaging]", "orbit.target_pct[1]", "greater than 0"),
        (RATIOS + "\ntarget_pct = [1, 100, 2]", "[averaging]", "orbit.target_pct[1]", "less than 100"),
        (
            RATIOS + "\ntarget_pct = [1, 2, 3]",
            "",
            "averaging",
            "'orbit.target_pct' (adaptive targets per ratio) needs an [averaging] table",
        ),
        (
            RATIOS + "\ntarget_pct = [1, 2, 3]",
            "[averaging]\ntarget_pct = 2",
            "averaging",
            "give 'averaging.target_pct' (one target) or 'orbit.target_pct' (one per ratio), not both",
        ),
        (
            RATIOS,
            "[averaging]\nmin_revolutions = 5",
            "averaging",
            "needs a target: 'averaging.target_pct' (percent) or 'orbit.target_pct'",
        ),
    ],
)
def test_mistakes_name_the_key(tmp_path, orbit, extra, key, message):
    text = problem(tmp_path, orbit, extra)
    assert f"key '{key}': " in text and message in text, text
    assert len(text.splitlines()) == 1  # one problem, not a cascade


def test_the_line_of_the_key_is_named(tmp_path):
    text = problem(tmp_path, RATIOS + "\nrevolutions = [30, 40]")
    line = with_orbit(RATIOS + "\nrevolutions = [30, 40]").splitlines().index("revolutions = [30, 40]") + 1
    assert f"line {line}: key 'orbit.revolutions'" in text


def test_values_follow_their_ratios_when_sorted(tmp_path):
    mat = load(tmp_path, RATIOS + "\nrevolutions = [14, 6, 9]\ntarget_pct = [3.5, 1.5, 2.5]", "[averaging]")
    o = mat.orbit
    assert o.ratio_list == [0.5, 0.8, 1.2]
    assert [o.revolutions_at(k) for k in range(3)] == [6, 9, 14]
    assert [o.target_pct_at(k) for k in range(3)] == [1.5, 2.5, 3.5]
    plain = load(tmp_path, RATIOS).orbit
    assert plain.revolutions_at(0) is None and plain.target_pct_at(2) is None


def test_fixed_counts_per_ratio_in_the_plan(tmp_path):
    mat = load(tmp_path, RATIOS + "\nrevolutions = [14, 6, 9]")
    plan = make_plan(mat, cfg.load_rig())
    acq = acquires(mat)
    for tag, n in {"00": 6, "01": 9, "02": 14}.items():
        for d in ("fwd", "bwd"):
            a = acq[f"{tag}_{d}"]
            hz = a.block.orbit_hz
            assert a.revolutions == n and a.adaptive is None
            assert a.duration == pytest.approx((n + 1) / hz)  # one more revolution to find the trigger
            assert a.describe() == f"acquire {n} revolutions at {hz:.3f} Hz [{tag}_{d}]"
            rule = averaging_rule(a, 1000 * RPM)
            assert (rule.min_revolutions, rule.max_revolutions, rule.target) == (n, n, None)
    assert acq["02_fwd"].block.orbit == pytest.approx(1.2 * 1000 * RPM)
    assert plan.revolutions == 14  # the most any block averages
    rig = cfg.load_rig()
    counts = [a.revolutions for a in acq.values()]
    assert point_bytes(rig, plan.points[0], counts, 2) < point_bytes(rig, plan.points[0], 14, 2)
    assert point_bytes(rig, plan.points[0], counts, 2) - point_bytes(rig, plan.points[0], [6] * 6, 2) == pytest.approx(
        1.25 * 2 * (block_bytes(rig, 9) - block_bytes(rig, 6) + block_bytes(rig, 14) - block_bytes(rig, 6)), abs=2
    )


def test_adaptive_targets_per_ratio_in_the_plan(tmp_path):
    mat = load(
        tmp_path, RATIOS + "\ntarget_pct = [3.5, 1.5, 2.5]", "[averaging]\nmin_revolutions = 8\nmax_revolutions = 60"
    )
    acq = acquires(mat)
    for tag, t in {"00": 1.5, "01": 2.5, "02": 3.5}.items():
        a = acq[f"{tag}_bwd"]
        rule = averaging_rule(a, 1000 * RPM)
        assert (rule.min_revolutions, rule.max_revolutions, rule.target) == (8, 60, pytest.approx(t / 100))
        assert rule.spin_turns == pytest.approx(
            1000 * RPM / abs(a.block.orbit)
        )  # the stop check fits the spin tones out
        assert a.revolutions == 60 and a.duration == pytest.approx(61 / a.block.orbit_hz)  # no expected count
        assert f"8..60 revolutions (until every channel <= {t:g} %) at" in a.describe()


def test_expected_counts_set_the_adaptive_durations(tmp_path):
    mat = load(
        tmp_path,
        RATIOS + "\nrevolutions = [14, 6, 90]",
        "[averaging]\ntarget_pct = 2\nmin_revolutions = 8\nmax_revolutions = 60",
    )
    acq = acquires(mat)
    # 6 below the minimum counts as 8; 90 above the maximum as 60
    for tag, n in {"00": 8, "01": 60, "02": 14}.items():
        a = acq[f"{tag}_fwd"]
        assert a.duration == pytest.approx((n + 1) / a.block.orbit_hz)
        assert a.revolutions == 60  # the timeout and the storage estimate take the maximum
        assert averaging_rule(a, 1000 * RPM).target == pytest.approx(0.02)
        assert f"(until every channel <= 2 %, about {n} expected)" in a.describe()
    assert make_plan(mat, cfg.load_rig()).revolutions == 60


DESIGN = 'ratios = [1.2, 0.5, 0.8]\ndirections = ["backward"]\n'


@pytest.mark.parametrize(
    "body, key",
    [
        ("revolutions = [14, 6]", "revolutions"),
        ("revolutions = 27", "revolutions"),
        ("revolutions = [14, 6, 1]", "revolutions"),
        ("revolutions = [14, 6.5, 9]", "revolutions"),
        ("revolutions = [14, true, 9]", "revolutions"),
        ("target_pct = [1, 2]", "target_pct"),
        ("target_pct = [1, 100, 2]", "target_pct"),
        ('target_pct = [1, "2", 3]', "target_pct"),
    ],
)
def test_design_file_mistakes_name_the_file_and_key(tmp_path, body, key):
    (tmp_path / "d.toml").write_text(DESIGN + body + "\n")
    text = problem(tmp_path, 'design = "d.toml"', "[averaging]\nmin_revolutions = 5")
    assert "key 'orbit.design'" in text and str(tmp_path / "d.toml") in text
    assert f"'{key}' must be a list of 3 " in text and "one per entry of 'ratios'" in text, text


def test_a_design_gives_its_counts_and_targets(tmp_path):
    (tmp_path / "d.toml").write_text(DESIGN + "revolutions = [14, 6, 9]\ntarget_pct = [3.5, 1.5, 2.5]\n")
    fixed = load(tmp_path, 'design = "d.toml"')  # no [averaging]: the counts, not the targets
    assert fixed.orbit.revolutions == [14, 6, 9] and fixed.orbit.target_pct is None
    assert {t: a.revolutions for t, a in acquires(fixed).items()} == {"00_bwd": 6, "01_bwd": 9, "02_bwd": 14}
    adaptive = load(tmp_path, 'design = "d.toml"', "[averaging]\nmin_revolutions = 5\nmax_revolutions = 40")
    assert [adaptive.orbit.target_pct_at(k) for k in range(3)] == [1.5, 2.5, 3.5]
    assert averaging_rule(acquires(adaptive)["02_bwd"], 1000 * RPM).target == pytest.approx(0.035)
    assert acquires(adaptive)["02_bwd"].adaptive.expected == 14


def test_the_matrix_keeps_its_own_settings_over_the_design(tmp_path):
    (tmp_path / "d.toml").write_text(DESIGN + "revolutions = [14, 6, 9]\ntarget_pct = [3.5, 1.5, 2.5]\n")
    own = load(tmp_path, 'design = "d.toml"\nrevolutions = [20, 21, 22]\ntarget_pct = [1, 2, 3]', "[averaging]")
    assert own.orbit.revolutions == [20, 21, 22] and own.orbit.target_pct == [1.0, 2.0, 3.0]
    top = load(tmp_path, 'design = "d.toml"', "top: revolutions = 40")  # one count for all: the design's stay out
    assert top.orbit.revolutions is None and {a.revolutions for a in acquires(top).values()} == {40}
    one = load(tmp_path, 'design = "d.toml"', "[averaging]\ntarget_pct = 2")  # one target: the design's stay out
    assert one.orbit.target_pct is None
    assert [averaging_rule(a, 1000 * RPM).target for a in acquires(one).values()] == [pytest.approx(0.02)] * 3
