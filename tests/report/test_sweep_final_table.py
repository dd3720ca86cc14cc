"""The sweep's closing table: full tables for a few points, one summary row per point for many."""

from __future__ import annotations

import re

import pytest

from support.report_synthetic import write_synthetic_run

from orbitrig.analysis.rounding import at_decimals, uncertainty_decimals, with_uncertainty
from orbitrig.cli import sweep_summary
from orbitrig.cli.sweep_summary import DETAIL_POINTS, print_coefficients, rejected
from orbitrig.store.reader import freq_dep_key, read_run


@pytest.fixture(scope="module")
def many_points(tmp_path_factory):
    """More points than get full tables (and one incomplete): the closing table only reads the run."""
    return write_synthetic_run(tmp_path_factory.mktemp("many") / "run", n_points=DETAIL_POINTS + 2, incomplete=1)


@pytest.fixture(scope="module")
def one_point(tmp_path_factory):
    return write_synthetic_run(tmp_path_factory.mktemp("one") / "run", n_points=1, incomplete=0)


def test_many_points_print_one_summary_row_each(many_points, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "220")
    # the synthetic fits' stated uncertainties are generous (p about 1): rejecting every p below 1
    # marks the fits whose residuals are not negligible (kc7 without the true D), not the others
    monkeypatch.setattr(sweep_summary, "CHI2_ALPHA", 1.0)
    run = many_points
    print_coefficients(run)
    out = capsys.readouterr().out
    assert f"{DETAIL_POINTS + 2} operating points" in out
    rows = re.findall(r"^\S*\s*(\d{4})\s", out, flags=re.M)
    assert rows == [f"{i:04d}" for i in range(DETAIL_POINTS + 2)]  # the incomplete point is not listed
    errors = [float(k) for k, _ in re.findall(r"(\d+\.\d) % / (\d+\.\d) %", out)]
    assert len(errors) == DETAIL_POINTS + 2 and max(errors) < 5.0
    assert "Kxx" not in re.sub(r"Kxx MN/m", "", out)  # no per-coefficient tables
    # fits the chi2 adequacy test rejects: counted per point and named per fit family with their points
    stored = read_run(run, blocks=False).complete_points
    for p in stored:
        n = sum(rejected(i.result) for i in p.identifications if i.ok)
        assert re.search(rf"^\S*\s*{p.name}\s.*\s{n} of {sum(i.ok for i in p.identifications)}\s", out, flags=re.M), (
            p.name
        )
    families = {
        f"{i.model} {i.freq_dep} {i.method}" for p in stored for i in p.identifications if i.ok and rejected(i.result)
    }
    every = {f"{i.model} {i.freq_dep} {i.method}" for p in stored for i in p.identifications if i.ok}
    assert families and families != every and "rejected * = fits the chi2 adequacy test rejects" in out
    assert sorted(re.findall(r"^rejected: (.+?), (?:piezo|strain)", out, flags=re.M)) == sorted(families)


def test_few_points_print_the_full_tables(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "220")
    run = write_synthetic_run(tmp_path / "run", n_points=2, incomplete=0)
    print_coefficients(run)
    out = capsys.readouterr().out
    titles = re.findall(r"^point \d{4}  \S", out, flags=re.M)  # one table per point, then its judgement lines
    assert len(titles) == 2 and "Cyy" in out and "operating points" not in out
    stored = read_run(run, blocks=False).complete_points
    assert "units: K MN/m, C kN s/m, D kg" in out  # rigunits.display_unit, as reduce and identify
    first = next(i.result for i in stored[0].identifications if i.ok)
    kxx, u = first["coefficients"]["Kxx"], first["expanded_uncertainty"]["values"]["Kxx"]
    assert re.search(rf"^Kxx\s.*\s{re.escape(with_uncertainty(kxx * 1e-6, u * 1e-6))}", out, flags=re.M)
    assert not any(rejected(i.result) for p in stored for i in p.identifications if i.ok)
    assert " *" not in out and "adequacy test rejects" not in out  # nothing rejected, nothing marked
    monkeypatch.setattr(sweep_summary, "CHI2_ALPHA", 1.0)  # as above: the fits with residuals are rejected
    print_coefficients(run)
    out = capsys.readouterr().out
    marked = re.findall(r"(piezo|strain) (\S+) (\S+) \*", out)
    expected = {
        (i.lms, i.model, i.method)
        for p in stored
        for i in p.identifications
        if i.ok and rejected(i.result) and i.freq_dep == "none"
    }
    assert expected and set(marked) >= expected and "* the fit's chi2 adequacy test rejects it" in out


