"""`sweep --dry-run` and `design` piped: their lines for reading (totals, predictions, the
UNDETERMINED lists, the candidate and proposed lists, warnings, each step's description) are
folded to 80 columns (orbitrig.cli.plain_table.wrap; they ran to ~400), a continuation indented
under its line or its column, a list's entry never split; the words are those of a wide terminal.
The tables keep their rows, and --json is as it was."""

from __future__ import annotations

import json
import os
import re
import subprocess

import pytest

from orbitrig.cli.plain_table import PIPE_WIDTH, unbroken, wrap
from support.cli_helpers import orbitrig_cmd
from support.paths import ROOT

PLANS = {
    "dry-run paper": ("sweep", "--sim", "--dry-run", "--steps", "--matrix", "paper"),
    "dry-run designed": ("sweep", "--sim", "--dry-run", "--steps", "--matrix", "designed"),
    "design match": ("design", "--model", "kcd11", "--spin", "1000", "--match"),
    "design target": ("design", "--model", "kc8", "--spin", "1000", "--matrix", "demo", "--target", "0.2"),
}


def _run(args: tuple[str, ...], columns: int | None) -> str:
    env = {k: v for k, v in os.environ.items() if k != "COLUMNS"}
    if columns is not None:
        env["COLUMNS"] = str(columns)
    p = subprocess.run(orbitrig_cmd(*args), cwd=ROOT, env=env, capture_output=True, text=True, timeout=180)
    assert p.returncode == 0, p.stderr
    return p.stdout


@pytest.mark.parametrize("name", PLANS)
def test_piped_lines_fit_80_columns_and_say_what_a_wide_terminal_says(name):
    piped, wide = _run(PLANS[name], None), _run(PLANS[name], 1000)
    assert max(map(len, wide.splitlines())) > 150  # lines that ran long
    too_long = [line for line in piped.splitlines() if len(line) > PIPE_WIDTH and " " in line.strip()]
    assert too_long == []
    assert piped.split() == wide.split()  # folded at spaces only: nothing lost, cut or added
    assert "\u00a0" not in piped


def test_a_list_entry_stays_whole_and_a_continuation_sits_under_its_line():
    out = _run(PLANS["dry-run paper"], None)
    entry = re.compile(r"D[xy]{2}(_\d)? [0-9.e+]+(\.\.[0-9.e+]+)? % \(\d of 6\)")
    block = out.split("    UNDETERMINED")[2].split("\n  kc7 power:2")[0].splitlines()[1:]
    assert block and all(line.startswith("      ") and not line.startswith("       ") for line in block)
    assert len(entry.findall(out)) == 3 + 6 + 6  # every entry on one line
    by_step = out.split("by step: ")[1].split("\npredicted")[0]
    assert "settle 1:12:00" in by_step and "\n  " in by_step  # folded between entries, not inside one
    step = next(i for i, line in enumerate(out.splitlines()) if "  identify (kc7/none/ols" in line)
    lines = out.splitlines()
    column = lines[step].index("identify (")
    assert lines[step + 1][:column].strip() == "" and lines[step + 1][column] != " "  # under the step column


def test_design_json_is_not_folded():
    args = ("design", "--model", "kcd11", "--spin", "1000", "--match", "--json")
    piped, wide = _run(args, None), _run(args, 1000)
    assert piped == wide and json.loads(piped)["proposal"]["ratios"]


def test_wrap_indents_a_continuation_under_its_line_and_keeps_an_entry():
    text = "    UNDETERMINED: " + ", ".join(unbroken(f"Dxx {i}..{i + 9} % (6 of 6)") for i in range(6))
    lines = wrap(text, width=40).splitlines()
    assert lines[0].startswith("    UNDETERMINED:") and all(ln.startswith("      D") for ln in lines[1:])
    assert all(re.fullmatch(r" +(UNDETERMINED: )?(Dxx \d+\.\.\d+ % \(6 of 6\),? ?)+", ln) for ln in lines)
    assert wrap("a b c", width=2, indent="   ") == "a\n   b\n   c"
    assert wrap("x" * 50, width=10) == "x" * 50  # one word: never cut
