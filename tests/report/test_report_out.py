"""`orbitrig report DIR --out FOLDER` on a run of the real sweep on the simulator: a paper's
figures (single column, one kind, PNG and PDF) go to FOLDER with their own page, the run folder
stays byte for byte as it was (the operator's page and figures included), figures of the same
request the run already holds are copied rather than drawn again, and an FOLDER inside the run is
refused."""

from __future__ import annotations

import hashlib
import re
import shutil
import struct
from pathlib import Path

import pytest
from typer.testing import CliRunner

from orbitrig.analysis.report import ReportOptions, make_report
from orbitrig.cli import app

QUICK = ("--figures", "coherence,lms")  # two of the cheaper kinds: the operator's page


@pytest.fixture(scope="module")
def run(sweep_run, tmp_path_factory) -> Path:
    """A copy of the session's simulator run with the operator's report (coherence and lms
    figures); each test checks that it leaves it as it was."""
    copy = shutil.copytree(sweep_run, tmp_path_factory.mktemp("out") / "run", ignore=shutil.ignore_patterns("plots"))
    p = CliRunner().invoke(app, ["report", str(copy), *QUICK])
    assert p.exit_code == 0, p.output
    return copy


def _files(folder: Path) -> dict[str, str]:
    """Every file and folder under `folder` by relative name: SHA-256 of a file, "dir" for a folder."""
    return {
        p.relative_to(folder).as_posix(): "dir" if p.is_dir() else hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
    }


def _png_width(path: Path) -> int:
    """Pixels across a PNG (its IHDR)."""
    return struct.unpack(">I", path.read_bytes()[16:20])[0]


def test_journal_figures_go_to_out_and_leave_the_run_untouched(run, tmp_path):
    before = _files(run)
    assert "plots/index.html" in before and "plots/lms_0000.png" in before
    journal = tmp_path / "paper" / "figures"  # made with its parent
    journal_options = ["--width", "single", "--figures", "coherence", "--formats", "png,pdf"]
    p = CliRunner().invoke(app, ["report", str(run), "--out", str(journal), *journal_options])
    assert p.exit_code == 0, p.output
    assert _files(run) == before  # nothing written, removed or made in the run folder
    made = sorted(f.name for f in journal.iterdir() if f.is_file())
    assert made == ["coherence_0000.pdf", "coherence_0000.png", "index.html", "report.pdf"]
    # a journal's print widths at 300 dpi (placed there, the text prints at its stated size)
    assert _png_width(journal / "coherence_0000.png") == pytest.approx(85 / 25.4 * 300, abs=2)  # single column
    assert _png_width(run / "plots" / "coherence_0000.png") == pytest.approx(175 / 25.4 * 300, abs=2)  # the operator's
    assert f"open {journal / 'index.html'}" in p.output
    page = (journal / "index.html").read_text(encoding="utf-8")
    assert 'src="coherence_0000.png"' in page and "lms_0000.png" not in page
    links = re.findall(r'<a href="([^"#]+\.csv)">', page)
    assert links and (journal / links[0]).resolve() == (run / "coefficients.csv").resolve()


def test_figures_of_the_same_request_are_copied_from_the_run(run, tmp_path):
    """The run's own figures of the same kinds and style (the sweep's or an earlier report's)
    are copies in FOLDER, not drawn again; the run keeps its files."""
    before = _files(run)
    out = tmp_path / "elsewhere"
    report = make_report(run, out=out, options=ReportOptions(figures=frozenset({"coherence", "lms"})))
    assert [pr.reused for pr in report.points] == [True]
    assert sorted(p.name for p in report.plots) == ["coherence_0000.png", "lms_0000.png"]
    for name in ("coherence_0000.png", "lms_0000.png"):
        assert (out / name).read_bytes() == (run / "plots" / name).read_bytes()
    assert _files(run) == before
    again = make_report(run, out=out, options=ReportOptions(figures=frozenset({"coherence"})))
    assert [pr.reused for pr in again.points] == [False]  # another request: drawn, in FOLDER only
    assert sorted(p.name for p in out.glob("*.png")) == ["coherence_0000.png"]
    assert _files(run) == before


@pytest.mark.parametrize("inside", ["plots", "paper", "."])
def test_out_inside_the_run_is_refused(run, inside):
    before = _files(run)
    result = CliRunner().invoke(app, ["report", str(run), "--out", str(run / inside), *QUICK])
    assert result.exit_code == 2 and "inside the run folder" in result.output
    assert _files(run) == before
