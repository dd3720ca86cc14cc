"""The Agg canvas every report figure is drawn on, and the PNG it is written as.

Drawing a report figure is mostly text: tick labels, titles and legends are laid out and
rasterised glyph by glyph on every draw (about half of a figure's drawing time), although the
same strings ("0.2", "[MN/m]", a legend entry) come back in every panel, figure and point.
:class:`ReportCanvas` draws through :class:`CachedTextRenderer`, which rasterises each distinct
string once per process (font, size, angle, resolution) and then copies its bitmap: the string
is placed on a whole device pixel (as matplotlib placed text before 3.11; at 300 dpi a pixel is
0.085 mm), the glyphs inside it keep their sub-pixel positions. Mathtext (the subscripts) is laid
out once per process by one shared parser that keeps LAYOUT_CACHE_SIZE layouts (matplotlib's keeps
50, fewer than one point's figures use) and its own grammar keeping the parse of each math segment
(a string that changes per point repeats its subscripts), drawn by matplotlib once per process (string, font,
angle, resolution) with its origin on a whole pixel, and its pixels copied after (as for plain
text: what matplotlib draws at that pixel, a test compares them); TeX is drawn as matplotlib draws
it. A plain string's extent (for the layout) is likewise measured once per process, not per figure.

:func:`png_bytes` writes the canvas as an 8-bit RGB PNG without a filter, deflated by Intel's
ISA-L (``isal``) at level 1: the zlib stream every PNG reader decodes, in an eighth of zlib's
time at its fastest level (5 ms instead of 40 ms for a double-column figure), files about 7 %
smaller than zlib level 1 and 25 % larger than zlib's default level.
"""

from __future__ import annotations

import math
import os
import struct
import threading
import zlib
from collections import OrderedDict

import numpy as np
from matplotlib import _mathtext, rcParams
from matplotlib.backends.backend_agg import FigureCanvasAgg, RendererAgg, get_hinting_flag
from matplotlib.font_manager import fontManager, get_font
from matplotlib.ft2font import RenderMode
from matplotlib.mathtext import MathTextParser

#: strings kept rasterised per process (a few kB each at 300 dpi)
TEXT_CACHE_SIZE = 8192
#: mathtext strings kept drawn per process (a title's line is 10 to 300 kB at 300 dpi)
MATH_CACHE_SIZE = 1024
#: mathtext strings kept laid out, plain strings kept measured, per process (matplotlib keeps 50
#: layouts: fewer than the distinct mathtext labels of one point's figures at two resolutions)
LAYOUT_CACHE_SIZE = 4096
#: ISA-L level of the PNGs' deflate stream (0 to 3; 1: 0.1 s less per figure than zlib level 1)
PNG_COMPRESSION = 1

#: matplotlib's mathtext parser of each (process, thread), shared by its renderers: each renderer's
#: own would lay out every mathtext string again; its layouts hold FreeType faces, which matplotlib
#: keeps per process and thread (a forked worker must not use its parent's)
_MATHTEXT: dict[tuple[int, int], MathTextParser] = {}
_TEXT: OrderedDict[tuple, tuple[np.ndarray, int, int] | None] = OrderedDict()
_MATH: OrderedDict[tuple, tuple[np.ndarray, int, int] | str | None] = OrderedDict()
#: a mathtext string whose ink reached the edge of the canvas it was drawn on: drawn by matplotlib every time
_UNCACHED = "uncached"
_HEIGHTS: dict[tuple, tuple[float, float, float] | tuple[None, None, None]] = {}
_EXTENTS: OrderedDict[tuple, tuple[float, float, float]] = OrderedDict()


def _remember(cache: OrderedDict, key, value, size: int):
    """`value` kept in `cache` under `key`, the oldest entry dropped beyond `size` entries."""
    cache[key] = value
    if len(cache) > size:
        cache.popitem(last=False)
    return value


