"""Per-direction orbit lists ([orbit] whirl, or a design's): each entry of `ratios` runs in the
directions it names, so a ratio may be written twice (once forward, once backward, each its own
count). Validation naming the key and entry, the plan's blocks, the plan check of a sequential
initial list and the dry run's prediction from the blocks planned."""

from __future__ import annotations

import numpy as np
import pytest

from orbitrig import config as cfg
from orbitrig.cli.design_inputs import prior_theta, stated_noise
from orbitrig.cli.dry_run_predict import prediction_lines, predict_model
from orbitrig.errors import ConfigError
from orbitrig.run.plan import make_plan
from orbitrig.run.steps import Acquire
from reduction.design import predicted_covariance
from reduction.frequency_list import coefficient_scales
from reduction.misfit import list_shift
from reduction.models import model_spec
from reduction.rig_time import point_time
from reduction.whirl import Directions

from test_designed_matrix import with_orbit

from support.cli_helpers import orbitrig

RPM = 2 * np.pi / 60
# 1.5 forward and backward with their own counts, 0.5 both ways, 0.8 backward only; written out of order
PER_DIRECTION = 'ratios = [1.5, 0.5, 1.5, 0.8]\nwhirl = ["forward", "both", "backward", "backward"]'


def load(tmp_path, orbit: str, extra: str = "") -> cfg.MatrixConfig:
    path = tmp_path / "m.toml"
    path.write_text(with_orbit(orbit, extra))
    return cfg.load_matrix(path)


def problem(tmp_path, orbit: str) -> str:
    with pytest.raises(ConfigError) as err:
        load(tmp_path, orbit)
    return str(err.value)


@pytest.mark.parametrize(
    "orbit, key, message",
    [
        (
            'ratios = [0.5, 1.2, 1.2]\nwhirl = ["both", "forward", "both"]',
            "orbit",
            "'ratios' has 1.2 twice (entries 1 and 2) with 'whirl' 'forward' and 'both': a ratio written twice "
            "must run in directions that do not overlap",
        ),
        (
            'ratios = [0.5, 1.2, 1.2]\nwhirl = ["both", "backward", "backward"]',
            "orbit",
            "'ratios' has 1.2 twice (entries 1 and 2) with 'whirl' 'backward' and 'backward'",
        ),
        ("ratios = [0.5, 1.2, 1.2]", "orbit", "'ratios' has repeated values (a ratio may be written twice only"),
        ('ratios = [0.5, 1.2, 0.8]\nwhirl = ["both", "forward"]', "orbit.whirl", "has 2 values and 'ratios' 3"),
        ('ratios = [0.5, 1.2]\nwhirl = ["both", "sideways"]', "orbit.whirl[1]", "'forward', 'backward' or 'both'"),
        (
            'ratios = [0.5, 1.2]\ndirections = ["forward"]\nwhirl = ["forward", "backward"]',
            "orbit",
            "'whirl[1]' is 'backward' (ratio 1.2): backward is not in 'directions' (forward)",
        ),
        (
            'ratios = [0.5, 1.2]\ndirections = ["backward"]\nwhirl = ["both", "backward"]',
            "orbit",
            "'whirl[0]' is 'both' (ratio 0.5): forward is not in 'directions' (backward)",
        ),
        (
            'ratio_start = 0.3\nratio_stop = 1.2\ncount = 3\nwhirl = ["both", "forward", "backward"]',
            "orbit.whirl",
            "needs 'ratios'",
        ),
    ],
)
def test_mistakes_name_the_key_and_the_entry(tmp_path, orbit, key, message):
    text = problem(tmp_path, orbit)
    assert f"key '{key}': " in text and message in text, text


def test_the_plan_runs_exactly_the_blocks_the_list_names(tmp_path):
    mat = load(tmp_path, PER_DIRECTION + "\nrevolutions = [124, 20, 109, 30]")
    assert mat.orbit.ratio_list == [0.5, 0.8, 1.5, 1.5]  # a ratio written twice is there twice, as written
    assert [w.value for w in mat.orbit.whirl_list] == ["both", "backward", "forward", "backward"]
    plan = make_plan(mat, cfg.load_rig())
    blocks = [
        (s.block.tag, round(s.block.orbit / (1000 * RPM), 9), s.revolutions)
        for s in plan.steps
        if isinstance(s, Acquire)
    ]
    # forward from the highest |Omega| down, then backward from the lowest up; counts follow their entries
    assert blocks == [
        ("02_fwd", 1.5, 124),
        ("00_fwd", 0.5, 20),
        ("00_bwd", -0.5, 20),
        ("01_bwd", -0.8, 30),
        ("03_bwd", -1.5, 109),
    ]


