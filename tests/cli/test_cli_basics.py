"""The hands-on CLI: --version, help texts without a type on flags, matrix names, the dry run's totals first."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest
from support.cli_helpers import orbitrig, orbitrig_here
from support.paths import ROOT

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
        p = orbitrig_here(*args)
        assert p.returncode == 0, p.stderr
        assert p.stdout.strip() == f"orbitrig {package.__version__}"


def test_root_help_lists_every_command_and_no_type_on_flags():
    p = orbitrig_here("--help")
    assert p.returncode == 0, p.stderr
    for name in ("identify", "sim", "acquire", "sweep", "reduce", "report", "serve", "drives", "--version"):
        assert name in p.stdout
    assert "<bool>" not in p.stdout


HELP_PROBE = """
import sys
import typer.main
import orbitrig.cli
try:
    typer.main.get_command(orbitrig.cli.app)(["--help"], prog_name="orbitrig")
except SystemExit:
    pass
print(sorted(n for n in sys.modules if n.split(".")[0] in ("rich", "asyncio", "numpy")))
"""


def test_root_help_shows_each_commands_whole_first_sentence_in_plain_text():
    """Plain text at any width: no box drawing, no description cut short with "..." where the
    names leave less room (click's default), and `--help` loads neither rich nor asyncio."""
    env = {**os.environ, "COLUMNS": "60"}
    p = subprocess.run(
        [sys.executable, "-c", HELP_PROBE], cwd=ROOT, env=env, capture_output=True, text=True, timeout=60
    )
    assert p.returncode == 0, p.stderr
    *help_lines, loaded = p.stdout.splitlines()
    assert loaded == "[]"
    text = "\n".join(help_lines)
    assert "\u2500" not in text and "\u2502" not in text
    commands = help_lines[help_lines.index("Commands:") :]
    assert not [line for line in commands if line.endswith("...")]
    assert max(len(line) for line in help_lines) <= 60
    flat = " ".join(text.split())
    assert (
        "design Predict the coefficients' standard errors for a list of orbit frequencies and propose a better list."
        in flat
    )


@pytest.mark.parametrize("command", COMMANDS)
def test_help_shows_flags_without_a_value_type(command):
    p = orbitrig_here(*command.split(), "--help")
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
    # each UNDETERMINED line with its continuation (folded at 200 columns, indented 6)
    undetermined = [" ".join(ln.split()) for ln in re.split(r"\n(?! {6})", p.stdout) if ln.startswith("    UNDET")]
    assert len(undetermined) == 3  # kcd11 none, power:1 and power:2: D over 100 %; kc7 fits are not named
    assert re.search(r"Dyy \d+\.\.929 %", undetermined[0]) and "Dyy 2.48e+03..3.72e+04 %" in undetermined[1]
    # the times as the header says, h:mm:ss: a column that lines up across the hour
    assert next(ln for ln in lines if ln.startswith("point ")).endswith("(times h:mm:ss)")
    points = [ln for ln in lines if re.fullmatch(r"\s*\d+\s+\d+:\d\d:\d\d\s+\d+:\d\d:\d\d\s+20\s+w\d+rpm\S+", ln)]
    starts = [ln.split()[1] for ln in points]
    assert starts[0] == "0:00:00" and len({len(t) for t in starts}) == 1, starts  # under 10 h: one width
    assert [ln.split()[0] for ln in points] == [f"{i:04d}" for i in range(108)]  # as --steps and the run's files
    assert len(lines) < 150 and f"({m.group(1)} steps: --steps lists every one" in lines[-1]
    full = orbitrig("sweep", "--sim", "--dry-run", "--matrix", "paper", "--steps").stdout.splitlines()
    steps = [line for line in full if re.match(r"\s*\d+\s+\d+:\d\d:\d\d\s+(point|end)", line)]
    assert len(steps) == int(m.group(1)) and steps[-1].split()[0] == m.group(1)
    assert sorted({ln.split()[3] for ln in steps if ln.split()[2] == "point"}) == [ln.split()[0] for ln in points]


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
    # only the plan's one warning (the paper's ratios 0.978 and 1.089 near 1), nothing of the pipe
    lines = p.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("warning: ") and "0.977778, 1.08889 are within 0.1" in lines[0]


def _help_words(*command: str) -> str:
    """The help of ``command`` as one line of words (the table's borders and wrapping removed)."""
    p = orbitrig_here(*command, "--help")
    assert p.returncode == 0, p.stderr
    return " ".join(p.stdout.replace("│", " ").split())


@pytest.mark.parametrize(
    "command",
    ["calibrate list", "calibrate show", "calibrate delay", "drives run", "drives stop", "acquire", "sweep", "design"],
)
def test_the_rig_configuration_option_says_where_the_default_is_found(command):
    """One help for every command's --config (acquire's --rig): the lookup of README "Where
    commands find the configuration", not the source tree."""
    from orbitrig.cli.config_help import RIG_CONFIG_HELP

    assert "$ORBITRIG_HOME" in RIG_CONFIG_HELP and "current directory" in RIG_CONFIG_HELP
    words = _help_words(*command.split())
    assert RIG_CONFIG_HELP in words and "source tree" not in words


def test_design_help_names_the_default_revolutions_in_full():
    words = _help_words("design")
    assert "(default: averaging.revolutions of the rig configuration)" in words and "rig.toml )" not in words


def test_design_help_says_noise_from_takes_a_run_file_too():
    words = _help_words("design")
    assert "Run directory, or a run file itself (run.h5 or its h5 export, under any name)" in words


def test_the_paper_matrix_comment_counts_what_kcd11_power_2_fits():
    """config/matrices/paper.toml says kcd11 power:2 is fitted with 18 coefficients, as the
    identification does (K_2 carried by D), not that it is refused."""
    from reduction.models import model_spec
    from support.paths import ROOT

    comment = " ".join(
        line.lstrip("# ") for line in (ROOT / "config/matrices/paper.toml").read_text().splitlines() if line[:1] == "#"
    )
    assert len(model_spec("kcd11", "power:2").terms) == 18 and "14 and 18 with second order" in comment
    assert "kcd11 with power:2 is fitted without K_2" in comment and "refused" not in comment
