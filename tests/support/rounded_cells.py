"""A value beside its standard error as a table should show it, spelled here apart from
orbitrig.analysis.rounding so that a test of that rule can fail."""

from __future__ import annotations


def with_error(value: float, std: float) -> str:
    """'33.022 ± 0.073': `std` (0 < std < 99.5 in the table's unit) to 2 significant digits
    ('#.2g' keeps a trailing zero: 0.0996 -> '0.10', 11.4 -> '11.'), `value` to the same decimal."""
    assert 0 < std < 99.5, std  # '#.2g' writes 100 and above with an exponent
    u = f"{std:#.2g}"
    decimals = len(u.split(".")[1])
    shown = f"{value:.{decimals}f}"
    return f"{f'{0.0:.{decimals}f}' if float(shown) == 0 else shown} \u00b1 {u.rstrip('.')}"
