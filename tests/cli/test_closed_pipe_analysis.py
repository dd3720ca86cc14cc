"""The analysis commands (identify, reduce, report, compare, catalog list|export, design,
export, init) piped into a reader that is gone before they print (`... | true`, a `| head` that
has its lines): the command does its work, says nothing of the pipe (its notes and warnings
only) and keeps its exit status (0), as the dry run does (tests/cli/test_cli_basics.py).
Before, click's own handling of the broken pipe ended them with exit 1 and nothing on standard
error. Onto a full disk they fail saying so in the one error form (before: a traceback)."""

from __future__ import annotations

import shlex
import subprocess
import sys

import pytest
from support.paths import ROOT
from support.report_synthetic import write_synthetic_run

TABLE = "examples/orbit-tables/kcd11-constant.csv"


def _into_gone_reader(*args: str) -> subprocess.CompletedProcess:
    """`python -m orbitrig ARGS... | true` under pipefail: the reader exits at once, so every
    write of the command meets a closed pipe (EPIPE)."""
    cmd = f"{shlex.quote(sys.executable)} -m orbitrig {shlex.join(args)} | true"
    return subprocess.run(["bash", "-o", "pipefail", "-c", cmd], cwd=ROOT, capture_output=True, text=True, timeout=120)


def _only_notes(stderr: str) -> bool:
    return all(line.startswith(("note: ", "warning: ")) for line in stderr.splitlines())


@pytest.mark.parametrize("output", [(), ("--json",), ("--format", "csv")])
def test_identify_into_a_gone_reader_exits_0_and_says_nothing(output):
    p = _into_gone_reader("identify", TABLE, "--model", "kcd11", "--method", "wls", *output)
    assert p.returncode == 0 and _only_notes(p.stderr), p.stderr


def test_reduce_into_a_gone_reader_writes_its_csv_and_exits_0(tmp_path):
    run = write_synthetic_run(tmp_path / "run", n_points=1, incomplete=0)
    p = _into_gone_reader("reduce", str(run), "--model", "kc8")
    assert p.returncode == 0 and _only_notes(p.stderr), p.stderr
    assert (run / "reduce_kc8_none_ols.csv").read_text().count("\n") >= 3  # header and both systems' rows


@pytest.mark.parametrize("output", [(), ("--json",)])
def test_identify_onto_a_full_disk_fails_naming_standard_output(output):
    with open("/dev/full", "w") as full:
        p = subprocess.run(
            [sys.executable, "-m", "orbitrig", "identify", TABLE, "--model", "kcd11", *output],
            cwd=ROOT,
            stdout=full,
            stderr=subprocess.PIPE,
            text=True,
            timeout=120,
        )
    assert p.returncode == 1
    assert p.stderr.splitlines()[-1] == "orbitrig identify: error: standard output: No space left on device"
    assert "Traceback" not in p.stderr


@pytest.mark.parametrize("command", [("list",), ("export", "--format", "csv")])
def test_the_catalog_into_a_gone_reader_exits_0(tmp_path, command):
    pytest.importorskip("sqlalchemy")
    runs = tmp_path / "runs"
    write_synthetic_run(runs / "run1", n_points=1, incomplete=0)
    assert (
        subprocess.run([sys.executable, "-m", "orbitrig", "catalog", "add", str(runs / "run1")], cwd=ROOT).returncode
        == 0
    )
    p = _into_gone_reader("catalog", *command, "--runs", str(runs))
    assert p.returncode == 0 and "error" not in p.stderr, p.stderr


@pytest.mark.parametrize("output", [(), ("--json",)])
def test_design_into_a_gone_reader_exits_0(output):
    p = _into_gone_reader("design", "--model", "kc8", "--spin", "1000", "--matrix", "demo", *output)
    assert p.returncode == 0 and "error" not in p.stderr, p.stderr


def test_export_and_init_into_a_gone_reader_do_their_work_and_exit_0(tmp_path):
    run = write_synthetic_run(tmp_path / "run", n_points=1, incomplete=0)
    p = _into_gone_reader("export", str(run), "--format", "csv")
    assert (p.returncode, p.stderr) == (0, "")
    assert (run / "export" / "fits.csv").is_file()
    p = _into_gone_reader("init", str(tmp_path / "lab"), "--rig-id", "rig-7")
    assert (p.returncode, p.stderr) == (0, "")
    assert 'rig_id = "rig-7"' in (tmp_path / "lab" / "rig.toml").read_text()


def test_report_and_compare_into_a_gone_reader_draw_and_exit_0(tmp_path):
    pytest.importorskip("sqlalchemy")
    run = write_synthetic_run(tmp_path / "run", n_points=1, incomplete=0)
    p = _into_gone_reader("report", str(run), "--figures", "coherence")
    assert p.returncode == 0 and "error" not in p.stderr, p.stderr
    assert (run / "plots" / "index.html").is_file() and list((run / "plots").glob("coherence_*.png"))
    p = _into_gone_reader("compare", str(run), "--against", "static_eccentricity", "--out", str(tmp_path / "figs"))
    assert p.returncode == 0 and "error" not in p.stderr, p.stderr
    assert (tmp_path / "figs" / "compare.png").is_file() and (tmp_path / "figs" / "compare.pdf").is_file()
