"""The sweep writes the basis of a fit's expanded uncertainty as the text of
reduction.systematic.UncertaintyBasis, the Enum the report reads it with: plain JSON, the
strings runs stored before it have ("combined", "statistical")."""

from __future__ import annotations

import json

from orbitrig.run.point_analysis import expanded_uncertainty
from reduction.systematic import UncertaintyBasis


def test_expanded_uncertainty_basis_is_the_enums_text() -> None:
    fit = {"coefficients": {"Kxx": 5.0, "Cxx": 2.0}, "std_errors": {"Kxx": 0.5, "Cxx": None}}
    statistical = expanded_uncertainty(fit)
    combined = expanded_uncertainty({**fit, "uncertainty": {"k": 2.0, "expanded": {"Kxx": 1.5, "Cxx": 0.4}}})
    assert (statistical["basis"], combined["basis"]) == ("statistical", "combined")
    assert UncertaintyBasis(statistical["basis"]) is UncertaintyBasis.STATISTICAL
    assert UncertaintyBasis(combined["basis"]) is UncertaintyBasis.COMBINED
    assert type(statistical["basis"]) is str and type(combined["basis"]) is str  # as read back from JSON
    assert json.loads(json.dumps(combined)) == combined
    assert statistical["values"] == {"Kxx": 1.0, "Cxx": None}
