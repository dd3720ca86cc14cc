"""A matrix against the rig before anything starts (orbitrig.config.plan_checks): the supply
pressure each point asks against the interlock band, orbit ratios at Omega/omega = 1 refused and
near it warned once per matrix, a sequential initial list that cannot identify its model, and
the line of each [sequential] key's own problem."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from orbitrig import config as cfg
from orbitrig.cli import app
from orbitrig.errors import ConfigError
from orbitrig.run.events import RunOutcome
from orbitrig.run.states import Outcome

MATRIX = """name = "t"
[operating]
spin_rpm = {spin}
recess_pressure_mpa = {recess}
pressure_ratio = {beta}
static_eccentricity = [0.0]
dynamic_eccentricity = [0.096]
[orbit]
{ratios}
directions = {directions}
{extra}[[models]]
model = "kcd11"
"""

SEQUENTIAL = """sequential = true
[sequential]
target_pct = 0.5
cap_s = 120
{bounds}
"""


def write(tmp_path: Path, name: str = "m.toml", **keys: str) -> Path:
    """A matrix file whose [operating] keys are on lines 3-7, [orbit] on 8, its ratios on 9."""
    given = {
        "spin": "[1000.0]",
        "recess": "[0.4826]",
        "beta": "[0.4]",
        "ratios": "ratios = [0.3, 0.5, 0.7]",
        "directions": '["forward", "backward"]',
        "extra": "",
    }
    given.update(keys)
    path = tmp_path / name
    path.write_text(MATRIX.format(**given))
    return path


def problems(path: Path, rig=None) -> list[str]:
    """The problems check_matrix_against_rig finds ([] none), asserting they name the file."""
    try:
        cfg.check_matrix_against_rig(cfg.load_matrix(path), rig or cfg.load_rig())
    except ConfigError as err:
        assert err.file == str(path)
        return err.problems
    return []


def dry_run(path: Path):
    return CliRunner().invoke(app, ["sweep", "--sim", "--dry-run", "--matrix", str(path)])


# ---------------------------------------------------------------- supply pressure
def test_a_point_whose_supply_pressure_is_outside_the_interlock_band_is_refused(tmp_path):
    path = write(tmp_path, recess="[0.4826, 9.0]", beta="[0.05, 0.4]")
    found = problems(path)
    # p_s = p_r / beta: 0.4826 / 0.05 = 9.652, 9 / 0.05 = 180, 9 / 0.4 = 22.5 MPa; 0.4826 / 0.4 = 1.2065 is in 0.2..8
    assert sorted(float(re.search(r"supply pressure of ([0-9.]+) MPa", p).group(1)) for p in found) == [
        9.652,
        22.5,
        180,
    ]
    for p in found:
        assert p.startswith("line 4: key 'operating.recess_pressure_mpa': ")
        assert "'operating.pressure_ratio' 0.05 (line 5)" in p or "'operating.pressure_ratio' 0.4 (line 5)" in p
        assert "interlocks band supply_pressure_min_mpa..supply_pressure_max_mpa = 0.2..8 MPa" in p
    low = problems(write(tmp_path, "low.toml", recess="[0.05]"))  # 0.05 / 0.4 = 0.125 MPa below 0.2
    assert len(low) == 1 and "needs a supply pressure of 0.125 MPa" in low[0]
    assert 5.6e6 / 0.7 > 8e6  # the band's edge in floating point (Pa): inside, as the interlock takes it
    assert problems(write(tmp_path, "edge.toml", recess="[5.6]", beta="[0.7]")) == []
    rig = cfg.load_rig()
    unwatched = rig.model_copy(
        update={"interlocks": rig.interlocks.model_copy(update={"check_supply_pressure": False})}
    )
    assert problems(path, unwatched) == []  # no interlock watches it: nothing would suspend the run


def test_dry_run_and_sweep_refuse_the_supply_pressure_before_anything_starts(tmp_path, monkeypatch):
    import orbitrig.cli.sweep as sweep

    started = []

    async def no_run(*args, **kwargs):
        started.append(True)

    monkeypatch.setattr(sweep, "run_sweep", no_run)
    path = write(tmp_path, recess="[9.0]")
    res = dry_run(path)
    assert res.exit_code == 2
    assert f"{path}: line 4: key 'operating.recess_pressure_mpa': 9 MPa" in res.stderr
    assert "needs a supply pressure of 22.5 MPa" in res.stderr
    out = tmp_path / "run"
    res = CliRunner().invoke(app, ["sweep", "--sim", "--matrix", str(path), "--out", str(out)])
    assert res.exit_code == 2 and "22.5 MPa" in res.stderr
    assert not started and not out.exists()


# ---------------------------------------------------------------- Omega/omega = 1
def test_a_ratio_at_omega_over_omega_one_is_refused_and_one_near_it_warned(tmp_path):
    (one,) = problems(write(tmp_path, ratios="ratios = [0.5, 1.0]"))
    assert one.startswith("line 9: key 'orbit.ratios': orbit ratio 1 is within 0.01 of Omega/omega = 1")
    (two,) = problems(write(tmp_path, "two.toml", ratios="ratios = [0.5, 0.995, 1.005]"))
    assert "orbit ratios 0.995, 1.005 are within 0.01 of Omega/omega = 1" in two
    (span,) = problems(write(tmp_path, "span.toml", ratios="ratio_start = 0.5\nratio_stop = 1.0\ncount = 3"))
    assert span.startswith("line 9: key 'orbit.ratio_start': orbit ratio 1 is within 0.01")
    seq = SEQUENTIAL.format(bounds='model = "kcd11"')
    (initial,) = problems(write(tmp_path, "seq.toml", ratios="ratios = [0.3, 0.7, 1.0]", extra=seq))
    assert initial.startswith("line 9: key 'orbit.ratios': orbit ratio 1 is within 0.01")
    # 0.01 away is allowed, with the one warning of the matrix naming every ratio within 0.1
    near = write(tmp_path, "near.toml", ratios="ratios = [0.5, 0.99, 1.01, 1.1]")
    assert problems(near) == []
    (warning,) = cfg.plan_warnings(cfg.load_matrix(near), 50)
    assert warning.startswith("line 9: key 'orbit.ratios': orbit ratios 0.99, 1.01 are within 0.1 of Omega/omega = 1")
    assert warning.endswith(
        "keeps 0.1 away; at 0.99 (50 revolutions), 1.01 (50 revolutions) it turns less than once against the "
        "orbit over the block, so it stays in the averaged phasors and the stated uncertainties u understate "
        "their error (on the simulator 2.6 times at 0.99 with 50 revolutions): more revolutions there, or ratios "
        "farther from 1"
    )


def test_the_runout_left_in_the_average_is_said_per_ratio_with_its_fewest_revolutions(tmp_path):
    """n |1/r - 1| < 1: the spin's tone turns less than once over the block (0.98 at 50: 1.02 turns)."""
    fixed = write(tmp_path, "fixed.toml", ratios="ratios = [0.5, 0.98, 0.985, 1.05]\nrevolutions = [50, 50, 50, 10]")
    (warning,) = cfg.plan_warnings(cfg.load_matrix(fixed), 200)
    assert warning.endswith("away; at 0.985 (50 revolutions), 1.05 (10 revolutions) it turns less than once" + TAIL)
    assert cfg.plan_warnings(cfg.load_matrix(write(tmp_path, "many.toml", ratios="ratios = [0.5, 0.99]")), 102)[
        0
    ].endswith("keeps 0.1 away")  # 102 x 0.0101 = 1.03 turns
    adaptive = write(
        tmp_path, "adaptive.toml", ratios="ratios = [0.5, 0.93]", extra="[averaging]\ntarget_pct = 1.0\n"
    )  # a block may stop at min_revolutions (10): 10 x 0.075 = 0.75 turns
    (warning,) = cfg.plan_warnings(cfg.load_matrix(adaptive), 50)
    assert warning.endswith("away; at 0.93 (10 revolutions) it turns less than once" + TAIL)


