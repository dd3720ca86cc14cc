"""report.pdf from the PNGs when no vector file is asked for, and figures reused by a later
report of an unchanged point (orbitrig.analysis.report_pdf, orbitrig.analysis.report_cache)."""

from __future__ import annotations

import dataclasses
import shutil
import struct
import zlib

import numpy as np
import pytest
from PIL import Image
from pypdf import PdfReader
from typer.testing import CliRunner

from orbitrig.analysis import plots
from orbitrig.analysis.report import ReportOptions, make_report
from orbitrig.analysis.report_cache import point_key
from orbitrig.analysis.report_pdf import combine_pdf
from orbitrig.cli import app
from orbitrig.store.reader import read_run

QUICK = ReportOptions(figures=frozenset({"coherence", "lms"}))  # two of the cheaper kinds


@pytest.fixture(scope="module")
def stored(synthetic_run, tmp_path_factory):
    """A copy of the session's synthetic run (two complete points), without its plots."""
    run = shutil.copytree(synthetic_run, tmp_path_factory.mktemp("reuse") / "run")
    shutil.rmtree(run / "plots", ignore_errors=True)
    return run


@pytest.fixture(scope="module")
def first(stored, tmp_path_factory):
    """A report (QUICK) of that copy, which no test changes."""
    return make_report(stored, options=QUICK)


def _stamps(report):
    return {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in report.plots}


def test_report_pdf_carries_every_png_unchanged(first):
    report = first
    names = [p.name for p in report.plots]
    assert names == ["coherence_0000.png", "lms_0000.png", "coherence_0001.png", "lms_0001.png", "summary.png"]
    assert not list(report.directory.glob("*_000?.pdf")) and not list(report.directory.glob("*.svg"))
    pages = PdfReader(report.pdf).pages
    assert report.table_pages >= 2  # the tables first, each point from a page of its own (test_report_pdf_tables)
    assert len(pages) == report.table_pages + len(report.plots)  # then every figure, the summary included, in order
    for page, png in zip(pages[report.table_pages :], report.plots):
        with Image.open(png) as img:
            assert img.mode == "RGB" and img.info["dpi"][0] == pytest.approx(300, abs=0.5)
            width, height = img.size
        image = page["/Resources"]["/XObject"]["/Im0"].get_object()
        assert (image["/Width"], image["/Height"], image["/ColorSpace"]) == (width, height, "/DeviceRGB")
        assert image["/DecodeParms"]["/Columns"] == width and image["/DecodeParms"]["/Colors"] == 3
        assert image._data == _idat(png.read_bytes()), png.name  # the PNG's own pixels, unchanged
        assert len(zlib.decompress(image._data)) == height * (1 + 3 * width)  # rows: filter byte + RGB
        assert width / 300 == pytest.approx(plots.COLUMN_WIDTHS["double"], abs=0.01)
        assert float(page.mediabox.width) == pytest.approx(width / 300 * 72, abs=0.1)
        assert float(page.mediabox.height) == pytest.approx(height / 300 * 72, abs=0.1)


def _idat(data: bytes) -> bytes:
    """The concatenated IDAT chunks of a PNG file."""
    out, at = [], 8
    while at < len(data):
        length, kind = struct.unpack(">I4s", data[at : at + 8])
        if kind == b"IDAT":
            out.append(data[at + 8 : at + 8 + length])
        at += 12 + length
    return b"".join(out)


def test_a_png_of_another_colour_type_is_converted(tmp_path):
    """A PNG with alpha (an older report's) becomes RGB rows without filters, at its stated dpi."""
    rgba = np.random.default_rng(3).integers(0, 256, (30, 40, 4), dtype=np.uint8)
    png = tmp_path / "old.png"
    Image.fromarray(rgba).save(png, dpi=(150, 150))
    combine_pdf([png], tmp_path / "one.pdf")
    page = PdfReader(tmp_path / "one.pdf").pages[0]
    image = page["/Resources"]["/XObject"]["/Im0"].get_object()
    rows = np.frombuffer(zlib.decompress(image._data), np.uint8).reshape(30, 1 + 3 * 40)
    assert not rows[:, 0].any() and np.array_equal(rows[:, 1:].reshape(30, 40, 3), rgba[..., :3])
    assert float(page.mediabox.width) == pytest.approx(40 / 150 * 72, abs=0.1)
    assert combine_pdf([], tmp_path / "one.pdf") is None and not (tmp_path / "one.pdf").exists()


def test_an_unchanged_point_reuses_its_figures_until_something_changes(first, tmp_path):
    run = shutil.copytree(first.run.directory, tmp_path / "run")  # with the first report's plots
    calls = []
    again = make_report(run, options=QUICK, progress=lambda *a: calls.append(a))
    assert calls[-1] == (2, 2, 0)  # the closing line says no figure was drawn
    assert [p.name for p in again.plots] == [p.name for p in first.plots]
    stamps = _stamps(again)
    for name, (_, mtime) in stamps.items():  # copied, not drawn again (the summary depends on every point)
        assert (mtime == (first.directory / name).stat().st_mtime_ns) == (name != "summary.png"), name
    assert len(PdfReader(again.pdf).pages) == again.table_pages + len(again.plots)
    assert again.table_pages == first.table_pages  # the tables of the reused points too
    (run / "plots" / "lms_0001.png").unlink()  # a figure gone: its point is drawn again
    third = _stamps(make_report(run, options=QUICK))
    assert {k for k, v in third.items() if stamps[k] != v} == {"lms_0001.png", "coherence_0001.png", "summary.png"}
    result = CliRunner().invoke(app, ["report", str(run), "--point", "0", "--figures", "coherence", "--coverage", "1"])
    assert result.exit_code == 0, result.output  # other kinds and another style: drawn again
    assert (run / "plots" / "coherence_0000.png").stat().st_mtime_ns != third["coherence_0000.png"][1]
    assert not (run / "plots" / "lms_0000.png").exists()  # --figures still drops the other kinds
    for name in ("coherence_0001.png", "lms_0001.png"):  # a point not asked for is left alone
        assert (run / "plots" / name).stat().st_mtime_ns == third[name][1]


@pytest.mark.parametrize("damage", ['{"key":', "[" * 100_000 + "]" * 100_000], ids=["torn", "nested-too-deeply"])
def test_a_damaged_figure_record_has_its_point_drawn_again(first, tmp_path, damage):
    """A record nested too deeply was a RecursionError traceback (exit 1); a torn one was redrawn."""
    run = shutil.copytree(first.run.directory, tmp_path / "run")
    (run / "plots" / ".figures" / "0001.json").write_text(damage)
    before = (run / "plots" / "lms_0001.png").stat().st_mtime_ns
    result = CliRunner().invoke(app, ["report", str(run), "--figures", "coherence,lms"])
    assert result.exit_code == 0 and result.exception is None, result.output
    assert (run / "plots" / "lms_0001.png").stat().st_mtime_ns != before


def test_the_key_follows_the_stored_point_and_the_options(stored):
    key = point_key(read_run(stored).points[0], QUICK)
    assert point_key(read_run(stored).points[0], QUICK) == key  # read again: the same key
    changed = read_run(stored).points[0]
    table = changed.tables["piezo"]
    changed.tables["piezo"] = dataclasses.replace(table, fx=table.fx * 1.001)
    assert point_key(changed, QUICK) != key
    assert point_key(read_run(stored).points[0], ReportOptions(figures=QUICK.figures, all_frequencies=True)) != key
