"""Model adequacy at one operating point: do the data support frequency dependence?

The constant model (freq-dep none) is nested in every frequency-dependent one of the same
base model (its columns are a subset). With unknown noise the F-test compares the residual
sums of squares (in the fit's own metric): F = ((RSS_0 - RSS_1) / (p_1 - p_0)) / (RSS_1 /
dof_1), F-distributed with (p_1 - p_0, dof_1) degrees of freedom when the constant model is
true. With known noise (u_* columns: chi2) the likelihood ratio chi2_0 - chi2_1 is
chi2-distributed with p_1 - p_0 degrees of freedom. Exact for every method: each fit's chi2
is taken at its wls solution (:mod:`reduction.statistics`), also for ols and iv (tls: its
own maximum-likelihood costs, a likelihood ratio too). For power:auto, whose exponent is
chosen on the same data, the p-value is adjusted for the choice (:mod:`reduction.selection`:
the chance that the candidate of the least residual looks as good when Z is constant); the chosen
exponent's own p-value goes with it. AIC and BIC of both fits go with the verdict (lower is
better).
"""

from __future__ import annotations

from dataclasses import dataclass

from reduction import distributions as dist

from reduction.errors import ReductionError
from reduction.result import Identification
from reduction.statistics import p_text

ALPHA = 0.05


@dataclass(frozen=True)
class Adequacy:
    """Verdict of :func:`frequency_dependence`; ``statistic`` is F (unknown noise) or the
    chi2 difference (known noise), ``dof`` its (numerator, denominator) degrees of freedom
    (denominator 0 for the chi2 test)."""

    supported: bool
    p_value: float
    statistic: float
    test: str  # "F" | "likelihood ratio"
    dof: tuple[int, int]
    alpha: float
    aic: tuple[float, float]  # (constant, frequency-dependent)
    bic: tuple[float, float]
    p_chosen: float | None = None  # power:auto: the chosen exponent's own p (p_value is adjusted)
    candidates: tuple[int, ...] = ()  # power:auto: the exponents it chose from

    @property
    def verdict(self) -> str:
        chose = (
            f", adjusted for the choice of M among {', '.join(map(str, self.candidates))}; "
            f"that M alone {p_text(self.p_chosen, 3)}"
            if self.p_chosen is not None
            else ""
        )
        return f"frequency dependence supported: {'yes' if self.supported else 'no'} ({p_text(self.p_value, 3)}{chose})"

    def to_dict(self) -> dict[str, object]:
        return {
            "supported": self.supported,
            "p_value": self.p_value,
            "statistic": self.statistic,
            "test": self.test,
            "dof": list(self.dof),
            "alpha": self.alpha,
            "aic": list(self.aic),
            "bic": list(self.bic),
            "verdict": self.verdict,
        } | ({"p_chosen": self.p_chosen, "candidates": list(self.candidates)} if self.p_chosen is not None else {})


def frequency_dependence(constant: Identification, dependent: Identification, alpha: float = ALPHA) -> Adequacy:
    """Test the constant model against a frequency-dependent one fitted to the same table
    with the same method. Raises ReductionError when they are not nested fits of one table."""
    if not set(constant.free) < set(dependent.free):
        raise ReductionError(
            f"{constant.model} {constant.freq_dep} is not nested in {dependent.model} {dependent.freq_dep}"
        )
    if (constant.n_frequencies, constant.method, constant.known_noise) != (
        dependent.n_frequencies,
        dependent.method,
        dependent.known_noise,
    ):
        raise ReductionError("frequency_dependence needs two fits of one table with one method")
    q = len(dependent.free) - len(constant.free)
    if constant.known_noise:
        if constant.chi2 is None or dependent.chi2 is None:
            raise ReductionError("frequency_dependence: a fit with stated noise has no chi2")
        stat = max(constant.chi2 - dependent.chi2, 0.0)
        p = float(dist.chi2_sf(stat, q))
        test, dof = "likelihood ratio", (q, 0)
    else:
        if dependent.dof <= 0:
            raise ReductionError("frequency_dependence: the frequency-dependent fit has no degrees of freedom")
        rss0, rss1 = constant.cost, dependent.cost
        stat = max(rss0 - rss1, 0.0) / q / (rss1 / dependent.dof) if rss1 > 0 else float("inf")
        p = float(dist.f_sf(stat, q, dependent.dof))
        test, dof = "F", (q, dependent.dof)
    chosen: float | None = None
    candidates: tuple[int, ...] = ()
    if dependent.selection is not None:
        chosen, candidates = p, dependent.selection.exponents
        p = dependent.selection.p_value(p, constant.known_noise)
    return Adequacy(
        p < alpha,
        p,
        float(stat),
        test,
        dof,
        alpha,
        (constant.aic, dependent.aic),
        (constant.bic, dependent.bic),
        chosen,
        candidates,
    )