class _Segments(_mathtext.Parser):
    """matplotlib's mathtext grammar keeping the parse of each math segment (between $ signs) of a
    string: strings that change per point (a legend entry's numbers, a title's operating point)
    repeat their segments ("$_\\mathrm{eff,xx}$"), whose parse is most of the string's. A segment is
    reused where everything it was parsed under is the same: the font set and its fonts, the
    parser's state on entry (font, size, resolution, spacing after a sub/superscript) and the
    mathtext rcParams; its boxes are only read after (packed into each string's own boxes)."""

    def __init__(self) -> None:
        super().__init__()
        self._parsed: OrderedDict[tuple, tuple] = OrderedDict()

    def math_string(self, toks):
        state, rc = self.get_state(), tuple(v for k, v in rcParams.items() if k.startswith("mathtext."))
        fonts = state.fontset
        key = (toks[0], type(fonts), fonts.default_font_prop, fonts.load_glyph_flags, state.font, state.font_class)
        key += (state.fontsize, state.dpi, self._needs_space_after_subsuper, rc)
        if key in self._parsed:
            self._parsed.move_to_end(key)
            found, self._needs_space_after_subsuper, popped = self._parsed[key]
            del self._state_stack[len(self._state_stack) - popped :]  # as the segment's parse pops them
            return found.copy()
        depth = len(self._state_stack)
        found = super().math_string(toks)
        popped = depth - len(self._state_stack)  # the state the text before it pushed: popped at its end
        _remember(self._parsed, key, (found.copy(), self._needs_space_after_subsuper, popped), LAYOUT_CACHE_SIZE)
        return found


class _LaidOut(MathTextParser):
    """matplotlib's mathtext parser ("path") keeping LAYOUT_CACHE_SIZE layouts instead of 50: a point's
    figures measure their mathtext labels (the legend's room) and draw them, and a report repeats
    them figure after figure; with 50 most were laid out again every time. Its grammar is its own
    (:class:`_Segments`), not matplotlib's shared one."""

    def __init__(self) -> None:
        super().__init__("path")
        self._layouts: OrderedDict[tuple, object] = OrderedDict()
        self._parser = _Segments()

    def parse(self, s, dpi=72, prop=None, *, antialiased=None):
        antialiased = rcParams["text.antialiased"] if antialiased is None else antialiased
        # what matplotlib's own cache is keyed by (its hinting flags follow from the output type)
        key = (s, dpi, None if prop is None else prop.copy(), antialiased, rcParams["text.hinting"])
        if key in self._layouts:
            self._layouts.move_to_end(key)
            return self._layouts[key]
        return _remember(self._layouts, key, super().parse(s, dpi, prop, antialiased=antialiased), LAYOUT_CACHE_SIZE)


def _font_key(prop) -> tuple:
    return (
        tuple(prop.get_family()),
        prop.get_style(),
        prop.get_variant(),
        prop.get_weight(),
        prop.get_stretch(),
        prop.get_size_in_points(),
        prop.get_file(),
    )


def _rasterise(renderer: RendererAgg, s: str, prop, angle: float, antialiased: bool, mtext):
    """(grey bitmap, left, top) of string `s` with its origin at (0, 0) in FreeType's
    coordinates (y up), or None for a string without ink."""
    font = renderer._prepare_font(prop)
    items = font._layout(
        s,
        flags=get_hinting_flag(),
        features=mtext.get_fontfeatures() if mtext is not None else None,
        language=mtext.get_language() if mtext is not None else None,
    )
    size = prop.get_size_in_points()
    cos, sin = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    matrix = (0x10000 * np.array([[cos, -sin], [sin, cos]])).round().astype(int)
    mode = RenderMode.NORMAL if antialiased else RenderMode.MONO
    glyphs = []
    for item in items:
        face = item.ft_object
        face.set_size(size, renderer.dpi)
        x, y = item.x, item.y
        face._set_transform(matrix, [round(0x40 * (x * cos - y * sin)), round(0x40 * (x * sin + y * cos))])
        bitmap = face._render_glyph(item.glyph_index, get_hinting_flag(), mode)
        pixels = np.array(bitmap.buffer, dtype=np.uint8)
        if pixels.size:
            glyphs.append((bitmap.left, bitmap.top, pixels if antialiased else pixels * 0xFF))
    if not glyphs:
        return None
    left = min(g[0] for g in glyphs)
    top = max(g[1] for g in glyphs)
    right = max(g[0] + g[2].shape[1] for g in glyphs)
    bottom = min(g[1] - g[2].shape[0] for g in glyphs)
    image = np.zeros((top - bottom, right - left), np.uint8)
    for gl, gt, pixels in glyphs:
        view = image[top - gt : top - gt + pixels.shape[0], gl - left : gl - left + pixels.shape[1]]
        np.maximum(view, pixels, out=view)
    return image, left, top


