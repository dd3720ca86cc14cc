"""The page's results table (static/results.js) rounds a coefficient beside its uncertainty as the
report and the terminal do (orbitrig.analysis.rounding), run in the real browser the dashboard
tests drive: U to 2 significant digits, the value to U's decimal, never '-0.00'; where U is
missing or its decimal is far from a table's (outside 10^-6 .. 10^3) both keep 4 significant digits."""

from __future__ import annotations

from pathlib import Path

import orbitrig.dashboard
from orbitrig.analysis.rounding import at_decimals, uncertainty_decimals

STATIC = Path(orbitrig.dashboard.__file__).parent / "static"

#: (value, U) in display units: ordinary results, U rounding up a decade (0.0996 -> 0.10), U of tens and
#: hundreds (value to tens), a value that rounds to zero from below, exact binary halves at U's decimal
PAIRS = [(33.7854, 0.8667), (-28.68, 31.2), (12.3456, 0.0996), (1234.5, 96.0), (-0.004, 0.31)]
PAIRS += [(5.1234e-3, 2.3e-4), (8765.4, 1234.0), (0.125, 0.031), (0.375, 0.052), (12.5, 3.1), (-2.5, 1.2)]
PAIRS += [(1.0, 0.05), (0.0, 0.44), (-7.25, 0.5), (3.0, 0.95), (41.0, 0.0995)]


def _python(v: float, u: float) -> list[str]:
    d = uncertainty_decimals(u)
    assert d is not None and -3 <= d <= 6
    return [at_decimals(v, d), at_decimals(u, d)]


def test_the_page_rounds_a_value_beside_its_uncertainty_as_the_report(driver):
    driver.get("about:blank")
    script = (STATIC / "results.js").read_text(encoding="utf-8")
    shown = driver.execute_script(script + "\nreturn arguments[0].map(p => valueAndU(p[0], p[1]));", PAIRS)
    assert shown == [_python(v, u) for v, u in PAIRS]
    assert shown[:4] == [["33.79", "0.87"], ["-29", "31"], ["12.35", "0.10"], ["1234", "96"]]  # 1234.5: to even
    assert shown[4] == ["0.00", "0.31"] and shown[6] == ["8800", "1200"]  # never -0.00; to hundreds
