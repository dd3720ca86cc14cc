"""report.pdf's table pages embed the figures' font (DejaVu Sans and its bold) subset to the glyphs
they use, each at its own glyph id, with a ToUnicode map (orbitrig.analysis.pdf_text): a few
tens of kB instead of the whole files' 0.8 MB, and a reader still copies and searches the
text as written (pypdf's text extraction; fontTools reads the embedded files back)."""

from __future__ import annotations

import io
import re

from fontTools.ttLib import TTFont
from pypdf import PdfReader

from orbitrig.analysis.pdf_text import figure_font, show
from orbitrig.analysis.report_pages import TablePages
from orbitrig.analysis.report_pdf import raster_pdf

#: what the tables write: the minus sign U+2212, Greek letters, µ, subscripts, superscripts
TEXT = "K_{yx} = \u22123.505 MN/m, u_{x} = 0.25 \u00b5m, \u03a9/\u03c9 = 0.978, \u03c7\u00b2 = 14.9, \u03b5_{d} = 0.04"


def _pdf() -> bytes:
    pages = TablePages()
    pages.paragraph("Run run, point 0001: \u03c9 = 1000 rpm, \u03b2 = 0.25", bold=True)
    pages.paragraph(TEXT)
    out = io.BytesIO()
    raster_pdf([], out, None, pages)
    return out.getvalue()


def test_the_text_reads_back_as_written():
    text = PdfReader(io.BytesIO(_pdf())).pages[0].extract_text()
    assert "\u03c9 = 1000 rpm, \u03b2 = 0.25" in text
    for part in ("\u22123.505 MN/m", "0.25 \u00b5m", "\u03a9/\u03c9 = 0.978", "\u03c7\u00b2 = 14.9"):
        assert part in text, (part, text)


def test_each_font_is_a_subset_of_the_glyphs_used_at_their_own_ids():
    data = _pdf()
    assert len(data) < 60_000  # the whole fonts, deflated: 0.8 MB
    fonts = PdfReader(io.BytesIO(data)).pages[0]["/Resources"]["/Font"]
    names = []
    for ref, text in (("/F1", TEXT), ("/F2", "Run run, point 0001: \u03c9 = 1000 rpm, \u03b2 = 0.25")):
        cid = fonts[ref].get_object()["/DescendantFonts"][0].get_object()
        descriptor = cid["/FontDescriptor"].get_object()
        names.append(str(descriptor["/FontName"]))
        stream = descriptor["/FontFile2"].get_object()
        file = stream.get_data()
        assert len(file) == stream["/Length1"] and len(stream._data) < 25_000  # deflated
        face = TTFont(io.BytesIO(file))
        glyf, order = face["glyf"], face.getGlyphOrder()
        used = {int(g) for g in cid["/W"][::2]}  # the glyph ids the strings name, with their widths
        drawn = {k for k, name in enumerate(order) if k and glyf[name].numberOfContours != 0}
        parts = {order.index(c.glyphName) for g in used for c in getattr(glyf[order[g]], "components", [])}
        assert (
            used - {order.index(face.getBestCmap()[ord(" ")])} <= drawn <= used | parts
        )  # (a composite's parts: \u1e0b)
        for c in set(re.sub(r"[_{} ]", "", text)):  # each character's glyph at the id its string uses
            assert order.index(face.getBestCmap()[ord(c)]) in drawn, c
    assert re.fullmatch(r"/[A-Z]{6}\+DejaVuSans", names[0]) and re.fullmatch(r"/[A-Z]{6}\+DejaVuSans-Bold", names[1])


def test_a_combining_mark_over_a_tall_letter_is_raised_by_its_height_over_x():
    """d\u0308 (the acceleration of the sign convention): the font places its diaeresis for an x, over
    d's ascender it would sit on the stem; raised by d's height over x's (DejaVu Sans: 0.213 em),
    written as its own string, so readers still extract d\u0308."""
    font = figure_font()
    assert font.pieces("D d\u0308 x\u0308") == [("D d", 0), ("\u0308", 213), (" x", 0), ("\u0308", 0)]
    ops = show(font, b"/F1", "C \u1e0b + D d\u0308", 10.0, 100.0, 10.0)
    ys = [float(y) for y in re.findall(rb" ([\d.]+) Tm", ops)]  # each string's baseline (pt)
    assert ys == [100.0, 102.13]
