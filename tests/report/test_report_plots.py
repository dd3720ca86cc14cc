"""`orbitrig report DIR`: PNG plots and the HTML page."""

from __future__ import annotations

import re
import struct

import pytest
from typer.testing import CliRunner

from orbitrig.cli import app
from orbitrig.reduce import coefficient_unit

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def png_size(path):
    """(width, height) from the IHDR chunk, after checking the signature."""
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC, f"{path} is not a PNG"
    assert data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def test_report_writes_every_plot(synthetic_report):
    names = {p.name for p in synthetic_report.plots}
    assert names == {
        "forces_0000_piezo.png", "forces_0000_strain.png",
        "coefficients_0000_piezo_kcd11.png", "coefficients_0000_strain_kcd11.png",
        "coefficients_0000_piezo_kc7.png", "coefficients_0000_strain_kc7.png",
        "coherence_0000.png", "lms_0000.png",
    }  # fmt: skip
    for path in synthetic_report.plots:
        assert path.parent == synthetic_report.directory == synthetic_report.run.directory / "plots"
        w, h = png_size(path)
        assert w >= 800 and h >= 400
        assert path.stat().st_size > 30_000  # drawn content, not an empty canvas


def test_repeated_identifications_match_the_stored_ones(synthetic_report):
    (pr,) = synthetic_report.points
    assert pr.mismatches == []
    assert {(r.model, r.freq_dep) for r in pr.results["piezo"]} == {("kcd11", "none"), ("kc7", "none"), ("kcd11", "power:1")}


def test_html_references_every_plot_and_shows_coefficients(synthetic_report):
    html = synthetic_report.html.read_text(encoding="utf-8")
    assert synthetic_report.html == synthetic_report.directory / "index.html"
    sources = set(re.findall(r'<img src="([^"]+)"', html))
    assert sources == {p.name for p in synthetic_report.plots}
    assert not re.search(r'(src|href)="(https?:)?//', html) and "<script" not in html  # self-contained
    (pr,) = synthetic_report.points
    for r in pr.results["strain"]:
        for key, value in r.identification.coefficients.items():
            unit, scale = coefficient_unit(key)
            assert f"{value * scale:.4g}" in html, key
            assert f"{r.identification.std_errors[key] * scale:.2g}" in html, key
    for text in ("MN/m", "kN s/m", "kg", "stopped", "1 incomplete (0001)", "1000 rpm", "0.4826 MPa", "true (simulator)"):
        assert text in html
    assert "kcd12 poly:2 refused" in html  # the sweep's refusal is shown, with its reason
    assert "\u03b3\u00b2 x, Fx" in html  # the coherence table (paper Table 1)


def test_coefficient_units():
    assert coefficient_unit("Kxy") == ("MN/m", 1e-6)
    assert coefficient_unit("Cyy_2") == ("kN s/m (rad/s)^-2", 1e-3)
    assert coefficient_unit("Dxx") == ("kg", 1.0)


def test_cli_report(synthetic_run):
    result = CliRunner().invoke(app, ["report", str(synthetic_run), "--point", "1"])
    assert result.exit_code == 0, result.output
    assert "2 complete point(s), 1 incomplete" in result.stdout
    plots = synthetic_run / "plots"
    assert (plots / "index.html").is_file() and (plots / "forces_0001_piezo.png").is_file()
    assert not (plots / "forces_0000_piezo.png").exists()


@pytest.mark.parametrize("point", ["2", "7"])
def test_cli_report_point_not_complete(synthetic_run, point):
    result = CliRunner().invoke(app, ["report", str(synthetic_run), "--point", point])
    assert result.exit_code == 2 and "no complete operating point" in result.stderr


def test_cli_report_bad_directory(tmp_path):
    result = CliRunner().invoke(app, ["report", str(tmp_path / "missing")])
    assert result.exit_code == 2 and "no such directory" in result.stderr
    (tmp_path / "run.h5").write_text("not hdf5")
    result = CliRunner().invoke(app, ["report", str(tmp_path)])
    assert result.exit_code == 2 and str(tmp_path / "run.h5") in result.stderr
