"""Text on report.pdf's table pages, written as PDF text operators in the figures' font.

The font is the one matplotlib draws the figures' text in (rcParams' sans-serif, DejaVu Sans, and
its bold), embedded as TrueType (Type0 / CIDFontType2, Identity-H: a string is its glyph ids)
subset to the glyphs the pages use (fontTools, each glyph keeping its id; 16 kB a font instead of
the whole file's 0.4 MB deflated), with each glyph's width and a ToUnicode map, so a reader copies
and searches the text as written (the minus sign U+2212, Greek letters, µ, subscripts).
matplotlib's own PDF text cost about 0.7 ms a string and 0.3 s to subset the fonts of each file
(a point's tables hold some 800 strings: 0.6 s a point); this writes a string in some µs, widths
from matplotlib's FreeType face, and subsets each font once a report.pdf.

A text of the tables' markup (orbitrig.analysis.table_rows): ``K_{xx}`` draws its subscript at
:data:`SUB_SCALE` of the text's size, lowered by :data:`SUB_DROP` of it.
"""

from __future__ import annotations

import functools
import hashlib
import io
import re
import zlib

SUB_SCALE = 0.75
SUB_DROP = 0.22
_SEGMENT = re.compile(r"_\{([^}]*)\}")
_MARK = re.compile("([\u0300-\u036f])")  # a combining mark (d\u0308): drawn for a letter of x-height


def segments(text: str) -> list[tuple[str, bool]]:
    """(text, is a subscript) of each run of the markup `text`."""
    parts = _SEGMENT.split(text)
    return [(p, k % 2 == 1) for k, p in enumerate(parts) if p]


class Font:
    """A TrueType font (matplotlib's FreeType face): each character's glyph id and advance width
    (1/1000 em), looked up once, and the glyphs a document used (its widths and ToUnicode map)."""

    def __init__(self, path: str) -> None:
        from matplotlib.ft2font import FT2Font

        self.path = path
        self._face = FT2Font(path)
        self._scale = 1000 / self._face.units_per_EM
        self.name = re.sub(r"[^A-Za-z0-9-]", "", self._face.postscript_name) or "Font"
        x0, y0, x1, y1 = (round(v * self._scale) for v in self._face.bbox)
        self.bbox = (x0, y0, x1, y1)
        self.ascent = round(self._face.ascender * self._scale)
        self.descent = round(self._face.descender * self._scale)
        self._glyphs: dict[str, tuple[int, int, bytes]] = {}  # character -> (glyph id, width, its hex)
        self.used: dict[int, tuple[int, int]] = {}  # glyph id -> (code point, width)
        self._widths: dict[str, int] = {}  # text -> its advance width, 1/1000 em
        self._tops: dict[str, int] = {}  # character -> its glyph's top, 1/1000 em

    def _glyph(self, c: str) -> tuple[int, int, bytes]:
        found = self._glyphs.get(c)
        if found is None:
            from matplotlib.ft2font import LoadFlags

            gid = self._face.get_char_index(ord(c))  # 0, .notdef, for a character it has not
            glyph = self._face.load_glyph(gid, flags=LoadFlags.NO_SCALE)
            found = self._glyphs[c] = (gid, round(glyph.horiAdvance * self._scale), b"%04X" % gid)
            self._tops[c] = round(glyph.horiBearingY * self._scale)
        return found

    def _top(self, c: str) -> int:
        self._glyph(c)
        return self._tops[c]

    def pieces(self, text: str) -> list[tuple[str, int]]:
        """`text` in runs drawn on one baseline, each with its rise (1/1000 em): a combining mark
        over a letter taller than x (the diaeresis of d\u0308, placed by the font for an x) raised
        by the difference, as a layout engine would place it."""
        if not _MARK.search(text):
            return [(text, 0)]
        runs: list[tuple[str, int]] = []
        for k, part in enumerate(_MARK.split(text)):
            if k % 2 == 0:
                runs += [(part, 0)] if part else []
            else:
                base = runs[-1][0][-1] if runs else "x"
                runs.append((part, max(0, self._top(base) - self._top("x"))))
        return runs

    def width(self, text: str, size: float) -> float:
        """The advance width (pt) of plain `text` at `size` pt."""
        units = self._widths.get(text)
        if units is None:  # a table repeats its units, heads and many numbers
            units = self._widths[text] = sum(self._glyph(c)[1] for c in text)
        return units * size / 1000

    def encode(self, text: str) -> bytes:
        """`text` as a hex string of glyph ids (a PDF string for Tj), its glyphs noted as used."""
        glyphs = [self._glyph(c) for c in text]
        for c in set(text):
            gid, width, _ = self._glyphs[c]
            self.used.setdefault(gid, (ord(c), width))
        return b"<" + b"".join(g[2] for g in glyphs) + b">"


def figure_font(bold: bool = False) -> Font:
    """The figures' font (matplotlib's sans-serif, as rcParams say), regular or bold, as a new
    record of the glyphs used."""
    from matplotlib.font_manager import FontProperties, findfont

    return Font(findfont(FontProperties(weight="bold" if bold else "normal")))


