"""`orbitrig report`'s page and report.pdf say which calibration record the run was made with
(or that it had none) and which code: report.pdf is shared on its own, away from run.json."""

from __future__ import annotations

from PIL import Image
from pypdf import PdfReader
from typer.testing import CliRunner

from orbitrig.cli import app
from orbitrig.config import digest
from orbitrig.run.provenance import Provenance

from support.report_synthetic import write_synthetic_run

RECORD = "2026-11-26T214732Z-initial"
RECORD_TEXT = 'date = "2026-11-26T21:47:32Z"\noperator = "lab"\nstep = "initial"\n'


def _provenance(record: str, sha: str) -> dict:
    p = Provenance("alice", "orbitrig 0.1.0 (source 3f9a1c2e4b7d)", "SAC-DS-1", {}, record, sha, "bench", "now")
    return p.to_dict()


def _report(run, *formats: str, points: tuple[str, ...] = ("--point", "0"), figures: str = "coherence"):
    """`orbitrig report` of `run` drawing only `figures` (the page and report.pdf say the same
    whichever are drawn; coherence is the quickest kind to draw)."""
    args = ["report", str(run), *points, "--figures", figures, "--formats", ",".join(formats or ("png",))]
    r = CliRunner().invoke(app, args)
    assert r.exit_code == 0, r.output
    page = (run / "plots" / "index.html").read_text(encoding="utf-8")
    return page, PdfReader(run / "plots" / "report.pdf").metadata


def test_report_pdf_names_the_record_its_digest_and_the_software(tmp_path):
    sha = digest(RECORD_TEXT)
    run = write_synthetic_run(
        tmp_path / "run", n_points=1, incomplete=0, provenance=_provenance(RECORD, sha), record_text=RECORD_TEXT
    )
    page, info = _report(run)
    assert f"{RECORD} (SHA-256 {sha})" in page
    assert info["/OrbitrigCalibrationRecord"] == f"{RECORD} (SHA-256 {sha})"
    assert info["/OrbitrigCalibrationRecordSHA256"] == sha
    assert info["/OrbitrigSoftwareVersion"].startswith("orbitrig 0.1.0 (source 3f9a1c2e4b7d)")
    assert info["/OrbitrigRunId"] and info["/OrbitrigRunId"] in info["/Subject"]
    assert "/OrbitrigSimScenarioSHA256" in info  # a --sim run: the scenario's text digest (here none stored)


def test_a_record_past_its_validity_at_the_start_is_said_expired_on_the_page_and_in_the_pdf(tmp_path):
    sha = digest(RECORD_TEXT)
    expired = (
        "expired: past calibration_valid_days = 365 at the run's start; loads 400 days old (2025-11-01, record "
        "2025-11-01T083000Z-loads)"
    )
    prov = _provenance(RECORD, sha) | {"calibration_validity": expired}
    run = write_synthetic_run(tmp_path / "run", n_points=1, incomplete=0, provenance=prov, record_text=RECORD_TEXT)
    page, info = _report(run)
    assert info["/OrbitrigCalibrationRecord"] == f"{RECORD} (SHA-256 {sha}); {expired}"
    assert f"{RECORD} (SHA-256 {sha}); expired: past calibration_valid_days = 365 at the run&#x27;s start" in page
    valid = prov | {"calibration_validity": "valid: within calibration_valid_days = 365 at the run's start; ..."}
    run = write_synthetic_run(tmp_path / "valid", n_points=1, incomplete=0, provenance=valid, record_text=RECORD_TEXT)
    assert _report(run)[1]["/OrbitrigCalibrationRecord"] == f"{RECORD} (SHA-256 {sha})"


def test_a_run_without_a_calibration_record_says_none_on_the_page_and_in_the_pdf(tmp_path):
    """The page left the row out (an empty cell): a reader could not tell 'none' from 'not shown'."""
    run = write_synthetic_run(tmp_path / "run", n_points=1, incomplete=0, provenance=_provenance("", ""))
    page, info = _report(run)
    assert "calibration record</th><td" in page and "none (no calibration corrections" in page
    assert info["/OrbitrigCalibrationRecord"].startswith("none (no calibration corrections")


def test_the_joined_vector_pdf_and_every_figure_file_carry_the_same_information(tmp_path):
    """A figure is copied into a slide or a paper on its own: each file (PNG, PDF, SVG) names the
    run, the calibration record with its SHA-256 and the software in its metadata (every kind is
    saved by plots.save_figure: the forces figures of both points, drawn in forked workers, and
    the summary, drawn here, stand for them)."""
    sha = digest(RECORD_TEXT)
    run = write_synthetic_run(
        tmp_path / "run", n_points=2, incomplete=0, provenance=_provenance(RECORD, sha), record_text=RECORD_TEXT
    )
    _, info = _report(run, "png", "pdf", "svg", points=("--workers", "2"), figures="forces")  # forked workers
    assert info["/OrbitrigCalibrationRecordSHA256"] == sha
    assert info["/Title"] == "orbitrig run run"
    subject = info["/Subject"]
    assert f"calibration record {RECORD} (SHA-256 {sha})" in subject and "source 3f9a1c2e4b7d" in subject
    pngs = sorted((run / "plots").glob("*.png"))
    assert {p.name.split("_")[0].removesuffix(".png") for p in pngs} == {"forces", "summary"}
    assert {p.name[:-4].rsplit("_", 2)[-2] for p in pngs if p.name.startswith("forces_")} >= {"0000", "0001"}
    for png in pngs:
        with Image.open(png) as im:
            assert im.text["Description"] == subject, png
        assert PdfReader(png.with_suffix(".pdf")).metadata["/Subject"] == subject
        assert f"<dc:description>{subject}</dc:description>" in png.with_suffix(".svg").read_text(encoding="utf-8")


