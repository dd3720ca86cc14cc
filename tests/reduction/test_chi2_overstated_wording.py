"""A chi2 far below its degrees of freedom is reported by its lower tail: the upper-tail p
rounds to 1 there ("p = 1" reads as certainty, not as a warning), so the warning gives
P(chi2 <= value), which says how unlikely so small a chi2 is when u_* are right."""

from __future__ import annotations

import re

from scipy import stats

from reduction.statistics import chi2_p_value, chi2_warning


def test_a_too_small_chi2_gives_its_lower_tail() -> None:
    p = chi2_p_value(2.237, 69)
    assert f"{p:.4g}" == "1"  # what the warning used to print
    said = chi2_warning(2.237, 69, p)
    assert said is not None and "p = 1)" not in said and "overstated" in said
    lower = float(re.search(r"lower-tail p = ([0-9.e+-]+)\)", said)[1])
    assert abs(lower / stats.chi2.cdf(2.237, 69) - 1) < 0.01 and lower < 1e-38  # 9.2e-39
    assert chi2_warning(69.0, 69, chi2_p_value(69.0, 69)) is None  # a fit as good as its u_*
    bad = chi2_warning(200.0, 69, chi2_p_value(200.0, 69))
    assert bad is not None and bad.startswith("bad fit: chi2 = 200 for 69 degrees of freedom (p = ")
