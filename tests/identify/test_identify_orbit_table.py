"""Orbit table CSV round trip and unit conversion at the edge."""

from __future__ import annotations

import numpy as np
import pytest

from reduction_synthetic import frequencies, orbit_table, truth
from orbitrig.errors import TableError
from orbitrig.store.orbit_table import read_orbit_table, write_orbit_table


def test_round_trip_is_exact(tmp_path):
    table = orbit_table(truth("kc8", {"K": (0,), "C": (0,)}), frequencies(3), gamma2=[0.9, 0.8, 0.7, 0.6])
    path = tmp_path / "t.csv"
    write_orbit_table(path, table)
    back = read_orbit_table(path)
    assert back.spin == pytest.approx(table.spin, rel=1e-15)
    np.testing.assert_allclose(back.orbit, table.orbit, rtol=1e-15)
    for name in ("x", "y", "fx", "fy", "gamma2"):
        np.testing.assert_array_equal(getattr(back, name), getattr(table, name))


def test_units_column_order_and_extra_columns(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("note,orbit_hz,spin_rpm,x_re,x_im,y_re,y_im,fx_re,fx_im,fy_re,fy_im\n"
                    "a,10,600,1e-6,0,0,-1e-6,1,2,3,4\n")
    t = read_orbit_table(path)
    assert t.spin == pytest.approx(2 * np.pi * 10) and t.orbit[0] == pytest.approx(2 * np.pi * 10)
    assert t.y[0] == -1e-6j and t.fy[0] == 3 + 4j and t.gamma2 is None


def test_table_error_carries_file_line_column(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("spin_rpm,orbit_hz,x_re,x_im,y_re,y_im,fx_re,fx_im,fy_re,fy_im\n1000,5,1e-6,0,0,-1e-6,1,2,3,4,9\n")
    with pytest.raises(TableError) as info:
        read_orbit_table(path)
    assert (info.value.file, info.value.line) == (str(path), 2) and info.value.column.startswith("#11")


def test_header_only_is_malformed(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("spin_rpm,orbit_hz,x_re,x_im,y_re,y_im,fx_re,fx_im,fy_re,fy_im\n")
    with pytest.raises(TableError, match="no data rows"):
        read_orbit_table(path)