TAIL = (
    " against the orbit over the block, so it stays in the averaged phasors and the stated uncertainties u "
    "understate their error (on the simulator 2.6 times at 0.99 with 50 revolutions): more revolutions there, "
    "or ratios farther from 1"
)


def test_the_paper_matrix_runs_with_one_warning_and_the_demo_with_none():
    paper = cfg.load_matrix(cfg.default_matrix_path("paper"))
    cfg.check_matrix_against_rig(paper, cfg.load_rig())  # 0.978 and 1.089 are kept
    assert cfg.plan_warnings(paper, 50) == [
        "line 15: key 'orbit.ratio_start': orbit ratios 0.977778, 1.08889 are within 0.1 of Omega/omega = 1: "
        "the spindle's runout (1x spin) turns only slowly through a block's revolutions there, so averaging "
        "and the runout fit take it out only in part and the coefficients at these ratios (C most) may be "
        "biased; `orbitrig design` keeps 0.1 away"
    ]
    assert cfg.plan_warnings(cfg.load_matrix(cfg.default_matrix_path("demo")), 50) == []  # 0.9 and 1.2: clear


def test_dry_run_and_sweep_start_warn_once_per_matrix(tmp_path, monkeypatch):
    import sys

    import orbitrig.cli.sweep as sweep

    async def no_run(*args, **kwargs):
        print("RUN STARTS", file=sys.stderr)
        return RunOutcome(Outcome.COMPLETED, "nothing run", "t", tmp_path / "run")

    monkeypatch.setattr(sweep, "run_sweep", no_run)
    path = write(tmp_path, spin="[1000.0, 1500.0]", beta="[0.25, 0.4]", ratios="ratios = [0.5, 0.95, 1.05]")
    res = dry_run(path)
    assert res.exit_code == 0, res.output
    assert res.stderr.count("warning:") == 1  # 4 points, 2 ratios near 1: one line
    assert res.stderr.startswith(f"warning: {path}: line 9: key 'orbit.ratios': orbit ratios 0.95, 1.05 are within 0.1")
    assert res.stdout.startswith("matrix t: 4 operating points")
    res = CliRunner().invoke(app, ["sweep", "--sim", "--matrix", str(path), "--out", str(tmp_path / "run")])
    assert res.exit_code == 0, res.output
    warned, started = res.stderr.find("orbit ratios 0.95, 1.05 are within 0.1"), res.stderr.find("RUN STARTS")
    assert res.stderr.count("warning:") == 1 and 0 <= warned < started


