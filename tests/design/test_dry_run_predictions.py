"""`sweep --dry-run`: the predicted uncertainty of each configured model and the refusals."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from orbitrig.cli.design_inputs import NOMINAL, stated_noise
from reduction.frequency_list import DesignProblem, predict
from reduction.models import model_spec

from support.cli_helpers import orbitrig
from support.paths import ROOT
from support.sweep_helpers import demo_text


def dry_run(matrix: Path) -> str:
    """The dry run's output on a terminal wide enough that no line is folded: one line each."""
    p = orbitrig("sweep", "--dry-run", "--matrix", str(matrix), timeout=120, columns=1000)
    assert p.returncode == 0, p.stderr
    return p.stdout


def worst_pct(model: str, ratios, radius: float, revolutions: int = 50, directions: str = "both") -> float:
    spec = model_spec(model)
    theta = np.array([NOMINAL.get(n, 0.0) for n in spec.names])
    problem = DesignProblem(
        spec, theta, 1000 * 2 * np.pi / 60, radius, stated_noise().u_revolution, revolutions, directions
    )
    return predict(problem, ratios).worst * 100


def test_demo_predictions_match_the_design(tmp_path):
    out = dry_run(ROOT / "config" / "matrices" / "demo.toml")
    lines = out.splitlines()
    assert lines[2].startswith("predicted uncertainty (Cramer-Rao; noise stated: 20 N (forces), 100 nm")
    ratios, radius = [0.3, 0.5, 0.7, 0.9, 1.2], 0.096 * 60e-6
    for model, coef in (("kcd11", "Dyy"), ("kc8", "C")):
        line = next(ln for ln in lines if ln.startswith(f"  {model} none:"))
        shown = float(re.search(r"worst relative standard error ([0-9.e+]+) %", line).group(1))
        assert shown == float(f"{worst_pct(model, ratios, radius):.3g}")
        assert f"({coef}" in line and "1000 rpm" in line and "orbit radius 5.76 \u00b5m)" in line and " um" not in line
    # more revolutions per block: the prediction falls as 1/sqrt(n), the plan takes longer
    more = tmp_path / "more.toml"
    more.write_text(demo_text("more", 200))
    out4 = dry_run(more)
    line = next(ln for ln in out4.splitlines() if ln.startswith("  kc8 none:"))
    shown = float(re.search(r"error ([0-9.e+]+) %", line).group(1))
    assert shown == float(f"{worst_pct('kc8', ratios, radius, 200):.3g}")
    assert shown < worst_pct("kc8", ratios, radius) / 1.9
    assert "200 revolutions per block" in out4


def test_models_the_planned_orbits_cannot_identify(tmp_path):
    one_way = tmp_path / "forward.toml"
    one_way.write_text(
        demo_text("forward")
        .replace('directions = ["forward", "backward"]', 'directions = ["forward"]')
        .replace("ratios = [0.3, 0.5, 0.7, 0.9, 1.2]", "ratios = [0.3, 0.5]")
    )
    out = dry_run(one_way)
    refused = [ln for ln in out.splitlines() if "CANNOT be identified" in ln]
    assert any(ln.startswith("  kcd11 none:") for ln in refused), out[:2000]
    assert "orbit blocks" in out.splitlines()[0]  # the plan itself is still shown