def test_the_full_table_marks_not_determined_coefficients_and_names_d(one_point, capsys, monkeypatch):
    from orbitrig.store.reader import read_run

    monkeypatch.setenv("COLUMNS", "220")
    run = one_point
    print_coefficients(run)
    out = " ".join(capsys.readouterr().out.split())
    fits = [i.result for i in read_run(run).complete_points[0].identifications if i.ok]
    nd = sum(1 for d in fits for k in d["not_determined"] if "_" not in k)  # the table shows constant terms
    assert nd and out.count(" n.d. ") == nd + 1  # each mark, and the note's "n.d. = not determined"
    assert "n.d. = not determined: the expanded uncertainty U exceeds the magnitude" in out
    assert (
        "\u00b1 = expanded uncertainty U (a coverage probability of about 95 %: k = 2, or Student's t at the "
        "effective degrees of freedom where a part of U is estimated from few; coefficients.csv's KEY_k): "
        "statistical (type A) and calibration (type B) combined"
    ) in out
    if any("Dxx" in d["coefficients"] for d in fits):
        assert "D = apparent inertia (added mass)" in out


def test_each_value_is_rounded_to_the_decimal_of_its_uncertainty(one_point, many_points, capsys, monkeypatch):
    """'33.79 ± 0.21': U to 2 significant digits and the value (and its truth) to U's decimal, as
    reduce, the report and the dashboard round (orbitrig.analysis.rounding), not 4 significant
    digits whatever the uncertainty ('34.57 ± 1.9'); the summary row's terms alike."""
    from orbitrig.store.csvfile import fit_truth
    from rigunits import display_unit

    monkeypatch.setenv("COLUMNS", "400")
    run = one_point
    print_coefficients(run)
    out = capsys.readouterr().out
    point = read_run(run, blocks=False).complete_points[0]
    fits = [i.result for i in point.identifications if i.ok]
    cells, trues = [], []
    for d in fits:
        for key, v in d["coefficients"].items():
            u = d["expanded_uncertainty"]["values"].get(key)
            if "_" in key or u is None:
                continue
            scale = display_unit(key)[1]
            cells.append(with_uncertainty(v * scale, u * scale))
            trues.append(at_decimals(fit_truth(d, point.truth)[key] * scale, uncertainty_decimals(u * scale)))
    shown = re.findall(r"(-?\d[\d.]*) \u00b1 (\d[\d.]*)", out)
    assert sorted(f"{v} \u00b1 {u}" for v, u in shown) == sorted(cells)
    true_rows = [line.split()[1:] for line in out.splitlines() if line.startswith("  true")]
    assert sorted(c for row in true_rows for c in row) == sorted(trues)

    many = many_points
    print_coefficients(many)
    out = capsys.readouterr().out
    for p in read_run(many, blocks=False).complete_points:
        fits = {
            f"{i.lms}__{i.model}__{freq_dep_key(i.freq_dep)}__{i.method}": i.result for i in p.identifications if i.ok
        }
        d = fits[min(k for k in fits if k.startswith("piezo"))]  # the row's fit: the first piezo one
        row = re.search(
            rf"^{p.name}\s+{re.escape(p.settings.label)}\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s", out, flags=re.M
        )
        assert row, p.name
        for key, cell in zip(("Kxx", "Kyy", "Cxx", "Cyy"), row.groups()):
            scale, u = display_unit(key)[1], d["expanded_uncertainty"]["values"][key]
            assert cell == at_decimals(d["coefficients"][key] * scale, uncertainty_decimals(u * scale)), (p.name, key)


def test_the_constant_best_fit_is_rounded_as_the_fits_truth(one_point, capsys, monkeypatch):
    """The 'const. fit' column to the finest decimal of the fits' U, as their 'true' rows: a
    numerically zero entry of the simulator's constant fit reads 0.000, never 7.112e-15."""
    from orbitrig.cli.plain_table import OutputFormat, Transcript
    from rigunits import display_unit

    monkeypatch.setenv("COLUMNS", "400")
    point = read_run(one_point, blocks=False).complete_points[0]
    point.truth["C0"][0][1] = 7.112e-15 / display_unit("Cxy")[1]  # as the simulator's clean bearing stores it
    console = Transcript()
    sweep_summary._print_points(console, [point])  # print_coefficients' tables, of the point as altered
    console.write(OutputFormat.TEXT)
    out = capsys.readouterr().out
    fits = [i.result for i in point.identifications if i.ok]
    for key in ("Kxx", "Kxy", "Cxx", "Cxy", "Dyy"):
        scale = display_unit(key)[1]
        decimals = max(
            uncertainty_decimals(d["expanded_uncertainty"]["values"][key] * scale)
            for d in fits
            if key in d["coefficients"]
        )
        want = at_decimals(point.truth[key[0] + "0"]["xy".index(key[1])]["xy".index(key[2])] * scale, decimals)
        assert re.search(rf"^{key}\s+{re.escape(want)}\s", out, flags=re.M), (key, want)
    assert "e-15" not in out and re.search(r"^Cxy\s+0\.0+\s", out, flags=re.M)