class CachedTextRenderer(RendererAgg):
    """Agg renderer drawing plain text from a per-process cache of rasterised strings, and
    mathtext through one parser per process (its cache of laid-out strings outlives a figure)."""

    def __init__(self, width, height, dpi):
        super().__init__(width, height, dpi)
        here = os.getpid(), threading.get_ident()
        if here not in _MATHTEXT:
            _MATHTEXT[here] = _LaidOut()
        self.mathtext_parser = _MATHTEXT[here]

    def draw_text(self, gc, x, y, s, prop, angle, ismath=False, mtext=None):
        if ismath:
            return self._draw_math(gc, x, y, s, prop, angle, ismath, mtext)
        antialiased = bool(gc.get_antialiased())
        features = mtext.get_fontfeatures() if mtext is not None else None
        language = mtext.get_language() if mtext is not None else None
        key = (s, _font_key(prop), angle, self.dpi, antialiased, features, language)
        if key in _TEXT:
            found = _TEXT[key]
        else:
            found = _remember(_TEXT, key, _rasterise(self, s, prop, angle, antialiased, mtext), TEXT_CACHE_SIZE)
        if found is None:
            return
        image, left, top = found
        ox, oy = round(x), round(self.height - y)  # the string's origin, whole pixels, y up
        self._renderer.draw_text_image(image, left + ox, int(self.height) - (top + oy) + image.shape[0], 0, gc)

    def _draw_math(self, gc, x, y, s, prop, angle, ismath, mtext) -> None:
        """Mathtext `s` from the per-process cache of drawn strings (:func:`_math_bitmap`), its origin
        on a whole pixel; translucent or clipped text (none in the report: Agg clips an image's
        pixels otherwise than a text's) as matplotlib draws it."""
        red, green, blue, alpha = gc.get_rgb()
        clipped = gc.get_clip_rectangle() is not None or gc.get_clip_path()[0] is not None
        if ismath is not True or alpha != 1.0 or clipped:
            super().draw_text(gc, x, y, s, prop, angle, ismath, mtext)
            return
        antialiased = bool(gc.get_antialiased())
        key = (s, _font_key(prop), prop.get_math_fontfamily(), angle, self.dpi, antialiased, get_hinting_flag())
        if key in _MATH:
            found = _MATH[key]
        else:
            found = _remember(_MATH, key, _math_bitmap(self, s, prop, angle, antialiased), MATH_CACHE_SIZE)
        if found is None:
            return
        if isinstance(found, str):
            super().draw_text(gc, x, y, s, prop, angle, ismath, mtext)
            return
        cover, left, bottom = found
        image = np.empty((*cover.shape, 4), np.uint8)
        image[:, :, :3] = np.floor(np.array([red, green, blue]) * 255 + 0.5)  # Agg's 8-bit colour: rounded half up
        image[:, :, 3] = cover[::-1]  # draw_image's rows: the lowest first
        self.draw_image(gc, round(x) + left, round(self.height - y) + bottom, image)  # y: down from the top

    def get_text_width_height_descent(self, s, prop, ismath):
        """matplotlib's (width, height, descent) px of `s`, a plain string's measured once per
        process (font, size, resolution): matplotlib keeps them per renderer, one per figure."""
        if ismath:
            return super().get_text_width_height_descent(s, prop, ismath)
        key = (s, _font_key(prop), self.dpi, get_hinting_flag())
        if key in _EXTENTS:
            return _EXTENTS[key]
        return _remember(_EXTENTS, key, super().get_text_width_height_descent(s, prop, ismath), LAYOUT_CACHE_SIZE)

    def _get_font_height_metrics(self, prop):
        """(ascent, descent, line gap) px of the font of `prop` (matplotlib's Text layout asks
        for them on every layout and reads the font's tables each time), None when unknown."""
        key = (_font_key(prop), self.dpi)
        if key not in _HEIGHTS:
            _HEIGHTS[key] = _font_heights(prop, self.dpi)
        return _HEIGHTS[key]


