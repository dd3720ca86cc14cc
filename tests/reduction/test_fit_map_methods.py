"""The calibration and runout terms of a fit go through the map the fit's method fits by
(reduction.systematic.fit_map): tls each row's complex residual whitened by its 2 x 2 covariance
diag(u_f^2) + Z diag(u_d^2) Z^H (reduction.regression.residual_covariances), iv its two
unweighted stages; not the equations' variances alone. Checked against the refit's change under
a channel delay, whose part outside the model the map spreads over the rows."""

from __future__ import annotations

import numpy as np
import pytest

from support.reduction_synthetic import frequencies, orbit_table, truth, with_noise
from reduction.identify import identify, tls_noise_ratio
from reduction.systematic import systematic_jacobian
from reduction.table import OrbitTable

TRUE = truth("kcd12", {"K": (0,), "C": (0,), "D": (0,)})


def _noisy_displacements() -> OrbitTable:
    """kcd12 on forward, backward and elliptic orbits from 0.2 to 3 times the spin, the displacement
    noise (u_x 10 times u_y) ahead of the force noise: what tls is for."""
    rng = np.random.default_rng(3)
    clean = orbit_table(TRUE, frequencies(10, 0.2, 3), shapes=("forward", "backward", (1.0, 0.4, 0.3)))
    sd = 1e-5 * np.sqrt(np.mean(np.abs(clean.x) ** 2))
    sf = 1e-7 * np.sqrt(np.mean(np.abs(clean.fx) ** 2))
    return with_noise(clean, rng, (sd, sd / 10, sf, sf))


@pytest.mark.parametrize("channel", ["fy", "y"])
def test_a_delay_term_of_a_tls_fit_is_the_change_of_its_refit(channel):
    """A delay tau on one channel (5 µs, central difference: first order to (Omega tau)^2): the
    refitted tls coefficients move by the Jacobian's column within 2 % of its largest entry (0.1 %
    here; what is left is the residual-dependent part, in proportion to the noise). Whitened by the
    equations' variances alone (the wls map) the columns were off by 136 and 172 %: the map spreads
    the delay's part outside the model over the rows, and tls weighs them by their 2 x 2 covariance."""
    refit, column = _delay_moves(_noisy_displacements(), "tls", channel)
    assert np.max(np.abs(refit - column)) < 0.02 * np.max(np.abs(column))


@pytest.mark.parametrize("times", [1 / 30, 30])
@pytest.mark.parametrize("channel", ["fy", "y"])
def test_a_tls_fit_with_its_own_noise_ratio_maps_its_terms_with_it(channel, times):
    """A tls fit without u_* given a noise ratio (``tls_ratio``, here 1/30 and 30 times the default
    rms|f| / rms|d|) whitens its rows by its residual covariance at that ratio, and so does its map
    (Identification.tls_ratio): orbits from 0.1 to 6 times the spin (|Z| varies by the rows), 1e-6
    noise, a 5 µs delay; the refit's change is the column within 1 % of its largest entry (1e-4
    here). With the default ratio in the map the columns were 4 to 10 % off."""
    rng = np.random.default_rng(3)
    clean = orbit_table(TRUE, frequencies(10, 0.1, 6), shapes=("forward", "backward", (1.0, 0.4, 0.3)))
    sd = 1e-6 * np.sqrt(np.mean(np.abs(clean.x) ** 2))
    sf = 1e-6 * np.sqrt(np.mean(np.abs(clean.fx) ** 2))
    table = with_noise(clean, rng, (sd, sd, sf, sf), stated=False)
    ratio = times * tls_noise_ratio(table)
    assert identify(table, "kcd12", method="tls", tls_ratio=ratio).tls_ratio == ratio
    refit, column = _delay_moves(table, "tls", channel, tls_ratio=ratio)
    assert np.max(np.abs(refit - column)) < 0.01 * np.max(np.abs(column))


def test_only_a_tls_fit_without_u_records_its_noise_ratio():
    """The default ratio rms|f| / rms|d| is recorded as the fit's own; with u_* (the noise stated)
    and for the other methods there is none."""
    noisy = _noisy_displacements()
    bare = OrbitTable(noisy.spin, noisy.orbit, noisy.x, noisy.y, noisy.fx, noisy.fy)
    rms = np.sqrt(
        (np.mean(np.abs(bare.fx) ** 2) + np.mean(np.abs(bare.fy) ** 2))
        / (np.mean(np.abs(bare.x) ** 2) + np.mean(np.abs(bare.y) ** 2))
    )
    assert identify(bare, "kcd12", method="tls").tls_ratio == pytest.approx(rms, rel=1e-12)
    assert identify(noisy, "kcd12", method="tls").tls_ratio is None
    assert identify(bare, "kcd12", method="ols").tls_ratio is None