def test_a_spin_in_hz_where_rpm_is_meant_is_warned_before_the_run_starts(tmp_path):
    """spin_rpm = [16.7] (the operator's 1000 rpm written as 16.7 Hz) is a legal speed, and would
    run for most of an hour: the dry run and the sweep's start say it, naming the line and key."""
    path = write(tmp_path, spin="[16.7, 1000.0, 25.0]")
    (warning,) = cfg.plan_warnings(cfg.load_matrix(path), 50)
    assert warning == (
        "line 3: key 'operating.spin_rpm': spin 16.7, 25 rpm are below 60 rpm (one turn a second): Hz written "
        "where rpm is meant? 16.7 Hz is 1002 rpm; every speed in a matrix is in rpm, and so slow an orbit makes "
        "each block last minutes (`orbitrig sweep --dry-run` says how long)"
    )
    res = dry_run(path)
    assert res.exit_code == 0, res.output
    assert res.stderr.startswith(f"warning: {path}: {warning}")
    assert cfg.plan_warnings(cfg.load_matrix(write(tmp_path, "fine.toml", spin="[60.0]")), 50) == []


# ---------------------------------------------------------------- sequential
S7 = dict(
    ratios="ratios = [0.3, 0.7]",
    directions='["forward"]',
    extra="revolutions = [10, 10]\n" + SEQUENTIAL.format(bounds='model = "kcd11"'),
)


def test_a_sequential_initial_list_that_cannot_identify_its_model_is_refused(tmp_path):
    path = write(tmp_path, **S7)
    text = path.read_text().splitlines()
    assert text[15] == 'model = "kcd11"' and text[8] == "ratios = [0.3, 0.7]"
    (p,) = problems(path)
    assert p.startswith(
        "line 9: key 'orbit.ratios': the initial list of a sequential point (ratios 0.3, 0.7, directions forward) "
        "cannot identify kcd11 ('sequential.model', line 16) at 1000 rpm"
    )
    assert "too few orbit frequencies: 11 coefficients need at least 3 orbit frequencies" in p
    default = dict(S7, extra=S7["extra"].replace('model = "kcd11"', ""))
    (q,) = problems(write(tmp_path, "default.toml", **default))
    assert "cannot identify kcd11 (the first [[models]], line 18)" in q
    both = dict(S7, directions='["forward", "backward"]')
    assert problems(write(tmp_path, "both.toml", **both)) == []  # both directions identify kcd11
    res = dry_run(path)
    assert res.exit_code == 2 and "cannot identify kcd11" in res.stderr


