"""The sweep's closing table: full tables for a few points, one summary row per point for many."""

from __future__ import annotations

import re

from support.report_synthetic import write_synthetic_run

from orbitrig.cli import sweep_summary
from orbitrig.cli.sweep_summary import DETAIL_POINTS, print_coefficients, rejected
from orbitrig.store.reader import read_run


def test_many_points_print_one_summary_row_each(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "220")
    # the synthetic fits' stated uncertainties are generous (p about 1): rejecting every p below 1
    # marks the fits whose residuals are not negligible (kc7 without the true D), not the others
    monkeypatch.setattr(sweep_summary, "CHI2_ALPHA", 1.0)
    run = write_synthetic_run(tmp_path / "run", n_points=DETAIL_POINTS + 2, incomplete=1)
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
    kxx = next(i.result for i in stored[0].identifications if i.ok)["coefficients"]["Kxx"]
    assert re.search(rf"^Kxx\s.*\s{re.escape(f'{kxx * 1e-6:.4g}')} \u00b1 ", out, flags=re.M)
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


def test_the_full_table_marks_not_determined_coefficients_and_names_d(tmp_path, capsys, monkeypatch):
    from orbitrig.store.reader import read_run

    monkeypatch.setenv("COLUMNS", "220")
    run = write_synthetic_run(tmp_path / "run", n_points=1, incomplete=0)
    print_coefficients(run)
    out = " ".join(capsys.readouterr().out.split())
    fits = [i.result for i in read_run(run).complete_points[0].identifications if i.ok]
    nd = sum(1 for d in fits for k in d["not_determined"] if "_" not in k)  # the table shows constant terms
    assert nd and out.count(" n.d. ") == nd + 1  # each mark, and the note's "n.d. = not determined"
    assert "n.d. = not determined: the expanded uncertainty U exceeds the magnitude" in out
    if any("Dxx" in d["coefficients"] for d in fits):
        assert "D = apparent inertia (added mass)" in out
