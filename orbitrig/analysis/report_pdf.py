"""``report.pdf``: every figure of a report in one file, point by point, for sharing.

When every figure was written as a vector PDF too (``--formats png,pdf``) those PDFs are joined
(pypdf, one bookmark per figure). Otherwise the PDF is built from the 300 dpi PNGs without
drawing anything again: each page is one image XObject whose data is the PNG's own compressed
pixel stream (IDAT, Flate with PNG predictors, which PDF decodes natively), sized so the page
is the figure's size in inches. A PNG that is not 8-bit RGB is converted (PIL) first.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path
from typing import BinaryIO

from orbitrig.store.durable import atomic_file, remove
from orbitrig.store.errors import storage_error

COMBINED_PDF = "report.pdf"
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def combine_pdf(pngs: list[Path], path: Path) -> Path | None:
    """One PDF of the figures `pngs`, in order, at `path` (vector when each has its .pdf beside
    it, else the PNGs' pixels); None, and no file, when there is no figure."""
    pngs = [Path(p) for p in pngs]
    remove(path)
    if not pngs:
        return None
    vectors = [p.with_suffix(".pdf") for p in pngs]
    with atomic_file(path) as f:  # streamed: a large report is not held in memory
        if all(v.exists() for v in vectors):
            _join_vector(vectors, f)
        else:
            raster_pdf(pngs, f)
    return path


def _join_vector(pdfs: list[Path], out: BinaryIO) -> None:
    from pypdf import PdfWriter

    writer = PdfWriter()
    for pdf in pdfs:
        writer.append(str(pdf), outline_item=pdf.stem)
    writer.write(out)


def png_image(path: Path) -> tuple[int, int, float, bytes]:
    """(width px, height px, dpi, Flate data of 8-bit RGB rows with PNG filters) of a PNG file;
    dpi 72 when the file states none."""
    data = path.read_bytes()
    if not data.startswith(_PNG_SIGNATURE):
        raise storage_error(path, "read", OSError("not a PNG file"))
    width = height = 0
    dpi, rgb, idat, at = 72.0, False, [], len(_PNG_SIGNATURE)
    while at + 8 <= len(data):
        length, kind = struct.unpack(">I4s", data[at : at + 8])
        body = data[at + 8 : at + 8 + length]
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            rgb = depth == 8 and colour == 2 and interlace == 0
        elif kind == b"pHYs" and body[8] == 1:  # pixels per metre
            dpi = struct.unpack(">I", body[:4])[0] * 0.0254
        elif kind == b"IDAT":
            idat.append(body)
        at += 12 + length
    if rgb:
        return width, height, dpi, b"".join(idat)
    return _converted(path, dpi)


def _converted(path: Path, dpi: float) -> tuple[int, int, float, bytes]:
    """A PNG of another colour type as RGB rows, each with filter byte 0 (none), deflated."""
    from PIL import Image

    with Image.open(path) as src:
        img = src.convert("RGB")
        w, h, raw = img.width, img.height, img.tobytes()
    rows = b"".join(b"\x00" + raw[r * 3 * w : (r + 1) * 3 * w] for r in range(h))
    return w, h, dpi, zlib.compress(rows, 6)


def raster_pdf(pngs: list[Path], out: BinaryIO) -> None:
    """A PDF of one page per PNG, each page the image at its stated resolution, written to `out`
    (objects: 1 catalog, 2 page tree, then page, contents and image of each figure)."""
    offsets: list[int] = []
    start = out.tell()

    def obj(body: bytes) -> None:
        offsets.append(out.tell() - start)
        out.write(b"%d 0 obj\n" % len(offsets) + body + b"\nendobj\n")

    out.write(b"%PDF-1.4\n%\xe2\xe3\xcf\xd3\n")
    n = len(pngs)
    kids = b" ".join(b"%d 0 R" % (3 + 3 * k) for k in range(n))
    obj(b"<< /Type /Catalog /Pages 2 0 R >>")
    obj(b"<< /Type /Pages /Kids [%s] /Count %d >>" % (kids, n))
    for k, png in enumerate(pngs):
        w, h, dpi, pixels = png_image(png)
        pw, ph = w * 72.0 / dpi, h * 72.0 / dpi
        content, image = 4 + 3 * k, 5 + 3 * k  # the page itself is object 3 + 3 k
        obj(
            b"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 %.3f %.3f] /Contents %d 0 R "
            b"/Resources << /XObject << /Im0 %d 0 R >> >> >>" % (pw, ph, content, image)
        )
        draw = b"q %.3f 0 0 %.3f 0 0 cm /Im0 Do Q" % (pw, ph)
        obj(b"<< /Length %d >>\nstream\n%s\nendstream" % (len(draw), draw))
        obj(
            b"<< /Type /XObject /Subtype /Image /Width %d /Height %d /ColorSpace /DeviceRGB "
            b"/BitsPerComponent 8 /Filter /FlateDecode /DecodeParms << /Predictor 15 /Colors 3 "
            b"/BitsPerComponent 8 /Columns %d >> /Length %d >>\nstream\n"
            % (w, h, w, len(pixels))
            + pixels
            + b"\nendstream"
        )
    xref = out.tell() - start
    out.write(b"xref\n0 %d\n0000000000 65535 f \n" % (len(offsets) + 1))
    out.write(b"".join(b"%010d 00000 n \n" % o for o in offsets))
    out.write(b"trailer\n<< /Size %d /Root 1 0 R >>\nstartxref\n%d\n%%%%EOF\n" % (len(offsets) + 1, xref))