def test_a_sequential_reference_list_that_cannot_identify_its_model_is_refused(tmp_path):
    """match_ratios of one ratio cannot identify kcd11 (8 real equations for 11 coefficients):
    refused before the run, at its key's line, instead of failing the point after its initial
    list (reduction.sequential.reference_errors); two ratios in both directions do."""
    bounds = 'model = "kcd11"\nmatch_ratios = [0.5]'
    match = SEQUENTIAL.format(bounds=bounds).replace("target_pct = 0.5\n", "")
    path = write(tmp_path, extra="revolutions = [10, 10, 10]\n" + match)
    assert path.read_text().splitlines()[15] == "match_ratios = [0.5]"  # line 16
    (p,) = problems(path)
    assert p.startswith(
        "line 16: key 'sequential.match_ratios': the reference list (ratios 0.5, directions forward, backward) "
        "cannot identify kcd11 at 1000 rpm, so no standard error to match follows from it: "
    ), p
    assert "too few orbit frequencies" in p and p.endswith("or 'sequential.target_pct'")
    two = write(tmp_path, "two.toml", extra="revolutions = [10, 10, 10]\n" + match.replace("[0.5]", "[0.3, 0.6]"))
    assert problems(two) == []


def test_sequential_candidate_problems_name_the_line_of_their_key(tmp_path):
    bounds = 'candidates = [0.2, 0.95, 0.75]\nmodel = "kcd11"'
    path = write(tmp_path, extra="revolutions = [10, 10, 10]\n" + SEQUENTIAL.format(bounds=bounds))
    assert path.read_text().splitlines()[15].startswith("candidates = ")  # line 16; [sequential] on 13
    assert problems(path) == [
        "line 16: key 'sequential.candidates': ratio 0.95 is within 0.1 of Omega/omega = 1 "
        "(the orbit cannot be told from the spindle's runout)"
    ]
    match = SEQUENTIAL.format(bounds="cap_s_note = 0").replace("target_pct = 0.5\n", "")
    match = match.replace("cap_s_note = 0", "match_ratios = [0.3, 1.8]")
    path = write(tmp_path, "match.toml", extra="revolutions = [10, 10, 10]\n" + match)
    assert path.read_text().splitlines()[14].startswith("match_ratios = ")  # line 15
    assert problems(path) == [
        "line 15: key 'sequential.match_ratios': ratio 1.8 is above the rig's drives.max_ratio = 1.5",
    ]


def test_a_real_sweep_stores_the_warning_in_its_run_log(tmp_path):
    """The warning is part of the run's record (run.log), not only of the terminal it ran on."""
    from support.cli_helpers import orbitrig

    path = write(tmp_path, ratios="ratios = [0.3, 0.6, 0.95]\nrevolutions = [8, 8, 8]", directions='["forward"]')
    out = tmp_path / "run"
    args = ("sweep", "--sim", "--matrix", str(path), "--out", str(out), "--speedup", "20", "--no-draw-figures")
    done = orbitrig(*args, timeout=200, columns=None)
    assert done.returncode == 0, done.stderr
    assert done.stderr.count("orbit ratio 0.95 is within 0.1 of Omega/omega = 1") == 1
    logged = [ln for ln in (out / "run.log").read_text().splitlines() if "within 0.1 of Omega/omega = 1" in ln]
    assert len(logged) == 1 and f"warning: {path}: line 9: key 'orbit.ratios'" in logged[0]


# ---------------------------------------------------------------- runout subtraction
RUNOUT = "\n[runout]\nspin_rpm = 100.0\nrevolutions = 100\n" + "".join(
    f"\n[runout.{p}]\nh1_um = [2.0, 0.0]\nh2_um = [1.0, 0.0]\n" for p in ("x_a", "y_a", "x_b", "y_b")
)


def _rig_with_runout(subtract: bool = True, runout: str = RUNOUT):
    """The shipped rig whose active record holds ``runout`` (the record's text given, as a run's copy)."""
    shipped = cfg.load_rig()
    text = shipped.text if subtract else "subtract_runout = false\n" + shipped.text
    return cfg.rig_from_text(text, shipped.file, record_text=shipped.record_text + runout)


