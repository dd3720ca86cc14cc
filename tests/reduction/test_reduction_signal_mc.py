"""Monte Carlo of the v3 refusals and warnings (1000 noisy tables each): identifiability on
signal (a line orbit whose other axis is probe noise), the absolute variance-inflation test
(near-coincident frequencies, a whirl direction present only as a tiny row), and their
false alarms on good designs (the paper's ten ratios, forward and backward circles).

The design-side verdicts call the library's own checks in a loop (analyse, signal_design +
check_signal, ill_conditioning: well under a millisecond each); the end-to-end refusals
are confirmed through identify and the CLI on a few tables."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from support.reduction_synthetic import SPIN, cnoise, impedance, keys_of, truth
from orbitrig.cli import app
from orbitrig.store.orbit_table import write_orbit_table
from reduction.design import design_orbits
from reduction.errors import IdentifiabilityError
from reduction.excitation import CLEAR_REFUSE, CLEAR_WARN, displacement_noise, excitation_ratios, signal_design
from reduction.conditioning import ill_conditioning
from reduction.identifiability import analyse, check_signal
from reduction.identify import identify
from reduction.models import model_spec
from reduction.table import OrbitTable

N_TABLES = 1000
R = 5e-6  # orbit radius, m
PROBE = 20e-9  # probe noise u_x = u_y, m
RATIOS = np.array([0.25, 0.36, 0.47, 0.57, 0.68, 0.77, 0.87, 1.04, 1.14, 1.25])  # the paper's ten Omega/omega
TRUE = truth("kcd11", {"K": (0,), "C": (0,), "D": (0,)})


def _table(rng, orbit, x, y, force_rel=0.01, probe=PROBE, with_u=True, true=TRUE) -> OrbitTable:
    """Forces of ``true`` on the true orbits, then probe noise on x, y and force noise."""
    n = orbit.size
    Z = impedance(true, orbit)
    fx, fy = -(Z[:, 0, 0] * x + Z[:, 0, 1] * y), -(Z[:, 1, 0] * x + Z[:, 1, 1] * y)
    sf = force_rel * np.sqrt(np.mean(np.abs(fx) ** 2 + np.abs(fy) ** 2))
    u = np.tile([probe, probe, sf, sf], (n, 1)) if with_u else None
    return OrbitTable(
        SPIN,
        orbit,
        x + cnoise(rng, probe, n),
        y + cnoise(rng, probe, n),
        fx + cnoise(rng, sf, n),
        fy + cnoise(rng, sf, n),
        u=u,
    )


def _line_orbits(n=16):
    orbit = np.linspace(0.2, 1.2, n) * SPIN
    return orbit, np.full(n, R, dtype=complex), np.zeros(n, dtype=complex)


def _paper_design():
    return design_orbits(RATIOS * SPIN / (2 * np.pi), "both", R)


def _verdict(table, model, freq_dep="none") -> str:
    """'refused', 'warned' or 'clean': the design verdicts identify makes, without the fit."""
    spec = model_spec(model, freq_dep)
    try:
        rank = analyse(spec, table)
        signal = signal_design(table, displacement_noise(table))
        check_signal(spec, table, signal)
    except IdentifiabilityError:
        return "refused"
    return "warned" if signal.removed or signal.weak or ill_conditioning(spec, table, rank) else "clean"


def test_a_line_orbit_whose_other_axis_is_probe_noise_is_refused_in_every_table():
    rng = np.random.default_rng(31)
    tables = [_table(rng, *_line_orbits()) for _ in range(N_TABLES)]
    # vectorised: the table's excitation across the main axis is noise (ratio about 1)
    x, y = np.stack([t.x for t in tables]), np.stack([t.y for t in tables])
    u = np.stack([t.u[:, :2] for t in tables])
    _, minor, _ = excitation_ratios(x, y, u)
    assert np.max(minor) < CLEAR_REFUSE, np.max(minor)
    verdicts = [_verdict(t, "kc8") for t in tables]
    assert verdicts.count("refused") == N_TABLES
    # end to end, with and without u_*: identify refuses, naming the cause
    for t in tables[:20]:
        for table in (t, OrbitTable(t.spin, t.orbit, t.x, t.y, t.fx, t.fy)):
            with pytest.raises(IdentifiabilityError, match="not clear of the displacement noise"):
                identify(table, "kc8")


def test_a_noise_free_line_orbit_at_a_thousandth_of_the_radius_is_refused(tmp_path):
    orbit, x, _ = _line_orbits()
    y = np.tile([1e-3j * R, -1e-3j * R], orbit.size // 2)  # thin ellipses, alternating direction
    Z = impedance(TRUE, orbit)
    table = OrbitTable(SPIN, orbit, x, y, -(Z[:, 0, 0] * x + Z[:, 0, 1] * y), -(Z[:, 1, 0] * x + Z[:, 1, 1] * y))
    with pytest.raises(IdentifiabilityError) as err:
        identify(table, "kc8")
    assert set(err.value.combinations) == {"Kxy", "Kyy", "Cxy", "Cyy"}
    path = tmp_path / "line.csv"
    write_orbit_table(path, table)
    res = CliRunner().invoke(app, ["identify", str(path), "--model", "kc8", "--json"])
    assert res.exit_code == 2 and res.stdout == ""
    assert "not clear of the displacement noise" in res.stderr and "  Kyy" in res.stderr


def test_good_designs_pass_the_signal_and_inflation_tests():
    rng = np.random.default_rng(32)
    orbit, x, y = _paper_design()
    verdicts = {model: [] for model in ("kc8", "kcd11", "kcd11 poly:2")}
    minors = []
    for _ in range(N_TABLES):
        t = _table(rng, orbit, x, y)
        minors.append(excitation_ratios(t.x, t.y, t.u[:, :2])[1])
        for key in verdicts:
            verdicts[key].append(_verdict(t, *key.split()))
    assert min(minors) > CLEAR_WARN
    for key, v in verdicts.items():  # at most 1 % false alarms (none expected: the margin is wide)
        assert v.count("clean") >= 0.99 * N_TABLES, (key, v.count("warned"), v.count("refused"))


def test_near_coincident_frequencies_are_warned_in_every_table():
    rng = np.random.default_rng(33)
    orbit, x, y = design_orbits([20.0, 20.0 * (1 + 1e-5)], "both", R)
    verdicts = [_verdict(_table(rng, orbit, x, y), "kcd11") for _ in range(N_TABLES)]
    assert verdicts.count("clean") == 0
    t = _table(rng, orbit, x, y)
    result = identify(t, "kcd11")
    assert any(w.startswith("ill-conditioned") and "Dxx" in w for w in result.warnings), result.warnings
    assert {"Dxx", "Dyy"} <= set(result.not_determined)


def test_a_whirl_direction_present_only_as_a_tiny_row_is_warned_or_refused():
    rng = np.random.default_rng(34)
    orbit, x, y = design_orbits(RATIOS * SPIN / (2 * np.pi), "forward", R)
    orbit = np.append(orbit, RATIOS[5] * SPIN)
    x, y = np.append(x, 0.01 * R), np.append(y, 0.01j * R)  # one backward row at 1 % of R
    verdicts = [_verdict(_table(rng, orbit, x, y), "kc8", "power:1") for _ in range(N_TABLES)]
    assert verdicts.count("clean") == 0, (verdicts.count("warned"), verdicts.count("refused"))


@pytest.mark.slow
def test_displacement_noise_that_biases_ols_is_warned_and_good_tables_are_not():
    rng = np.random.default_rng(35)
    orbit, x, y = _paper_design()
    hits = {0.2: 0, 0.004: 0}  # displacement noise / radius
    for rel in hits:
        for _ in range(N_TABLES):
            t = _table(rng, orbit, x, y, force_rel=0.002, probe=rel * R)
            w = identify(t, "kc8").warnings
            hits[rel] += any(s.startswith("displacement noise") and "tls" in s for s in w)
    assert hits[0.2] == N_TABLES and hits[0.004] <= 0.01 * N_TABLES, hits


@pytest.mark.slow
def test_known_noise_intervals_use_the_normal_quantile_also_without_degrees_of_freedom():
    rng = np.random.default_rng(36)
    orbit, x, y = design_orbits([0.4 * SPIN / (2 * np.pi)], "both", R)  # kc8: 8 equations, 8 coefficients
    true8 = truth("kc8", {"K": (0,), "C": (0,)})
    keys = list(keys_of(true8))
    true = np.array(list(keys_of(true8).values()))
    inside, half = [], []
    for _ in range(N_TABLES):
        r = identify(_table(rng, orbit, x, y, probe=0.0, true=true8), "kc8")
        lo, hi = np.array([r.confidence_95[k] for k in keys]).T
        inside.append((lo <= true) & (true <= hi))
        half.append((hi - lo) / 2 / np.array([r.std_errors[k] for k in keys]))
    assert r.dof == 0 and r.interval == "normal" and json.loads(json.dumps(r.to_dict()))["interval"] == "normal"
    assert np.allclose(half, 1.959964, rtol=1e-6)
    coverage = np.mean(inside, axis=0)  # 1000 tables: 0.7 % standard error
    assert np.all((coverage >= 0.93) & (coverage <= 0.97)), dict(zip(keys, coverage))


def test_a_row_stated_exact_leaves_the_wls_bias_check_on():
    """u_* = 0 on one row (allowed: u >= 0) gives that row the floored weight the wls fit uses;
    the errors-in-variables check must weigh it the same, not with 1/0 (inf x 0 = NaN hid the
    bias of every coefficient, so a table that is warned read as clean)."""
    rng = np.random.default_rng(37)
    orbit, x, y = _paper_design()
    t = _table(rng, orbit, x, y, force_rel=0.002, probe=0.2 * R)
    assert any(s.startswith("displacement noise") for s in identify(t, "kc8", method="wls").warnings)
    u = t.u.copy()
    u[0] = 0.0
    exact = OrbitTable(t.spin, t.orbit, t.x, t.y, t.fx, t.fy, u=u)
    warnings = identify(exact, "kc8", method="wls").warnings
    assert any(s.startswith("displacement noise") for s in warnings), warnings
