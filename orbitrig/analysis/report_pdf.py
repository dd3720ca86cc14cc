"""``report.pdf``: a report's tables (orbitrig.analysis.report_pages: text pages, first) and
every figure, point by point, in one file for sharing; the tables alone when no figure was drawn
(one point and `--figures` of kinds it has none of: ``--figures impedance`` of a rig's run, which
has no simulator truth, or ``--figures ""``).

When every figure was written as a vector PDF too (``--formats png,pdf``) those PDFs are joined
(pypdf, one bookmark per figure). Otherwise the PDF is built from the 300 dpi PNGs without
drawing anything again: each page is one image XObject whose data is the PNG's own compressed
pixel stream (IDAT, Flate with PNG predictors, which PDF decodes natively), sized so the page
is the figure's size in inches. A PNG that is not 8-bit RGB is converted (PIL) first.

The file is shared on its own, away from the run: its document information names where its
numbers come from (`run_info`: the run, the software version, the calibration record and its
SHA-256, or that the run had none, the simulator scenario's SHA-256), as every export does,
and its first page states the run's header (`provenance_rows`, the rows index.html's header
shows too).
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path, PureWindowsPath
from typing import BinaryIO

from orbitrig.config import rig_from_text
from orbitrig.config import PROBE_CHANNELS as PROBES
from orbitrig.errors import ConfigError
from orbitrig.store.durable import atomic_file, remove
from orbitrig.store.errors import storage_error
from orbitrig.store.stored_run import scenario_label

COMBINED_PDF = "report.pdf"
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def calibration_text(provenance: dict) -> str:
    """The run's calibration record as a reader is told it: 'NAME (SHA-256 HEX)'; 'none' for a
    run made without one (no corrections; U's calibration part from rig.toml's
    [calibration_uncertainty], if stated); 'not recorded' for a run stored before provenance (the
    reader gives every key, "" when not stored: a run's provenance always names its operator); a record
    past rig.toml's calibration_valid_days at the run's start adds its ``calibration_validity``
    ('NAME (SHA-256 HEX); expired: past calibration_valid_days = 365 ...; loads 400 days old ...')."""
    if not provenance.get("operator") and not provenance.get("started"):
        return "not recorded"
    name, sha = provenance.get("calibration_record", ""), provenance.get("calibration_record_sha256", "")
    if not name:
        return "none (no calibration corrections; U's calibration part from rig.toml's [calibration_uncertainty])"
    named = f"{name} (SHA-256 {sha})" if sha else name
    validity = provenance.get("calibration_validity", "")
    return f"{named}; {validity}" if validity.startswith("expired") else named


#: the corrections a sweep takes out of the readings, as a report's header names each (README, report)
CORRECTIONS = ("force lags", "force gain matrices", "probe runout", "probe gains", "probe lags")


def corrections_text(run) -> str:
    """What the sweep took out of the readings (orbitrig.run.corrections), as the run's stored rig
    configuration and calibration record say it: each of CORRECTIONS, 'applied (record NAME: what)'
    or 'not applied (why)'; '' for a run that stored no rig configuration."""
    if not run.rig_config:
        return ""
    record_text = run.calibration_record_text or None
    try:
        rig = rig_from_text(run.rig_config, "rig configuration stored in the run", record_text, check_record=False)
    except ConfigError:
        return "not readable from the run's stored rig configuration"
    rec = rig.record
    if rig.calibration_record is None or rec is None:
        return "; ".join(f"{name}: not applied (no calibration record)" for name in CORRECTIONS)
    named = f"record {rig.calibration_record}"

    def state(what: str, why_not: str) -> str:
        return f"applied ({named}: {what})" if what else f"not applied ({why_not})"

    none = "none in the record"
    probes = [n for n in rec.delay if n in PROBES]
    if rec.runout is not None and not rig.subtract_runout:
        runout = "not applied (subtract_runout = false)"
    else:
        slow = rec.runout and f"slow roll at {rec.runout.spin_rpm:g} rpm, {rec.runout.revolutions} revolutions"
        runout = state(slow or "", none)
    lags_left = "the record's predate their correction: left in, counted in their u"
    states = (
        state(", ".join(n for n in rec.delay if n not in PROBES), none),
        state(", ".join(str(lms) for lms in rec.loads), none + ": identity"),
        runout,
        state(", ".join(rec.probes), none),
        state(", ".join(probes) if rec.probe_lags_corrected else "", lags_left if probes else none),
    )
    return "; ".join(f"{name}: {told}" for name, told in zip(CORRECTIONS, states))


def software_text(run) -> str:
    """The run's software as a reader is told it: the one it started with and, when its points were
    measured by more than one (a resume with other software), each with the points it measured."""
    versions = run.software_versions
    if len(versions) < 2:
        return run.software_version
    each = [f"{v} (points {', '.join(p.name for p in run.points if p.software == v)})" for v in versions]
    return f"{run.software_version}; its points measured by {len(versions)} versions: " + "; ".join(each)


def scenario_name(run) -> str:
    """The simulator scenario as a reader elsewhere can find it: its name and file name,
    'paper (sim.toml)', never the path on the machine that made the run."""
    name = run.sim_scenario_name
    file = PureWindowsPath(name).name if name.endswith(".toml") else ""
    return scenario_label(name) + (f" ({file})" if file else "")


def provenance_rows(run) -> list[tuple[str, str]]:
    """The run's header, (name, text) in the order a reader is told it, on the page and on
    report.pdf's first page: which bearing and set-up, who, which calibration and corrections, the
    software; a row whose text is '' is not shown."""
    prov = run.provenance
    scenario = f"{scenario_name(run)}, SHA-256 {run.sim_scenario_sha256}" if run.sim_scenario_config else ""
    return [
        ("matrix", run.matrix_name),
        ("mode", "simulator (--sim)" if run.sim else "rig"),
        ("simulator scenario", (scenario or scenario_name(run)) if run.sim else ""),
        ("rig", prov.get("rig_id", "")),
        ("operator", prov.get("operator", "")),
        ("calibration record", calibration_text(prov)),
        ("corrections applied", corrections_text(run)),
        ("created", run.created),
        ("software version", software_text(run)),
    ]


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


def combine_pdf(pngs: list[Path], path: Path, info: dict[str, str] | None = None, tables=None) -> Path | None:
    """One PDF at `path`: the table pages `tables` (report_pages.TablePages), then the figures
    `pngs` in order (vector when each has its .pdf beside it, else the PNGs' pixels), its document
    information `info` (PDF Info keys, '/Title': text); the tables alone when no figure was drawn
    (`--figures` of kinds the points have none of); None, and no file, when there is neither."""
    pngs = [Path(p) for p in pngs]
    remove(path)
    if not pngs and (tables is None or not tables.count):
        return None
    vectors = [p.with_suffix(".pdf") for p in pngs]
    with atomic_file(path) as f:  # streamed: a large report is not held in memory
        if pngs and all(v.exists() for v in vectors):
            _join_vector(vectors, f, info or {}, tables)
        else:
            raster_pdf(pngs, f, info or {}, tables)
    return path


def _join_vector(pdfs: list[Path], out: BinaryIO, info: dict[str, str], tables=None) -> None:
    import io

    from pypdf import PdfWriter

    writer = PdfWriter()
    if tables is not None and tables.count:
        lead = io.BytesIO()
        raster_pdf([], lead, None, tables)
        writer.append(lead, outline_item="tables")
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


class _Objects:
    """A PDF's numbered objects written to `out` as they come (any order), then its cross-reference
    table and trailer."""

    def __init__(self, out: BinaryIO) -> None:
        self.out, self.start = out, out.tell()
        self.offsets: dict[int, int] = {}  # object number -> its offset in the file
        out.write(b"%PDF-1.4\n%\xe2\xe3\xcf\xd3\n")

    def put(self, number: int, body: bytes) -> None:
        self.offsets[number] = self.out.tell() - self.start
        self.out.write(b"%d 0 obj\n" % number + body + b"\nendobj\n")

    def stream(self, number: int, data: bytes, filters: bytes = b"") -> None:
        self.put(number, b"<< /Length %d%s >>\nstream\n%s\nendstream" % (len(data), filters, data))

    def finish(self, info: int | None) -> None:
        """The cross-reference table (objects 1 .. n, every one written) and the trailer (root 1)."""
        n, out = len(self.offsets), self.out
        xref = out.tell() - self.start
        out.write(b"xref\n0 %d\n0000000000 65535 f \n" % (n + 1))
        out.write(b"".join(b"%010d 00000 n \n" % self.offsets[k] for k in range(1, n + 1)))
        refer = b" /Info %d 0 R" % info if info else b""
        out.write(b"trailer\n<< /Size %d /Root 1 0 R%s >>\nstartxref\n%d\n%%%%EOF\n" % (n + 1, refer, xref))


def raster_pdf(pngs: list[Path], out: BinaryIO, info: dict[str, str] | None = None, tables=None) -> None:
    """A PDF of the table pages `tables` (report_pages.TablePages; A4, text in the figures' font),
    then one page per PNG, each page the image at its stated resolution, written to `out` (objects: 1
    catalog, 2 page tree, 3-12 the two fonts and 13 the pages' foot (a form) when there are table pages, then page
    and contents of each table page, page, contents and image of each figure, then the document information `info`
    when given)."""
    from orbitrig.analysis.pdf_text import font_objects
    from orbitrig.analysis.report_pages import PAGE

    pdf = _Objects(out)
    texts = tables.contents() if tables is not None else []
    kids, at = [], 14 if texts else 3  # 3-12: the fonts of the table pages, 13 their foot
    fonts = b"/Font << /F1 3 0 R /F2 8 0 R >>"
    if texts:
        foot = zlib.compress(tables.foot(), 6)
        pdf.put(
            13,
            b"<< /Type /XObject /Subtype /Form /BBox [0 0 %g %g] /Resources << %s >> /Filter /FlateDecode "
            b"/Length %d >>\nstream\n%s\nendstream" % (*PAGE, fonts, len(foot), foot),
        )
    for text in texts:
        pdf.put(
            at,
            b"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 %g %g] /Contents %d 0 R "
            b"/Resources << %s /XObject << /Foot 13 0 R >> >> >>" % (*PAGE, at + 1, fonts),
        )
        pdf.stream(at + 1, zlib.compress(text, 6), b" /Filter /FlateDecode")
        kids.append(at)
        at += 2
    for png in pngs:
        w, h, dpi, pixels = png_image(png)
        pw, ph = w * 72.0 / dpi, h * 72.0 / dpi
        pdf.put(
            at,
            b"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 %.3f %.3f] /Contents %d 0 R "
            b"/Resources << /XObject << /Im0 %d 0 R >> >> >>" % (pw, ph, at + 1, at + 2),
        )
        pdf.stream(at + 1, b"q %.3f 0 0 %.3f 0 0 cm /Im0 Do Q" % (pw, ph))
        pdf.put(
            at + 2,
            b"<< /Type /XObject /Subtype /Image /Width %d /Height %d /ColorSpace /DeviceRGB "
            b"/BitsPerComponent 8 /Filter /FlateDecode /DecodeParms << /Predictor 15 /Colors 3 "
            b"/BitsPerComponent 8 /Columns %d >> /Length %d >>\nstream\n"
            % (w, h, w, len(pixels))
            + pixels
            + b"\nendstream",
        )
        kids.append(at)
        at += 3
    for k, font in enumerate(tables.fonts if texts else ()):  # the glyphs the pages used are known now
        for j, body in enumerate(font_objects(font, 3 + 5 * k)):
            pdf.put(3 + 5 * k + j, body)
    pdf.put(1, b"<< /Type /Catalog /Pages 2 0 R >>")
    refs = b" ".join(b"%d 0 R" % k for k in kids)
    pdf.put(2, b"<< /Type /Pages /Kids [%s] /Count %d >>" % (refs, len(kids)))
    if info:
        pdf.put(at, _info_object(info))
    pdf.finish(at if info else None)
