"""A matrix using a designed list by name ([orbit] design = "NAME") and an [averaging] table."""

from __future__ import annotations

import tomllib

import pytest

from orbitrig import config as cfg
from orbitrig.errors import ConfigError

from support.cli_helpers import orbitrig
from support.paths import ROOT

DEMO = (ROOT / "config" / "matrices" / "demo.toml").read_text()


def with_orbit(orbit: str, extra: str = "") -> str:
    """The demo matrix with this [orbit] body; ``extra``: tables after it, a first line
    "top: KEY = V" goes to the top level instead."""
    text = DEMO
    if extra.startswith("top: "):
        top, _, extra = extra[5:].partition("\n")
        text = text.replace('name = "demo"', f'name = "demo"\n{top}')
    start, end = text.index("[orbit]"), text.index("[[models]]")
    return text[:start] + "[orbit]\n" + orbit + "\n\n" + extra + "\n" + text[end:]


def test_the_shipped_designed_matrix():
    mat = cfg.load_matrix(cfg.matrix_file("designed"))
    design = tomllib.loads((ROOT / "config" / "designs" / "kcd11-demo.toml").read_text())
    assert mat.orbit.design == "kcd11-demo"
    assert mat.orbit.ratio_list == sorted(design["ratios"])
    assert mat.orbit.directions == design["directions"] == ["forward", "backward"]
    # the design's revolutions and adaptive targets per ratio; the matrix's [averaging] gives the bounds
    assert [mat.orbit.revolutions_at(k) for k in range(len(design["ratios"]))] == design["revolutions"]
    assert [mat.orbit.target_pct_at(k) for k in range(len(design["ratios"]))] == design["target_pct"]
    assert (mat.averaging.target_pct, mat.averaging.min_revolutions, mat.averaging.max_revolutions) == (None, 20, 400)


def test_a_design_file_next_to_the_matrix(tmp_path):
    (tmp_path / "mine.toml").write_text('ratios = [0.4, 1.3]\ndirections = ["backward"]\n')
    path = tmp_path / "m.toml"
    path.write_text(with_orbit('design = "mine.toml"'))
    mat = cfg.load_matrix(path)
    assert mat.orbit.ratio_list == [0.4, 1.3] and mat.orbit.directions == ["backward"]


@pytest.mark.parametrize(
    "orbit, extra, message",
    [
        ('design = "kcd11-demo"\nratios = [0.5]', "", "give 'design' or the ratios"),
        ('design = "nosuch"', "", "no design file"),
        ('design = "kcd11-demo"', "top: revolutions = 40\n[averaging]\ntarget_pct = 1", "not both"),
        (
            'design = "kcd11-demo"',
            "[averaging]\ntarget_pct = 1\nmin_revolutions = 50\nmax_revolutions = 20",
            "must not exceed",
        ),
        ('design = "kcd11-demo"', "[averaging]\ntarget_pct = 0", "target_pct"),
    ],
)
def test_mistakes_are_named(tmp_path, orbit, extra, message):
    path = tmp_path / "bad.toml"
    path.write_text(with_orbit(orbit, extra))
    with pytest.raises(ConfigError) as err:
        cfg.load_matrix(path)
    assert message in str(err.value) and "bad.toml" in str(err.value)


def test_unknown_design_lists_the_known_ones_and_names_the_line(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(with_orbit('design = "nosuch"'))
    with pytest.raises(ConfigError) as err:
        cfg.load_matrix(path)
    line = with_orbit('design = "nosuch"').splitlines().index('design = "nosuch"') + 1
    assert f"line {line}:" in str(err.value) and "kcd11-demo" in str(err.value)


def test_dry_run_of_the_designed_matrix():
    p = orbitrig("sweep", "--dry-run", "--steps", "--matrix", "designed", timeout=120, columns=None)
    assert p.returncode == 0, p.stderr
    assert "4 orbit blocks" in p.stdout.splitlines()[0]
    out = " ".join(p.stdout.split())  # lines folded to 80 columns (piped), a step's under its column
    design = tomllib.loads((ROOT / "config" / "designs" / "kcd11-demo.toml").read_text())
    lo, hi = min(design["target_pct"]), max(design["target_pct"])
    assert f"adaptive averaging: every channel <= its ratio's target ({lo:g}..{hi:g} %) in 20..400 revolutions" in out
    counts = ", ".join(map(str, design["revolutions"]))
    assert f"{counts} revolutions per ratio (the expected counts)" in out
    # each block's expected count (the duration's) and its own target
    n_top, t_top = design["revolutions"][-1], design["target_pct"][-1]
    assert (
        f"acquire 20..400 revolutions (until every channel <= {t_top:g} %, about {n_top} expected) at 25.000 Hz" in out
    )
    assert "(the estimate above assumes each ratio's expected revolutions)" in out
