"""Quantiles and tail probabilities of the normal, Student t, chi-square and F distributions,
from ``scipy.special`` (the same values as ``scipy.stats``, whose import alone costs a command
about 0.8 s). The one place reduction/ and orbitrig/ take them from."""

from __future__ import annotations

from scipy import special


def norm_ppf(p: float) -> float:
    """The standard normal quantile at probability ``p`` (1.96 at 0.975)."""
    return float(special.ndtri(p))


def norm_isf(q: float) -> float:
    """The standard normal quantile with upper tail ``q`` (1.96 at 0.025)."""
    return float(-special.ndtri(q))


def t_ppf(p: float, dof: float) -> float:
    """Student's t quantile at probability ``p`` with ``dof`` > 0 degrees of freedom."""
    return float(special.stdtrit(dof, p))


def t_cdf(x: float, dof: float) -> float:
    """P(T <= ``x``) of Student's t with ``dof`` > 0 degrees of freedom."""
    return float(special.stdtr(dof, x))


def chi2_sf(x: float, dof: float) -> float:
    """P(X > ``x``) of a chi-square variable with ``dof`` > 0 degrees of freedom (1 for x <= 0)."""
    return float(special.chdtrc(dof, max(float(x), 0.0)))


def chi2_cdf(x: float, dof: float) -> float:
    """P(X <= ``x``) of a chi-square variable with ``dof`` > 0 degrees of freedom, in full where
    it is tiny (1 - chi2_sf would be 0 there)."""
    return float(special.chdtr(dof, max(float(x), 0.0)))


def chi2_isf(q: float, dof: float) -> float:
    """The chi-square value with upper tail ``q`` at ``dof`` > 0 degrees of freedom."""
    return float(special.chdtri(dof, q))


def f_sf(x: float, dfn: float, dfd: float) -> float:
    """P(X > ``x``) of an F variable with (``dfn``, ``dfd``) degrees of freedom (1 for x <= 0)."""
    return float(special.fdtrc(dfn, dfd, max(float(x), 0.0)))


def f_isf(q: float, dfn: float, dfd: float) -> float:
    """The F value with upper tail ``q`` at (``dfn``, ``dfd``) degrees of freedom."""
    return float(special.fdtri(dfn, dfd, 1.0 - q))
