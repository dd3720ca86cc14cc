"""Orbit table CSV round trip and unit conversion at the edge."""

from __future__ import annotations

import numpy as np
import pytest

from support.reduction_synthetic import frequencies, orbit_table, truth
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
    path.write_text(
        "note,orbit_hz,spin_rpm,x_re,x_im,y_re,y_im,fx_re,fx_im,fy_re,fy_im\na,10,600,1e-6,0,0,-1e-6,1,2,3,4\n"
    )
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


HEAD = "spin_rpm,orbit_hz,x_re,x_im,y_re,y_im,fx_re,fx_im,fy_re,fy_im"


def test_records_and_uncertainty_columns_round_trip(tmp_path):
    clean = orbit_table(truth("kc8", {"K": (0,), "C": (0,)}), frequencies(3))
    u = np.tile([1e-8, 2e-8, 0.5, 0.7], (clean.n, 1))
    table = type(clean)(
        clean.spin, clean.orbit, clean.x, clean.y, clean.fx, clean.fy, None, np.arange(40, 40 + clean.n), u
    )
    path = tmp_path / "t.csv"
    write_orbit_table(path, table)
    assert path.read_text().splitlines()[0].endswith("n_records,u_x,u_y,u_fx,u_fy")
    back = read_orbit_table(path)
    np.testing.assert_array_equal(back.u, u)
    np.testing.assert_array_equal(back.n_records, np.arange(40, 40 + clean.n))


@pytest.mark.parametrize(
    "extra_head, extra_row, column, reason",
    [
        (",u_x,u_y,u_fx", ",1e-9,1e-9,0.1", "u_fy", "set of four"),
        (",u_x,u_y,u_fx,u_fy", ",1e-9,-1e-9,0.1,0.1", "u_y", "must be >= 0"),
        (",u_x,u_y,u_fx,u_fy", ",1e-9,1e-9,abc,0.1", "u_fx", "not a number"),
        (",n_records", ",12.5", "n_records", "whole number"),
        (",n_records", ",0", "n_records", "whole number >= 1"),
    ],
)
def test_bad_records_or_uncertainty_name_line_and_column(tmp_path, extra_head, extra_row, column, reason):
    path = tmp_path / "t.csv"
    path.write_text(f"{HEAD}{extra_head}\n1000,5,1e-6,0,0,-1e-6,1,2,3,4{extra_row}\n")
    with pytest.raises(TableError, match=reason) as info:
        read_orbit_table(path)
    assert info.value.column == column
    assert info.value.line == (1 if reason == "set of four" else 2)


@pytest.mark.parametrize("parser", ["pandas", "numpy"])
def test_both_fast_parsers_read_every_decimal_to_the_same_double(tmp_path, monkeypatch, parser):
    """The fast path parses with pandas' C reader when pandas is installed, else numpy's:
    both give exactly the doubles Python's float() gives, at 17 digits and at short ones,
    and both hand a faulty table to the row-by-row reader (line and column named)."""
    if parser == "numpy":
        monkeypatch.setitem(__import__("sys").modules, "pandas", None)  # import pandas -> ImportError
    rng = np.random.default_rng(7)
    values = rng.normal(size=(500, 8)) * 10.0 ** rng.integers(-12, 6, size=(500, 8))
    cells = [[repr(v) if k % 3 else f"{v:.6g}" for k, v in enumerate(row)] for row in values.tolist()]
    rows = [",".join(["1000", repr(1 + i * 0.37)] + c) for i, c in enumerate(cells)]
    path = tmp_path / "t.csv"
    path.write_text(HEAD + "\n" + "\n".join(rows) + "\n\n")
    t = read_orbit_table(path)
    expect = np.array([[float(c) for c in row] for row in cells])
    got = np.stack([t.x.real, t.x.imag, t.y.real, t.y.imag, t.fx.real, t.fx.imag, t.fy.real, t.fy.imag], axis=1)
    np.testing.assert_array_equal(got, expect)
    path.write_text(HEAD + "\n" + rows[0] + "\n" + rows[1].replace(cells[1][3], "x7") + "\n")
    with pytest.raises(TableError) as info:
        read_orbit_table(path)
    assert (info.value.line, info.value.column) == (3, "y_im")
