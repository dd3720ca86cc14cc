"""The hands-on CLI: --version, help texts without a type on flags, matrix names, the dry run's totals first."""

from __future__ import annotations

import re

import pytest
from support.cli_helpers import orbitrig

import orbitrig as package

COMMANDS = [
    "identify",
    "sim",
    "acquire",
    "sweep",
    "reduce",
    "report",
    "serve",
    "version",
    "drives",
    "drives status",
    "drives run",
    "drives stop",
]


def test_version_option_prints_the_package_version():
    for args in (["--version"], ["version"]):
        p = orbitrig(*args)
        assert p.returncode == 0, p.stderr
        assert p.stdout.strip() == f"orbitrig {package.__version__}"


def test_root_help_lists_every_command_and_no_type_on_flags():
    p = orbitrig("--help")
    assert p.returncode == 0, p.stderr
    for name in ("identify", "sim", "acquire", "sweep", "reduce", "report", "serve", "drives", "--version"):
        assert name in p.stdout
    assert "<bool>" not in p.stdout


@pytest.mark.parametrize("command", COMMANDS)
def test_help_shows_flags_without_a_value_type(command):
    p = orbitrig(*command.split(), "--help")
    assert p.returncode == 0, p.stderr
    assert "<bool>" not in p.stdout
    help_line = next(line for line in p.stdout.splitlines() if "--help" in line)
    assert re.search(r"--help\s+Show this message", help_line), help_line  # nothing between flag and text
    if command == "sweep":  # options that take values keep their type
        assert re.search(r"--dry-run\s+print the plan", p.stdout)
        assert re.search(r"--speedup\s+<float", p.stdout)


def test_sweep_matrix_by_name_prints_totals_first():
    """The paper's matrix: totals, predictions (naming the undetermined fits), one line per point;
    --steps adds every step."""
    p = orbitrig("sweep", "--sim", "--dry-run", "--matrix", "paper")
    assert p.returncode == 0, p.stderr
    lines = p.stdout.splitlines()
    m = re.fullmatch(
        r"matrix paper: 108 operating points, 2160 orbit blocks, (\d+) steps, estimated (\S+) "
        r"\(physical time\)",
        lines[0],
    )
    assert m, lines[0]
    assert lines[1].startswith("by step: manual settings ")
    assert lines[2].startswith("predicted uncertainty")
    undetermined = [ln for ln in lines if ln.startswith("    UNDETERMINED")]
    assert len(undetermined) == 3  # kcd11 none, power:1 and power:2: D over 100 %; kc7 fits are not named
    assert re.search(r"Dyy \d+\.\.929 %", undetermined[0]) and "Dyy 2.48e+03..3.72e+04 %" in undetermined[1]
    points = [ln for ln in lines if re.fullmatch(r"\s*\d+\s+\d+:\d\d(:\d\d)?\s+\d+:\d\d\s+20\s+w\d+rpm\S+", ln)]
    assert [int(ln.split()[0]) for ln in points] == list(range(108))
    assert len(lines) < 150 and f"({m.group(1)} steps: --steps lists every one" in lines[-1]
    full = orbitrig("sweep", "--sim", "--dry-run", "--matrix", "paper", "--steps").stdout.splitlines()
    steps = [line for line in full if re.match(r"\s*\d+\s+\d+:\d\d(:\d\d)?\s+(point|end)", line)]
    assert len(steps) == int(m.group(1)) and steps[-1].split()[0] == m.group(1)


def test_sweep_matrix_name_and_file_give_the_same_plan():
    by_name = orbitrig("sweep", "--sim", "--dry-run", "--matrix", "demo")
    by_file = orbitrig("sweep", "--sim", "--dry-run", "--matrix", "config/matrices/demo.toml")
    assert by_name.returncode == by_file.returncode == 0
    assert by_name.stdout == by_file.stdout


def test_sweep_unknown_matrix_name_lists_the_available_ones():
    p = orbitrig("sweep", "--sim", "--dry-run", "--matrix", "no-such-matrix")
    assert p.returncode == 2
    assert p.stdout == ""
    assert "no-such-matrix" in p.stderr and "demo" in p.stderr and "paper" in p.stderr
    assert "Traceback" not in p.stderr


def test_dry_run_into_a_closed_pipe_is_quiet():
    import subprocess
    import sys

    from support.paths import ROOT

    cmd = f"{sys.executable} -m orbitrig sweep --sim --dry-run --matrix paper | head -n 2"
    p = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert p.stdout.startswith("matrix paper: 108 operating points")
    assert p.stderr == ""