def test_without_whirl_every_ratio_runs_in_every_direction(tmp_path):
    mat = load(tmp_path, 'ratios = [1.2, 0.5]\ndirections = ["backward"]')
    plan = make_plan(mat, cfg.load_rig())
    assert [s.block.tag for s in plan.steps if isinstance(s, Acquire)] == ["00_bwd", "01_bwd"]
    both = load(tmp_path, 'ratios = [1.2, 0.5]\nwhirl = ["both", "both"]')
    tags = [s.block.tag for s in make_plan(both, cfg.load_rig()).steps if isinstance(s, Acquire)]
    assert tags == ["01_fwd", "00_fwd", "00_bwd", "01_bwd"]


def test_the_dry_run_predicts_the_blocks_planned(tmp_path):
    """predict_model's worst relative error is the Cramer-Rao bound of exactly the planned blocks,
    and larger than that of the same ratios run in both directions (more blocks)."""
    rig = cfg.load_rig()
    mat = load(tmp_path, PER_DIRECTION + "\nrevolutions = [40, 20, 30, 25]")
    noise = stated_noise()
    got = predict_model(rig, mat, "kcd11", "none", noise)
    spec = model_spec("kcd11")
    theta, _ = prior_theta(spec)
    spin, radius = 1000 * RPM, 0.096 * rig.bearing.clearance
    acquires = [s for s in make_plan(mat, rig).steps if isinstance(s, Acquire)]
    orbit = np.array([s.block.orbit for s in acquires])
    n = np.array([s.revolutions for s in acquires], dtype=float)
    y = -1j * np.sign(orbit) * radius
    u = np.asarray(noise.u_revolution)[None, :] / np.sqrt(n)[:, None]
    cov = predicted_covariance(spec, np.abs(orbit), np.full(orbit.size, complex(radius)), y, u, theta=theta)
    rel = np.sqrt(np.diag(cov)) / coefficient_scales(spec, theta, spin)
    assert got.refusal is None and got.worst == pytest.approx(float(np.max(rel)), rel=1e-9)
    both = load(tmp_path, "ratios = [1.5, 0.5, 0.8]\nrevolutions = [40, 20, 25]")
    assert predict_model(rig, both, "kcd11", "none", noise).worst < got.worst
    header = prediction_lines(rig, mat)[0]
    assert "revolutions per entry of the list: 0.5 both 20, 0.8 backward 25, 1.5 forward 40, 1.5 backward 30;" in header


def test_the_dry_run_refuses_a_per_direction_list_that_cannot_identify(tmp_path):
    """Three single-direction blocks give 12 equations: kc8 (8 coefficients) is identifiable,
    kcd11 (11) is not with only three orbit frequencies of one direction each."""
    mat = load(tmp_path, 'ratios = [0.5, 0.8, 1.2]\nwhirl = ["forward", "backward", "forward"]')
    noise = stated_noise()
    assert predict_model(cfg.load_rig(), mat, "kc8", "none", noise).refusal is None
    assert predict_model(cfg.load_rig(), mat, "kcd11", "poly:1", noise).refusal


def test_a_sequential_initial_list_is_checked_on_its_blocks(tmp_path):
    """The initial list of a sequential point must identify the point's model on the blocks it
    runs: two ratios of one direction each cannot identify kcd11 (the refusal names them)."""
    sequential = "[sequential]\ntarget_pct = 0.5\ncap_s = 120\n"
    orbit = 'ratios = [0.5, 1.2]\nwhirl = ["forward", "backward"]\nsequential = true'
    mat = load(tmp_path, orbit, sequential)
    with pytest.raises(ConfigError) as err:
        make_plan(mat, cfg.load_rig())
    assert "the initial list of a sequential point (ratios 0.5 forward, 1.2 backward) cannot identify kcd11" in str(
        err.value
    )
    fine = load(
        tmp_path, 'ratios = [0.5, 0.8, 1.2]\nwhirl = ["both", "forward", "both"]\nsequential = true', sequential
    )
    assert make_plan(fine, cfg.load_rig()).points


