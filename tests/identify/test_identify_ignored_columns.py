"""A header column that looks like a misspelt known one (``u_fX``, ``n_record``) is ignored like
any extra column, but named in an IgnoredColumnWarning (docs/orbit-table.md, "The CSV"), which
`orbitrig identify` passes on: in ``warnings`` with --json, on standard error without."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from typer.testing import CliRunner

from support.reduction_synthetic import frequencies, orbit_table, truth
from orbitrig.cli import app
from orbitrig.errors import IgnoredColumnWarning, TableError
from orbitrig.store.orbit_table import parse_orbit_table, read_orbit_table, write_orbit_table

U = "u_x,u_y,u_fx,u_fy"
MISSPELT_U = "U_x,U_y,U_fx,U_fy"


def _table_csv(path, header_from=U, header_to=U, comment=False, blank_first=False, extra=("", "")):
    """A kc8 table with u_* and n_records written to ``path``, its header's ``header_from`` made
    ``header_to``; ``comment``: a text column first (the row-by-row reader then reads it);
    ``extra``: (header, row) text appended to the header and to every row."""
    clean = orbit_table(truth("kc8", {"K": (0,), "C": (0,)}), frequencies(4))
    u = np.tile([1e-8, 2e-8, 0.5, 0.7], (clean.n, 1))
    table = type(clean)(
        clean.spin, clean.orbit, clean.x, clean.y, clean.fx, clean.fy, None, np.arange(40, 40 + clean.n), u
    )
    write_orbit_table(path, table)
    head, *rows = path.read_text().splitlines()
    assert header_from in head
    head, rows = head.replace(header_from, header_to) + extra[0], [r + extra[1] for r in rows]
    if comment:
        head, rows = "comment," + head, [f"row {k}," + r for k, r in enumerate(rows)]
    path.write_text(("\n" if blank_first else "") + "\n".join([head, *rows]) + "\n")
    return path


def _read(path, parse: bool = False):
    """The table and the IgnoredColumnWarnings of reading it (every one, not once per place)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        t = parse_orbit_table(path.read_bytes(), path) if parse else read_orbit_table(path)
    return t, [w for w in caught if issubclass(w.category, IgnoredColumnWarning)]


def _expected(path, line: int = 1) -> list[str]:
    return [
        f"{path}, line {line}, column '{bad}': not an orbit-table column, ignored (did you mean '{good}'?)"
        for bad, good in zip(MISSPELT_U.split(","), U.split(","))
    ]


@pytest.mark.parametrize("parser", ["pandas", "numpy"])
@pytest.mark.parametrize("comment", [False, True], ids=["fast-reader", "row-by-row-reader"])
def test_misspelt_uncertainty_set_is_ignored_with_one_warning_per_column(tmp_path, monkeypatch, parser, comment):
    """Through numpy's / pandas' reader (whose own warnings are filtered) and through the
    row-by-row one (after the fast reader gave up: still one warning per column)."""
    if parser == "numpy":
        monkeypatch.setitem(__import__("sys").modules, "pandas", None)  # import pandas -> ImportError
    path = _table_csv(tmp_path / "t.csv", U, MISSPELT_U, comment=comment)
    t, caught = _read(path)
    assert t.u is None and t.n_records is not None and t.n == 8
    assert [str(w.message) for w in caught] == _expected(path)
    w = caught[0].message
    assert isinstance(w, UserWarning) and (w.file, w.line, w.column, w.suggestion) == (str(path), 1, "U_x", "u_x")


def test_warning_names_the_header_line_and_comes_from_parse_too(tmp_path):
    path = _table_csv(tmp_path / "t.csv", U, MISSPELT_U, blank_first=True)
    for parse in (False, True):
        t, caught = _read(path, parse=parse)
        assert t.u is None and [str(w.message) for w in caught] == _expected(path, line=2)


@pytest.mark.parametrize(
    "bad, good",
    [
        ("n_records", "n_record"),
        ("n_records", "nrecords"),
        ("n_records", "N_Records"),
        ("n_records", "n_record [1]"),
        (U, "u x,u y,u fx,u fy"),
        (U, "ux,uy,ufx,ufy"),
    ],
)
def test_other_misspellings_are_named(tmp_path, bad, good):
    path = _table_csv(tmp_path / "t.csv", bad, good)
    _, caught = _read(path)
    assert caught and all("did you mean" in str(w.message) for w in caught)
    assert [w.message.column for w in caught] == [c.split(" [")[0] for c in good.split(",")]


@pytest.mark.parametrize(
    "spelling", ["gamma2_xFx,gamma2_yFx,gamma2_xFy,gamma2_yFy", "gamma_xfx,gamma_yfx,gamma_xfy,gamma_yfy"]
)
def test_misspelt_coherence_set_is_named(tmp_path, spelling):
    path = _table_csv(tmp_path / "t.csv", extra=("," + spelling, ",0.9,0.8,0.9,0.8"))
    t, caught = _read(path)
    assert t.gamma2 is None and t.u is not None
    assert [(w.message.column, w.message.suggestion) for w in caught] == [
        (c, f"gamma2_{c[-3:].lower()}") for c in spelling.split(",")
    ]


@pytest.mark.parametrize("comment", [False, True], ids=["numeric-extras", "text-extra"])
def test_unrelated_extra_columns_give_no_warning(tmp_path, comment):
    """comment, point, temperature_C, direction: extra columns on purpose, passed over in
    silence; only the lone misspelt coherence column beside them is named."""
    extra = (",point,temperature_C,direction,gamma2_xFx", ",3,21.5,1,0.9")
    t, caught = _read(_table_csv(tmp_path / "t.csv", comment=comment, extra=extra))
    assert [w.message.column for w in caught] == ["gamma2_xFx"] and t.u is not None and t.n == 8
    t, caught = _read(_table_csv(tmp_path / "t.csv", comment=comment, extra=(",point,temperature_C", ",3,21.5")))
    assert caught == [] and t.u is not None


def test_incomplete_set_error_names_the_look_alike(tmp_path):
    path = _table_csv(tmp_path / "t.csv", "u_fx", "u_fX")
    with pytest.raises(TableError, match="set of four") as info:
        read_orbit_table(path)
    assert (info.value.line, info.value.column) == (1, "u_fx")
    assert "(column 'u_fX' in the header looks like it)" in str(info.value)


def test_missing_required_column_error_names_the_look_alike(tmp_path):
    path = _table_csv(tmp_path / "t.csv", "fx_re", "fx_rel")
    with pytest.raises(TableError, match="required column missing") as info:
        read_orbit_table(path)
    assert info.value.column == "fx_re" and "(column 'fx_rel' in the header looks like it)" in str(info.value)


def test_identify_json_lists_the_warnings_first_exit_0(tmp_path):
    path = _table_csv(tmp_path / "t.csv", U, MISSPELT_U)
    res = CliRunner().invoke(app, ["identify", str(path), "--model", "kc8", "--json"])
    assert res.exit_code == 0, res.stderr
    d = json.loads(res.stdout)
    assert d["warnings"][:4] == _expected(path) and "chi2" not in d
    assert res.stderr == ""


def test_identify_text_prints_the_warnings_on_stderr(tmp_path):
    path = _table_csv(tmp_path / "t.csv", U, MISSPELT_U)
    res = CliRunner().invoke(app, ["identify", str(path), "--model", "kc8"])
    assert res.exit_code == 0, res.stderr
    assert all(f"warning: {m}\n" in res.stderr for m in _expected(path))
    assert "did you mean" not in res.stdout
