"""Models and frequency dependence: coefficient counts, minimum frequencies, names."""

from __future__ import annotations

import pytest

from reduction.errors import ReductionError
from reduction.models import FreqDepKind, is_constant, model_spec, parse_freq_dep, resolved_freq_dep


@pytest.mark.parametrize(
    "model, freq_dep, n, min_freq",
    [
        ("kc7", "none", 7, 2),
        ("kc8", "none", 8, 2),
        ("kcd11", "none", 11, 3),
        ("kcd12", "none", 12, 3),
        # the paper's counts where no K order is absorbed: 14 -> 4, 21 -> 6, 22 (power:1) -> 6
        ("kc7", "power:1", 14, 4),
        ("kc7", "poly:2", 21, 6),
        ("kcd11", "power:1,2,3", 22, 6),
        ("kcd11", "power:1", 22, 6),
        ("kc8", "power:2", 16, 4),
        # v2: inertia absorbs the colliding stiffness orders (22 -> 18, 33 -> 29, 24 -> 20, 36 -> 32)
        ("kcd11", "power:2", 18, 5),
        ("kcd11", "poly:2", 29, 8),
        ("kcd12", "power:2", 20, 5),
        ("kcd12", "poly:2", 32, 8),
        ("kcd11", "power:2,1,1", 18, 5),
        ("kcd11", "power:4,2,2", 18, 5),
    ],
)
def test_counts_and_minimum_frequencies(model, freq_dep, n, min_freq):
    spec = model_spec(model, freq_dep)
    assert spec.n_coefficients == n
    assert spec.min_frequencies == min_freq


def test_absorbed_orders_are_omitted_from_the_keys_and_noted():
    spec = model_spec("kcd11", "poly:2")
    assert spec.absorbed == (2,)
    assert "Kxx_2" not in spec.keys() and {"Kxx_1", "Cxx_2", "Dxx_2", "Dyx_2"} <= set(spec.keys())
    assert len(spec.notes) == 1 and "K order 2" in spec.notes[0] and "skew-symmetric" in spec.notes[0]
    assert "skew-symmetric" not in model_spec("kcd12", "poly:2").notes[0]  # kcd12's D keeps it
    assert model_spec("kc8", "poly:2").absorbed == () and model_spec("kc8", "poly:2").notes == []


def test_names_follow_the_spec():
    spec = model_spec("kcd11", "power:1,2,3")
    keys = spec.keys()
    assert keys[:4] == ["Kxx", "Kxy", "Kyx", "Kyy"]
    assert {"Kxx_1", "Cyy_2", "Dxy_3", "Dyx_3"} <= set(keys)
    assert not any(k.startswith(("K", "C", "D")) and k.endswith("_0") for k in keys)
    assert len(keys) == 24  # all 12 entries of both orders
    # the symmetric inertia pair is one free coefficient, repeated in the output
    assert "Dyx" not in spec.names and "Dxy" in spec.names
    values = spec.expand(range(spec.n_coefficients))
    assert values["Dxy"] == values["Dyx"] and values["Dxy_3"] == values["Dyx_3"]
    assert "Dxx" not in model_spec("kc8").keys()


def test_kc7_damping_is_symmetric_and_no_inertia():
    spec = model_spec("kc7", "poly:2")
    assert [k for k in spec.keys() if k.startswith("D")] == []
    assert "Cyx_2" in spec.keys() and "Cyx_2" not in spec.names


@pytest.mark.parametrize("bad", ["power", "power:0", "power:1,2", "poly:x", "cubic:2", "poly:1,2", "power:-1"])
def test_bad_freq_dep_is_refused(bad):
    with pytest.raises(ReductionError, match="freq-dep"):
        parse_freq_dep(bad)


def test_unknown_model_is_refused():
    with pytest.raises(ReductionError, match="unknown model"):
        model_spec("kc9")


def test_power_auto_parses_but_has_no_fixed_list():
    assert parse_freq_dep("power:auto").auto
    with pytest.raises(ReductionError):
        model_spec("kc7", "power:auto")


@pytest.mark.parametrize(
    ("spec", "kind", "text"),
    [
        ("none", FreqDepKind.NONE, "none"),
        (" None ", FreqDepKind.NONE, "none"),
        ("", FreqDepKind.NONE, "none"),
        ("power:2", FreqDepKind.POWER, "power:2"),
        ("POWER:1, 2 ,3", FreqDepKind.POWER, "power:1,2,3"),
        ("power:auto", FreqDepKind.POWER, "power:auto"),
        ("poly:2", FreqDepKind.POLY, "poly:2"),
    ],
)
def test_freq_dep_kind_and_canonical_text(spec, kind, text):
    fd = parse_freq_dep(spec)
    assert (fd.kind, fd.text) == (kind, text)
    assert fd.constant is (kind is FreqDepKind.NONE) is is_constant(spec)


def test_power_auto_resolves_to_the_chosen_exponent_and_nothing_else_changes():
    assert resolved_freq_dep("power:auto", 3) == "power:3"
    assert resolved_freq_dep(" Power:Auto", 2) == "power:2"
    assert resolved_freq_dep("power:1,2,3", 4) == "power:1,2,3"
    assert resolved_freq_dep("none", None) == "none"