def _delay_moves(
    table: OrbitTable, method: str, channel: str, tau: float = 5e-6, **kw: float
) -> tuple[np.ndarray, np.ndarray]:
    """(the refit's change per second of delay on ``channel``, central difference; the Jacobian's column)."""
    ident = identify(table, "kcd12", method=method, **kw)
    labels, J = systematic_jacobian(ident, table)
    moved = []
    for sign in (1, -1):
        d = {"x": table.x, "y": table.y, "fx": table.fx, "fy": table.fy}
        d[channel] = d[channel] * np.exp(-1j * table.orbit * sign * tau)
        t = OrbitTable(table.spin, table.orbit, d["x"], d["y"], d["fx"], d["fy"], u=table.u)
        moved.append(np.array(identify(t, "kcd12", method=method, **kw).theta))
    return (moved[0] - moved[1]) / (2 * tau), J[:, labels.index(f"{channel}.delay")]


@pytest.mark.parametrize("channel", ["fy", "y"])
def test_a_delay_term_of_an_iv_fit_is_the_change_of_its_refit(channel):
    """iv weighs its rows equally whatever its u_* columns say: circular orbits with u_f 1 to 100
    times apart from row to row, a 5 µs delay on one channel; the refit's change is the column
    within 1 % of its largest entry (1e-4 here). With the u_* effective variances (the wls map)
    the columns were 4.5 % off."""
    rng = np.random.default_rng(3)
    clean = orbit_table(TRUE, frequencies(10, 0.2, 3))
    sf = 1e-7 * np.sqrt(np.mean(np.abs(clean.fx) ** 2)) * np.geomspace(1, 100, clean.n)
    sd = 1e-7 * np.sqrt(np.mean(np.abs(clean.x) ** 2))
    table = with_noise(clean, rng, (sd, sd, sf, sf))
    refit, column = _delay_moves(table, "iv", channel)
    assert np.max(np.abs(refit - column)) < 0.01 * np.max(np.abs(column))


@pytest.mark.parametrize("method", ["tls", "iv"])
def test_what_tls_and_iv_leave_of_a_displacement_error_is_a_sliver_of_their_statistical_u(method):
    """tls and iv go without the residual's part of a displacement error (their weights or
    instruments move with the data too; reduction.systematic.map_change): 1 % force and
    displacement noise, a 2 µs delay on x and a 0.1 degree phase error on y, each refitted at plus
    and minus its standard uncertainty. The refit's change is the column times it within 1 % of
    each coefficient's statistical u (at most 0.2 % here). A Monte Carlo of 400 refits on this
    table puts their systematic u at 0.40 to 6.2 (tls) and 0.03 to 2.0 (iv) times the spread, off
    on the entries the errors barely move (Kxx, Kxy, Kyx, Dxy, Dyx: spread 1e-4 to 4e-3 of the
    statistical u), and the combined u within 0.2 % of the statistical u and spread combined."""
    rng = np.random.default_rng(11)
    clean = orbit_table(TRUE, frequencies(10))
    sd = 1e-2 * np.sqrt(np.mean(np.abs(clean.x) ** 2))
    sf = 1e-2 * np.sqrt(np.mean(np.abs(clean.fx) ** 2)) * np.geomspace(0.3, 3, clean.n)
    table = with_noise(clean, rng, (sd, sd, sf, sf), stated=False)
    ident = identify(table, "kcd12", method=method)
    labels, J = systematic_jacobian(ident, table)
    stat = np.sqrt(np.diag(ident.covariance))
    for label, sigma, per_unit in (("x.delay", 2e-6, -1j * table.orbit), ("y.phase", np.radians(0.1), -1j)):
        moved = []
        for sign in (1, -1):
            d = {"x": table.x, "y": table.y}
            d[label[0]] = d[label[0]] * np.exp(sign * sigma * per_unit)
            t = OrbitTable(table.spin, table.orbit, d["x"], d["y"], table.fx, table.fy)
            moved.append(identify(t, "kcd12", method=method).theta)
        left = (moved[0] - moved[1]) / 2 - J[:, labels.index(label)] * sigma
        assert np.all(np.abs(left) < 0.01 * stat), (label, np.max(np.abs(left) / stat))
