"""The keys of the `identify` output object, in the contract's order (orbit-table.md v3)."""

from __future__ import annotations

#: the object's keys when the table carries uncertainties u_* (chi2 and p_value present)
KEYS_WITH_UNCERTAINTY = (
    "model",
    "freq_dep",
    "method",
    "n_coefficients",
    "min_frequencies",
    "n_frequencies",
    "coefficients",
    "units",
    "std_errors",
    "confidence_95",
    "free",
    "covariance",
    "dof",
    "condition_number",
    "residual_rms",
    "chi2",
    "p_value",
    "aic",
    "bic",
    "interval",
    "not_determined",
    "notes",
    "warnings",
    "fit",
)
#: ... and without u_* (no chi2, no p_value)
KEYS = tuple(k for k in KEYS_WITH_UNCERTAINTY if k not in ("chi2", "p_value"))


def keys(has_uncertainty: bool) -> list[str]:
    """The object's keys, in order, for a table with or without u_* columns."""
    return list(KEYS_WITH_UNCERTAINTY if has_uncertainty else KEYS)