def test_blocks_too_short_for_the_runout_fit_are_refused_while_the_runout_is_subtracted(tmp_path):
    """The runout's spin phase is fitted from a block's revolutions (reduction.runout, at least 3):
    a block of 2 kept the runout whole (on the simulator, blocks of 2: |dZ|/|Z| 13 % with 2 µm of runout, 0.8 % with 0.1 µm)
    while docs/calibration.md says every block loses it. Refused before anything starts, naming the
    line, the ratios and their counts; without runout in the record, or not subtracted, it runs."""
    short = write(tmp_path, "short.toml", ratios="ratios = [0.3, 0.5, 0.7]\nrevolutions = [50, 2, 2]")
    (p,) = problems(short, _rig_with_runout())
    assert p == (
        "line 10: key 'orbit.revolutions': 2 revolutions at orbit ratios 0.5, 0.7: the active calibration "
        "record's runout is taken out of a block by a fit over its revolutions, which needs at least 3; "
        "give at least 3, or set subtract_runout = false in the rig configuration"
    ), p
    assert problems(short) == []  # the shipped record holds no runout
    assert problems(short, _rig_with_runout(subtract=False)) == []
    assert (
        problems(write(tmp_path, "ok.toml", ratios="ratios = [0.3, 0.5]\nrevolutions = [3, 50]"), _rig_with_runout())
        == []
    )


def test_a_runout_without_its_recorded_uncertainty_is_said_once_among_the_warnings(tmp_path):
    """A record written before the runout step recorded h1_u_um, h2_u_um keeps the old rule (no
    runout term in U): one warning line names the record and the step to run again; a record with
    them, or a runout not subtracted, gives none."""
    matrix = cfg.load_matrix(write(tmp_path, "ok.toml", ratios="ratios = [0.3, 0.5]"))
    rig = _rig_with_runout()
    said = [line for line in cfg.warning_lines(matrix, 50, rig) if "no recorded uncertainty" in line]
    assert said == [
        f"warning: {rig.file}: the active calibration record {rig.calibration_record}'s runout has no recorded "
        "uncertainty ([runout.<probe>] h1_u_um, h2_u_um: written before the runout step recorded them): the "
        "runout is taken out, but the coefficients' U holds no term for its error; `orbitrig calibrate runout` "
        "again to have it counted"
    ]
    one = _rig_with_runout(runout=RUNOUT.replace("revolutions = 100", "revolutions = 1"))
    (said,) = [line for line in cfg.warning_lines(matrix, 50, one) if "no recorded uncertainty" in line]
    assert "h1_u_um, h2_u_um: a slow roll of one revolution: no scatter to take it from)" in said, said
    assert said.endswith("`orbitrig calibrate runout` again over more than one revolution to have it counted"), said
    with_u = RUNOUT.replace("h2_um = [1.0, 0.0]\n", "h2_um = [1.0, 0.0]\nh1_u_um = 0.004\nh2_u_um = 0.003\n")
    shipped = cfg.load_rig()
    measured = cfg.rig_from_text(shipped.text, shipped.file, record_text=shipped.record_text + with_u)
    assert measured.record.runout.uncertainties(("x_a", "y_b")).ravel() == pytest.approx([4e-9, 3e-9] * 2)
    assert not [line for line in cfg.warning_lines(matrix, 50, measured) if "no recorded uncertainty" in line]
    assert not [
        line for line in cfg.warning_lines(matrix, 50, _rig_with_runout(subtract=False)) if "uncertainty" in line
    ]


def test_too_fast_an_orbit_is_said_alike_in_the_orbit_list_and_a_sequential_list(tmp_path):
    """A ratio whose orbit at the spin is faster than [drives] max_orbit_rpm is told with the spin
    it is at, in the matrix's [orbit] list and in a sequential point's candidates alike."""
    bounds = 'candidates = [0.3, 0.6, 1.4]\nmodel = "kcd11"'
    extra = "revolutions = [10, 10, 10]\n" + SEQUENTIAL.format(bounds=bounds)
    path = write(tmp_path, spin="[2000.0]", ratios="ratios = [0.3, 0.5, 1.3]", extra=extra)
    found = problems(path)
    assert found == [
        "line 9: key 'orbit': ratio 1.3 at 2000 rpm gives 2600 rpm orbit, above the rig's drives.max_orbit_rpm = 2500",
        "line 16: key 'sequential.candidates': ratio 1.4 at 2000 rpm gives 2800 rpm orbit, "
        "above the rig's drives.max_orbit_rpm = 2500",
    ], found