def test_a_run_stored_before_provenance_is_not_told_as_one_without_a_record(tmp_path):
    run = write_synthetic_run(tmp_path / "run", n_points=1, incomplete=0)  # no provenance stored
    page, info = _report(run)
    assert "not recorded" in page and "none (no calibration" not in page
    assert info["/OrbitrigCalibrationRecord"] == "not recorded"


def test_the_page_says_which_corrections_the_run_took_out(tmp_path):
    """Runout, gain matrices and lags as the run's stored rig configuration and record say them:
    the shipped record (commissioning: nothing measured) takes nothing out; one with a measured
    runout and a piezo gain matrix says it subtracted that runout, unless rig.toml turns it off."""
    from types import SimpleNamespace

    from orbitrig.analysis.report_pdf import corrections_text
    from orbitrig.config.record_files import record_from_text, write_record
    from orbitrig.config.records import LoadGains, ProbeRunout, Runout
    from orbitrig.load_systems import LoadSystem
    from support.paths import ROOT

    rig_text = (ROOT / "config" / "rig.toml").read_text(encoding="utf-8")
    shipped = (ROOT / "config" / "calibration" / f"{RECORD}.toml").read_text(encoding="utf-8")
    told = corrections_text(SimpleNamespace(rig_config=rig_text, calibration_record_text=shipped))
    assert told == (
        "force lags: not applied (none in the record); "
        "force gain matrices: not applied (none in the record: identity); "
        "probe runout: not applied (none in the record); probe gains: not applied (none in the record); "
        "probe lags: not applied (none in the record)"
    )
    probe = ProbeRunout(h1_um=[0.5, 0.1], h2_um=[0.05, 0.0])
    runout = Runout(spin_rpm=60.0, revolutions=40, x_a=probe, y_a=probe, x_b=probe, y_b=probe)
    piezo = LoadGains(gain=[[1.01, 0.0], [0.0, 0.99]], gain_u=[[0.002, 0.001], [0.001, 0.002]])
    measured = record_from_text(shipped, "shipped").model_copy(
        update={"runout": runout, "loads": {LoadSystem.PIEZO: piezo}}
    )
    name, text = write_record(tmp_path, measured.model_copy(update={"date": "2026-11-27T10:00:00.000Z"}))
    rig_text = rig_text.replace(f'calibration_record = "{RECORD}"', f'calibration_record = "{name}"')
    run = SimpleNamespace(rig_config=rig_text, calibration_record_text=text)
    told = corrections_text(run)
    assert f"force gain matrices: applied (record {name}: piezo);" in told
    assert f"probe runout: applied (record {name}: slow roll at 60 rpm, 40 revolutions)" in told
    run.rig_config = "subtract_runout = false\n" + rig_text
    assert "probe runout: not applied (subtract_runout = false)" in corrections_text(run)
    assert corrections_text(SimpleNamespace(rig_config="", calibration_record_text="")) == ""


def test_a_simulated_runs_page_states_every_correction_the_readme_names(sweep_run, tmp_path):
    """The report of a real `sweep --sim` run (the shipped commissioning record: nothing measured)
    states each correction, probe lags included, as applied or not; the README names the same."""
    import html
    import re

    from orbitrig.analysis.report_pdf import CORRECTIONS
    from support.paths import ROOT

    r = CliRunner().invoke(app, ["report", str(sweep_run), "--figures", "", "--out", str(tmp_path / "out")])
    assert r.exit_code == 0, r.output
    page = (tmp_path / "out" / "index.html").read_text(encoding="utf-8")
    row = re.search(r'<th class="l">corrections applied</th><td class="l">(.*?)</td>', page)
    assert row is not None, page[:3000]
    told = html.unescape(row.group(1)).split("; ")
    assert [part.split(": ", 1)[0] for part in told] == list(CORRECTIONS)
    assert all(part.split(": ", 1)[1].startswith("not applied (none in the record") for part in told), told
    readme = " ".join((ROOT / "README.md").read_text(encoding="utf-8").split())
    header = readme[readme.index("the corrections the sweep took out") :][:900]
    for name in CORRECTIONS:
        assert f"`{name}`" in header, (name, header)


def test_report_pdf_s_first_page_states_the_header_a_referee_needs(tmp_path):
    """The file shared alone states on its first page, not only in its document information, the
    calibration record with its digest, each correction's state and the software, as the page does."""
    from orbitrig.analysis.report_pdf import provenance_rows
    from orbitrig.store.reader import read_run

    sha = digest(RECORD_TEXT)
    run = write_synthetic_run(
        tmp_path / "run", n_points=1, incomplete=0, provenance=_provenance(RECORD, sha), record_text=RECORD_TEXT
    )
    _report(run)
    first = " ".join(PdfReader(run / "plots" / "report.pdf").pages[0].extract_text().split())
    rows = dict(provenance_rows(read_run(run)))
    assert first.startswith("orbitrig run run matrix: ")
    assert f"calibration record: {RECORD} (SHA-256 {sha})" in first
    assert (
        rows["corrections applied"] and f"corrections applied: {' '.join(rows['corrections applied'].split())}" in first
    )
    assert "software version: orbitrig 0.1.0 (source 3f9a1c2e4b7d)" in first and "operator: alice" in first
    assert first.index("software version: ") < first.index("Run run, point 0000: ")  # the header, then the tables
