"""The simulator's truth of a point as arrays (orbitrig.store.truth_data, what RunData.truth gives):
every form a run stored it in (the true Z with its best fits; only K0, C0, D0 with null numbers;
per-row K, C, D) in the shapes docs/api.md states, NaN for null; the coefficient figure, the
exports and the terminal's comparison read these arrays as they read the stored lists."""

from __future__ import annotations

import numpy as np
import pytest

from orbitrig.analysis.plots_coefficients import truth_matrix
from orbitrig.cli.sweep_summary import compare_with_truth
from orbitrig.store.export_content import truth_arrays
from orbitrig.store.truth_data import truth_data
from support.units import UREG

K = [[3.1e7, 1e6], [-1e6, 3.0e7]]
C = [[8e4, 0.0], [0.0, 8e4]]
D = [[1.5, 0.0], [0.0, 1.5]]
#: three rows, forward, backward, forward, as orbitrig.run.truth.point_truth stores them
Z_RE = [[[3.0e7 - i * 1e5, 1e6], [-1e6, 3.0e7]] for i in range(3)]
Z_IM = [[[4e6 + i * 1e6, 0.0], [0.0, 4e6]] for i in range(3)]
STORED = {
    "definition": "Z: the simulator's true impedance ...",
    "orbit": [50.0, -50.0, 100.0],
    "orbit_hz": [8.0, 8.0, 16.0],
    "Z_re": Z_RE,
    "Z_im": Z_IM,
    "band": [50.0, 100.0],
    "fits": {
        "constant": {"K": K, "C": C, "D": D},
        "power": {"exponents": [2, 1, 3], "K0": K, "Km": D, "C0": C, "Cn": D, "D0": D, "Dp": D},
    },
    "K0": K,
    "C0": C,
    "D0": D,
}


def test_the_true_impedance_and_its_fits_are_arrays_of_the_stated_shapes_and_units():
    t = truth_data(STORED)
    assert {k: t[k].shape for k in ("orbit", "orbit_hz", "Z_re", "Z_im", "band", "K0", "C0", "D0")} == {
        "orbit": (3,),
        "orbit_hz": (3,),
        "Z_re": (3, 2, 2),
        "Z_im": (3, 2, 2),
        "band": (2,),
        "K0": (2, 2),
        "C0": (2, 2),
        "D0": (2, 2),
    }
    assert t["Z_im"][1, 0, 0] == 5e6 and t["K0"][1, 0] == -1e6 and t["orbit"][1] == -50.0
    assert t["units"] == {
        "orbit": "rad/s",
        "orbit_hz": "Hz",
        "Z_re": "N/m",
        "Z_im": "N/m",
        "band": "rad/s",
        "K0": "N/m",
        "C0": "N s/m",
        "D0": "kg",
    }
    const, power = t["fits"]["constant"], t["fits"]["power"]
    assert [const[m].shape for m in "KCD"] == [(2, 2)] * 3 and const["units"] == {"K": "N/m", "C": "N s/m", "D": "kg"}
    assert power["exponents"] == (2, 1, 3) and power["Km"].shape == (2, 2)
    assert power["units"] == {
        "K0": "N/m",
        "Km": "N/m (rad/s)^-2",
        "C0": "N s/m",
        "Cn": "N s/m (rad/s)^-1",
        "D0": "kg",
        "Dp": "kg (rad/s)^-3",
    }
    for unit in [*t["units"].values(), *const["units"].values(), *power["units"].values()]:
        UREG.parse_units(unit)
    assert UREG.parse_units(power["units"]["Cn"]) == UREG.parse_units("N s^2 / m / rad")
    assert t["definition"] == STORED["definition"]
    assert STORED["K0"] is K and isinstance(STORED["fits"]["constant"]["K"], list)  # the stored truth is left as it is


def test_an_older_truth_with_null_numbers_and_per_row_matrices():
    t = truth_data({"orbit_hz": [1.0, 2.0], "K": [K, K], "K0": [[3.1e7, None], [0, 3e7]], "C0": C, "D0": D})
    assert t["K"].shape == (2, 2, 2) and t["K0"].shape == (2, 2) and np.isnan(t["K0"][0, 1])
    assert set(t["units"]) == {"orbit_hz", "K", "K0", "C0", "D0"} and "Z_re" not in t


def test_no_truth_is_none_and_a_wrong_shape_is_refused():
    assert truth_data(None) is None
    with pytest.raises(ValueError):
        truth_data({"K0": [1.0, 2.0, 3.0]})


def test_the_figure_and_the_exports_read_the_arrays_as_the_stored_lists():
    arrays = truth_data(STORED)
    for m in "KCD":
        (w_list, list_mat), (w_arr, arr_mat) = truth_matrix(STORED, m), truth_matrix(arrays, m)
        np.testing.assert_array_equal(w_arr, [50.0, 50.0, 100.0])
        np.testing.assert_array_equal(w_list, w_arr)
        np.testing.assert_array_equal(list_mat, arr_mat)
        assert arr_mat.shape == (3, 2, 2)
    z, unit = truth_arrays(STORED)["Z"]
    assert unit == "N/m" and z.shape == (3, 2, 2) and z[2, 0, 0] == 3.0e7 - 2e5 + 6e6j
    fit = {"coefficients": {"Kxx": 3.41e7, "Kxy": 1e6, "Cyy": 7.6e4}}  # the terminal's comparison with the truth
    assert compare_with_truth(fit, arrays) == compare_with_truth(fit, STORED)
    assert compare_with_truth(fit, arrays)["Kxx"] == pytest.approx(10.0) and compare_with_truth(fit, arrays)[
        "Cyy"
    ] == pytest.approx(5.0)
