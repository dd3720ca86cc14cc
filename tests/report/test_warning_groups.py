"""Each distinct fit warning once per fit family, with a count and the points it concerns."""

from __future__ import annotations

from orbitrig.analysis.warning_groups import FitWarnings, group_warnings, point_ranges, warning_kind, warning_lines
from reduction.statistics import chi2_warning


def _bad(chi2: float) -> str:
    return chi2_warning(chi2, 12, 1e-9)


def _paper_like(n_points: int = 108, bad_at=range(83)) -> list[FitWarnings]:
    """kc7 none ols misses the apparent inertia at `bad_at` on both systems; kcd11 never does."""
    fits = []
    for p in range(n_points):
        for lms in ("piezo", "strain"):
            warned = (_bad(100.0 + p + (lms == "strain")),) if p in bad_at else ()
            fits.append(FitWarnings(p, lms, "kc7 none ols", warned))
            fits.append(FitWarnings(p, lms, "kcd11 none ols", ()))
    return fits


def test_166_warnings_become_one_line_per_family_with_count_points_and_a_fit_without_it():
    fits = _paper_like()
    assert sum(len(f.warnings) for f in fits) == 166  # 83 points x 2 systems, all different numbers
    (g,) = group_warnings(fits)
    assert (g.fit, g.systems, g.head, len(g.points), g.total) == (
        "kc7 none ols",
        ("piezo", "strain"),
        "bad fit",
        83,
        108,
    )
    assert g.points == tuple(range(83)) and g.see == ("kcd11 none ols",)
    (line,) = warning_lines(fits)
    assert line.startswith("kc7 none ols, both systems: bad fit at 83 of 108 points (0000-0082) - the residuals exceed")
    assert line.endswith("; see kcd11 none ols")


def test_one_system_other_kinds_and_no_see_when_every_family_has_it():
    fits = [FitWarnings(p, "strain", "kc7 none ols", (_bad(50.0 + p),)) for p in (1, 2, 3, 7)]
    fits += [FitWarnings(p, "piezo", "kc7 none ols", ()) for p in range(10)]
    fits += [FitWarnings(5, "piezo", "kc7 none ols", ("ill-conditioned: cond = 3e9",))]
    groups = group_warnings(fits)
    assert [(g.head, g.systems, g.points, g.total, g.see) for g in groups] == [
        ("bad fit", ("strain",), (1, 2, 3, 7), 10, ()),
        ("ill-conditioned", ("piezo",), (5,), 10, ()),
    ]
    assert warning_lines(fits)[0].startswith("kc7 none ols, strain: bad fit at 4 of 10 points (0001-0003, 0007)")


def test_kind_and_ranges():
    assert warning_kind(_bad(3.0))[0] == "bad fit"
    assert warning_kind(_bad(3.0))[1].startswith("the residuals exceed the stated u_* uncertainties")
    assert warning_kind("no colon here") == ("no colon here", "")
    assert point_ranges([5, 0, 1, 2, 9, 10]) == "0000-0002, 0005, 0009-0010"
    assert point_ranges(range(0, 40, 2), most=3) == "0000, 0002, 0004, ... (17 more)"
    assert group_warnings([]) == [] and warning_lines([FitWarnings(0, "piezo", "kc7 none ols", ())]) == []