def test_a_design_file_gives_the_whirl_list(tmp_path):
    (tmp_path / "designs").mkdir()
    (tmp_path / "matrices").mkdir()
    (tmp_path / "designs" / "pd.toml").write_text(
        'ratios = [1.5, 0.5, 1.5]\nrevolutions = [12, 8, 10]\ndirections = ["forward", "backward"]\n'
        'whirl = ["forward", "both", "backward"]\n'
    )
    path = tmp_path / "matrices" / "m.toml"
    path.write_text(with_orbit('design = "pd"'))
    mat = cfg.load_matrix(path)
    assert mat.orbit.ratio_list == [0.5, 1.5, 1.5]
    assert [(mat.orbit.whirl_at(k).value, mat.orbit.revolutions_at(k)) for k in range(3)] == [
        ("both", 8),
        ("forward", 12),
        ("backward", 10),
    ]
    (tmp_path / "designs" / "pd.toml").write_text('ratios = [1.5, 0.5]\nwhirl = ["forward"]\n')
    with pytest.raises(ConfigError) as err:
        cfg.load_matrix(path)
    assert '\'whirl\' must be a list of 2 directions "forward", "backward" or "both"' in str(err.value)


def test_a_ratio_in_both_directions_is_its_forward_and_its_backward_block():
    """One direction per ratio: 0.5 written twice (forward, backward) at one count is the
    ratio in both directions, for the rig time, the shift between lists and the prediction;
    and one ratio in one direction ramps the orbit drive once."""
    fb = [Directions.FORWARD, Directions.BACKWARD]
    spin = 1000 * RPM
    assert point_time(
        [0.5, 0.5, 1.2], spin, [30, 30, 40], fb + [Directions.BOTH], per_block_s=2.0, ramp_rate=50.0
    ) == pytest.approx(
        point_time([0.5, 1.2], spin, [30, 40], Directions.BOTH, per_block_s=2.0, ramp_rate=50.0), rel=1e-12
    )
    one = point_time([1.2], spin, [40], [Directions.BACKWARD], per_block_s=2.0, ramp_rate=50.0)
    assert one == pytest.approx(41 * 2 * np.pi / (1.2 * spin) + 2.0 + 1.2 * spin / 50.0, rel=1e-12)
    small, rich = model_spec("kc8"), model_spec("kcd12")
    theta = np.zeros(rich.n_coefficients)
    theta[rich.names.index("Dxx")], theta[rich.names.index("Kxy")] = 40.0, 6e6
    cov = np.eye(rich.n_coefficients)
    u = np.array([20e-9, 20e-9, 15.0, 15.0])
    a = ([0.3, 0.9], 50, u)
    both = list_shift(small, rich, theta, cov, spin, 2.4e-6, a, ([0.5, 1.2], [30, 40], u))
    split = list_shift(
        small, rich, theta, cov, spin, 2.4e-6, a, ([0.5, 0.5, 1.2], [30, 30, 40], u), Directions.BOTH, fb + ["both"]
    )
    assert np.allclose(split.shift, both.shift, rtol=1e-9, atol=1e-9) and np.allclose(split.std, both.std, rtol=1e-9)
    assert np.abs(both.shift).max() > 0  # D and the cross-coupling move kc8's K between the lists


def test_design_takes_a_per_direction_matrix_as_its_candidate(tmp_path):
    """`design --matrix` of a matrix with a whirl list predicts the blocks the matrix runs (the
    dry run's prediction at the same count) and reports each ratio's directions."""
    import json

    path = tmp_path / "m.toml"
    path.write_text(with_orbit(PER_DIRECTION, "top: revolutions = 50"))
    p = orbitrig(
        "design", "--model", "kcd11", "--spin", "1000", "--matrix", str(path), "--json", timeout=120, columns=None
    )
    assert p.returncode == 0, p.stderr
    c = json.loads(p.stdout)["candidate"]
    assert (c["ratios"], c["whirl"]) == ([0.5, 0.8, 1.5, 1.5], ["both", "backward", "forward", "backward"])
    dry = predict_model(cfg.load_rig(), cfg.load_matrix(path), "kcd11", "none", stated_noise())
    assert c["worst_relative_pct"] == pytest.approx(dry.worst * 100, rel=1e-9)