def _math_bitmap(renderer: RendererAgg, s: str, prop, angle: float, antialiased: bool):
    """(coverage, left, bottom) of mathtext `s` as matplotlib's Agg renderer draws it in black with its
    origin on a whole pixel: the coverage rows top first, (left, bottom) px of its lowest left pixel
    from the origin (y up); None for a string without ink, _UNCACHED when its ink reaches the edge
    of the canvas it was drawn on (a glyph reaching out more than a font size)."""
    laid = renderer.mathtext_parser.parse(s, renderer.dpi, prop, antialiased=antialiased)
    pad = math.ceil(prop.get_size_in_points() * renderer.dpi / 72.0) + 2  # px round the laid-out box
    cos, sin = math.cos(math.radians(angle)), math.sin(math.radians(angle))
    box = [(-pad, -laid.depth - pad), (laid.width + pad, -laid.depth - pad)]
    box += [(laid.width + pad, laid.height + pad), (-pad, laid.height + pad)]
    xs, ys = [bx * cos - by * sin for bx, by in box], [bx * sin + by * cos for bx, by in box]
    x0, y0 = math.ceil(-min(xs)), math.ceil(-min(ys))  # the origin, whole pixels from the lower left
    canvas = RendererAgg(x0 + math.ceil(max(xs)) + 1, y0 + math.ceil(max(ys)) + 1, renderer.dpi)
    canvas.mathtext_parser = renderer.mathtext_parser  # the layout just found
    gc = canvas.new_gc()
    gc.set_antialiased(antialiased)
    canvas.draw_text(gc, x0, canvas.height - y0, s, prop, angle, ismath=True)  # Agg's text y: down from the top
    gc.restore()
    cover = np.asarray(canvas.buffer_rgba())[:, :, 3]
    rows, cols = np.flatnonzero(cover.any(axis=1)), np.flatnonzero(cover.any(axis=0))
    if rows.size == 0:
        return None
    height, width = cover.shape
    if rows[0] == 0 or cols[0] == 0 or rows[-1] == height - 1 or cols[-1] == width - 1:
        return _UNCACHED
    ink = cover[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1].copy()
    return ink, int(cols[0]) - x0, height - 1 - int(rows[-1]) - y0


def _font_heights(prop, dpi: float):
    font = get_font(fontManager._find_fonts_by_props(prop))
    if (os2 := font.get_sfnt_table("OS/2")) is not None:
        gap, ascent, descent = os2["sTypoLineGap"], os2["sTypoAscender"], os2["sTypoDescender"]
    elif (hhea := font.get_sfnt_table("hhea")) is not None:
        gap, ascent, descent = hhea["lineGap"], hhea["ascent"], hhea["descent"]
    else:
        return None, None, None
    head = font.get_sfnt_table("head")
    if head is None:  # no units per em (a TrueType font always has one): matplotlib's own layout
        return None, None, None
    scale = prop.get_size_in_points() * dpi / 72 / head["unitsPerEm"]
    return ascent * scale, -descent * scale, gap * scale


class ReportCanvas(FigureCanvasAgg):
    """FigureCanvasAgg drawing with :class:`CachedTextRenderer`."""

    def get_renderer(self):
        w, h = self.get_width_height(physical=True)
        key = w, h, self.figure.dpi
        if self._lastKey != key:
            self.renderer = CachedTextRenderer(w, h, self.figure.dpi)
            self._lastKey = key
        return self.renderer


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def png_bytes(fig, dpi: float, text: dict[str, str] | None = None) -> bytes:
    """`fig` (on a :class:`ReportCanvas` or any Agg canvas) drawn at `dpi` and encoded as an
    8-bit RGB PNG stating its resolution (the figure is opaque: no alpha channel, so report.pdf
    can carry the PNG's compressed pixels unchanged); `text`: keyword -> text, each an iTXt
    chunk (UTF-8) before the pixels."""
    from isal import isal_zlib

    screen = fig.dpi
    try:
        fig.set_dpi(dpi)
        fig.canvas.draw()
        width, height = fig.canvas.get_width_height(physical=True)
        rows = np.empty((height, 1 + 3 * width), np.uint8)
        rows[:, 0] = 0  # filter type None on every row
        # red, green and blue copied from the canvas one channel at a time (alpha dropped): a fifth of
        # the time of copying the pixels' three bytes together
        rgba, rgb = np.asarray(fig.canvas.buffer_rgba()), rows[:, 1:].reshape(height, width, 3)
        for channel in range(3):
            rgb[:, :, channel] = rgba[:, :, channel]
    finally:
        fig.set_dpi(screen)
    per_metre = round(dpi / 0.0254)
    return b"".join(
        (
            b"\x89PNG\r\n\x1a\n",
            _chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)),
            _chunk(b"pHYs", struct.pack(">IIB", per_metre, per_metre, 1)),
            *(_chunk(b"iTXt", k.encode("latin-1") + b"\0\0\0\0\0" + v.encode()) for k, v in (text or {}).items()),
            _chunk(b"IDAT", isal_zlib.compress(rows, PNG_COMPRESSION)),
            _chunk(b"IEND", b""),
        )
    )