def text_width(font: Font, text: str, size: float) -> float:
    """The width (pt) of a text of the markup at `size` pt, subscripts at theirs."""
    return sum(font.width(t, size * SUB_SCALE if sub else size) for t, sub in segments(text))


def show(font: Font, ref: bytes, text: str, x: float, y: float, size: float) -> bytes:
    """PDF operators drawing a text of the markup with its baseline's left end at (x, y) (pt),
    `ref` the font's resource name (b'/F1')."""
    ops = [b"BT"]
    at = x
    for t, sub in segments(text):
        s = size * SUB_SCALE if sub else size
        for piece, rise in font.pieces(t):
            base = y - (SUB_DROP * size if sub else 0) + rise * s / 1000
            ops.append(b"%s %.2f Tf 1 0 0 1 %.2f %.2f Tm %s Tj" % (ref, s, at, base, font.encode(piece)))
            at += font.width(piece, s)
    ops.append(b"ET")
    return b" ".join(ops)


def subset_name(font: Font) -> bytes:
    """The embedded subset's PostScript name: a tag of six capitals, '+', the font's name (a PDF
    reader tells two subsets of one font apart by it); the tag from the glyphs it holds."""
    digest = hashlib.sha256(b"%s %r" % (font.name.encode("ascii"), sorted(font.used))).digest()
    return bytes(65 + b % 26 for b in digest[:6]) + b"+" + font.name.encode("ascii")


def font_objects(font: Font, first: int) -> list[bytes]:
    """The five objects embedding `font`, subset to the glyphs used, as numbers first .. first + 4:
    Type0 font, CIDFontType2, descriptor, the font file (Flate), ToUnicode map."""
    widths = b" ".join(b"%d [%d]" % (g, w) for g, (_, w) in sorted(font.used.items()))
    name = subset_name(font)
    data = _font_file(font.path, frozenset(font.used))
    cmap = _to_unicode(font.used)
    return [
        b"<< /Type /Font /Subtype /Type0 /BaseFont /%s /Encoding /Identity-H /DescendantFonts [%d 0 R] "
        b"/ToUnicode %d 0 R >>" % (name, first + 1, first + 4),
        b"<< /Type /Font /Subtype /CIDFontType2 /BaseFont /%s /CIDSystemInfo << /Registry (Adobe) "
        b"/Ordering (Identity) /Supplement 0 >> /FontDescriptor %d 0 R /W [%s] /CIDToGIDMap /Identity >>"
        % (name, first + 2, widths),
        b"<< /Type /FontDescriptor /FontName /%s /Flags 32 /FontBBox [%d %d %d %d] /ItalicAngle 0 "
        b"/Ascent %d /Descent %d /CapHeight %d /StemV 80 /FontFile2 %d 0 R >>"
        % (name, *font.bbox, font.ascent, font.descent, font.ascent, first + 3),
        b"<< /Length %d /Length1 %d /Filter /FlateDecode >>\nstream\n" % (len(data[1]), data[0])
        + data[1]
        + b"\nendstream",
        b"<< /Length %d >>\nstream\n" % len(cmap) + cmap + b"\nendstream",
    ]


@functools.lru_cache(maxsize=8)
def _font_file(path: str, gids: frozenset[int]) -> tuple[int, bytes]:
    """(length, deflated bytes) of the TrueType file `path` subset to the glyphs `gids` (and
    .notdef), each at its own id (Identity: a string's codes are the font's glyph ids): the
    outlines and hinting of those glyphs, an empty glyph at every other id, no layout tables."""
    from fontTools import subset
    from fontTools.ttLib import TTFont

    options = subset.Options(retain_gids=True, notdef_outline=True, glyph_names=False, layout_features=[])
    options.drop_tables += ["GSUB", "GPOS", "GDEF", "kern", "MATH", "FFTM", "PfEd", "BDF", "meta"]
    with TTFont(path, lazy=True, recalcTimestamp=False) as face:  # the same glyphs, the same bytes
        subsetter = subset.Subsetter(options)
        subsetter.populate(gids=set(gids))
        subsetter.subset(face)
        out = io.BytesIO()
        face.save(out)
    data = out.getvalue()
    return len(data), zlib.compress(data, 6)


def _to_unicode(used: dict[int, tuple[int, int]]) -> bytes:
    """A ToUnicode CMap of glyph id -> code point (UTF-16BE)."""
    entries = [
        b"<%04X> <%s>" % (g, chr(cp).encode("utf-16-be").hex().upper().encode()) for g, (cp, _) in sorted(used.items())
    ]
    chunks = [entries[k : k + 100] for k in range(0, len(entries), 100)]
    body = b"\n".join(b"%d beginbfchar\n%s\nendbfchar" % (len(c), b"\n".join(c)) for c in chunks)
    return (
        b"/CIDInit /ProcSet findresource begin 12 dict begin begincmap /CIDSystemInfo << /Registry (Adobe) "
        b"/Ordering (UCS) /Supplement 0 >> def /CMapName /Adobe-Identity-UCS def /CMapType 2 def "
        b"1 begincodespacerange <0000> <FFFF> endcodespacerange\n"
        + body
        + b"\nendcmap CMapName currentdict /CMap defineresource pop end end"
    )
