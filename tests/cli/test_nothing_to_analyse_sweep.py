"""A real `sweep --sim` stopped by SIGTERM before its first point completes: `export`, `report`
and `reduce` of that run each have nothing to work on and say so alike (exit 1, the point named,
no folder or CSV made), the rule tests/cli/test_nothing_to_analyse.py checks on a synthetic run."""

from __future__ import annotations

import signal

import pytest
from typer.testing import CliRunner

from orbitrig.cli import app
from support.store_checks import small_matrix
from support.sweep_process import SweepProcess, sweeps

pytestmark = pytest.mark.timeout(150)


def test_a_sweep_stopped_before_its_first_point_completes_is_nothing_to_analyse(tmp_path):
    (tmp_path / "m.toml").write_text(small_matrix("cut", 20, spin_rpm=(1000.0,)))
    with sweeps(lambda: SweepProcess(tmp_path / "run", "--matrix", str(tmp_path / "m.toml"), "--speedup", "5")) as go:
        s = go()
        s.wait_log("point 0000: stored")  # one block of the point stored
        s.proc.send_signal(signal.SIGTERM)
        assert s.proc.wait(60) == 3, s.proc.stderr.read()  # stopped
    run = s.out
    assert not (run / "points" / "0000" / "complete.json").exists()
    before = sorted(str(p.relative_to(run)) for p in run.rglob("*"))
    for command, extra, done in (
        ("export", ("--format", "mat"), "exported"),
        ("report", ("--figures", "coefficients"), "drawn"),
        ("reduce", ("--model", "kc8"), "reduced"),
    ):
        res = CliRunner().invoke(app, [command, str(run), *extra])
        assert res.exit_code == 1, (command, res.output)
        assert "point 0000 not included: never completed" in res.stderr, res.stderr
        assert f"error: nothing {done}: the run has no complete operating point" in res.stderr
    assert sorted(str(p.relative_to(run)) for p in run.rglob("*")) == before
