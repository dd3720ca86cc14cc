"""``report.pdf``: every figure of a report in one file, point by point, for sharing.

When every figure was written as a vector PDF too (``--formats png,pdf``) those PDFs are joined
(pypdf, one bookmark per figure). Otherwise the PDF is built from the 300 dpi PNGs without
drawing anything again: each page is one image XObject whose data is the PNG's own compressed
pixel stream (IDAT, Flate with PNG predictors, which PDF decodes natively), sized so the page
is the figure's size in inches. A PNG that is not 8-bit RGB is converted (PIL) first.

The file is shared on its own, away from the run: its document information names where its
numbers come from (`run_info`: the run, the software version, the calibration record and its
SHA-256, or that the run had none, the simulator scenario's SHA-256), as every export does.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path
from typing import BinaryIO

from orbitrig.config import rig_from_text
from orbitrig.config import PROBE_CHANNELS as PROBES
from orbitrig.errors import ConfigError
from orbitrig.store.durable import atomic_file, remove
from orbitrig.store.errors import storage_error

COMBINED_PDF = "report.pdf"
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def calibration_text(provenance: dict) -> str:
    """The run's calibration record as a reader is told it: 'NAME (SHA-256 HEX)'; 'none' for a
    run made without one (no corrections; U's calibration part from rig.toml's
    [calibration_uncertainty], if stated); 'not recorded' for a run stored before provenance (the
    reader gives every key, "" when not stored: a run's provenance always names its operator)."""
    if not provenance.get("operator") and not provenance.get("started"):
        return "not recorded"
    name, sha = provenance.get("calibration_record", ""), provenance.get("calibration_record_sha256", "")
    if not name:
        return "none (no calibration corrections; U's calibration part from rig.toml's [calibration_uncertainty])"
    return f"{name} (SHA-256 {sha})" if sha else name


def corrections_text(run) -> str:
    """What the sweep took out of the readings (orbitrig.run.corrections), as the run's stored rig
    configuration and calibration record say it: the force channels' lags, the load measuring
    systems' gain matrices, the probes' runout (subtracted or why not), gains and lags; '' for a
    run that stored no rig configuration."""
    if not run.rig_config:
        return ""
    record_text = run.calibration_record_text or None
    try:
        rig = rig_from_text(run.rig_config, "rig configuration stored in the run", record_text, check_record=False)
    except ConfigError:
        return "not readable from the run's stored rig configuration"
    rec = rig.record
    if rig.calibration_record is None or rec is None:
        return "none (no calibration record)"
    forces = [n for n in rec.delay if n not in PROBES]
    probes = [n for n in rec.delay if n in PROBES]
    if rec.runout is None:
        runout = "not subtracted: the record holds none"
    elif not rig.subtract_runout:
        runout = "not subtracted: subtract_runout = false"
    else:
        runout = f"subtracted (slow roll at {rec.runout.spin_rpm:g} rpm, {rec.runout.revolutions} revolutions)"
    parts = [
        "force lags: " + (", ".join(forces) or "none recorded"),
        "force gain matrices: " + (", ".join(str(lms) for lms in rec.loads) or "none recorded (identity)"),
        f"probe runout: {runout}",
        "probe gains: " + (", ".join(rec.probes) or "none recorded"),
    ]
    if probes:
        parts.append("probe lags: " + ("taken out" if rec.probe_lags_corrected else "left in, counted in their u"))
    return "; ".join(parts)


def software_text(run) -> str:
    """The run's software as a reader is told it: the one it started with and, when its points were
    measured by more than one (a resume with other software), each with the points it measured."""
    versions = run.software_versions
    if len(versions) < 2:
        return run.software_version
    each = [f"{v} (points {', '.join(p.name for p in run.points if p.software == v)})" for v in versions]
    return f"{run.software_version}; its points measured by {len(versions)} versions: " + "; ".join(each)


def run_info(run) -> dict[str, str]:
    """The document information of a run's report.pdf (PDF Info keys): title, the run, the
    software version, the calibration record and the simulator scenario's SHA-256."""
    prov = run.provenance
    info = {
        "/Title": f"orbitrig run {run.directory.name}",
        "/Creator": "orbitrig report",
        "/Producer": run.software_version,
        "/OrbitrigRunId": run.run_id,
        "/OrbitrigSoftwareVersion": run.software_version,
        "/OrbitrigCalibrationRecord": calibration_text(prov),
        "/OrbitrigCalibrationRecordSHA256": prov.get("calibration_record_sha256", ""),
    }
    if run.sim:
        info["/OrbitrigSimScenarioSHA256"] = run.sim_scenario_sha256
    info["/Subject"] = "; ".join(
        [f"run {run.run_id}", f"matrix {run.matrix_name}", f"calibration record {info['/OrbitrigCalibrationRecord']}"]
        + ([f"simulator scenario SHA-256 {run.sim_scenario_sha256}"] if run.sim else [])
        + [f"software {software_text(run)}"]
    )
    return info


def combine_pdf(pngs: list[Path], path: Path, info: dict[str, str] | None = None) -> Path | None:
    """One PDF of the figures `pngs`, in order, at `path` (vector when each has its .pdf beside
    it, else the PNGs' pixels), its document information `info` (PDF Info keys, '/Title': text);
    None, and no file, when there is no figure."""
    pngs = [Path(p) for p in pngs]
    remove(path)
    if not pngs:
        return None
    vectors = [p.with_suffix(".pdf") for p in pngs]
    with atomic_file(path) as f:  # streamed: a large report is not held in memory
        if all(v.exists() for v in vectors):
            _join_vector(vectors, f, info or {})
        else:
            raster_pdf(pngs, f, info or {})
    return path


def _join_vector(pdfs: list[Path], out: BinaryIO, info: dict[str, str]) -> None:
    from pypdf import PdfWriter

    writer = PdfWriter()
    for pdf in pdfs:
        writer.append(str(pdf), outline_item=pdf.stem)
    if info:
        writer.add_metadata(info)
    writer.write(out)


def _pdf_text(text: str) -> bytes:
    """``text`` as a PDF text string: UTF-16BE with its byte order mark, in hex (any character)."""
    return b"<FEFF" + text.encode("utf-16-be").hex().upper().encode("ascii") + b">"


def _info_object(info: dict[str, str]) -> bytes:
    """The document information dictionary of ``info`` ('/Key': text)."""
    entries = b" ".join(k.encode("ascii") + b" " + _pdf_text(v) for k, v in info.items())
    return b"<< " + entries + b" >>"


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


def raster_pdf(pngs: list[Path], out: BinaryIO, info: dict[str, str] | None = None) -> None:
    """A PDF of one page per PNG, each page the image at its stated resolution, written to `out`
    (objects: 1 catalog, 2 page tree, then page, contents and image of each figure, then the
    document information `info` when given)."""
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
    if info:
        obj(_info_object(info))
    xref = out.tell() - start
    out.write(b"xref\n0 %d\n0000000000 65535 f \n" % (len(offsets) + 1))
    out.write(b"".join(b"%010d 00000 n \n" % o for o in offsets))
    refer = b" /Info %d 0 R" % len(offsets) if info else b""
    out.write(b"trailer\n<< /Size %d /Root 1 0 R%s >>\nstartxref\n%d\n%%%%EOF\n" % (len(offsets) + 1, refer, xref))
