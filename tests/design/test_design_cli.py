"""`orbitrig design`: the JSON object, the proposal's promises, the saved design, operator errors."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import tomllib

import numpy as np
import pytest

from reduction.frequency_list import near_one
from rigunits import RPM, display_unit, in_hz
from support.cli_helpers import orbitrig, orbitrig_here
from support.paths import ROOT
from support.sweep_helpers import demo_text

KEYS = {
    "model",
    "freq_dep",
    "coefficients",
    "units",
    "spin_rpm",
    "orbit_radius_m",
    "directions",
    "noise",
    "prior",
    "allowed",
    "target_pct",
    "candidate",
    "proposal",
    "match_candidate",
    "per_direction",
    "model_test",
    "warnings",
}
LIST_KEYS = {
    "ratios",
    "orbit_hz",
    "directions",
    "whirl",
    "revolutions",
    "identifiable",
    "std_errors",
    "relative_pct",
    "worst_relative_pct",
    "rig_time_s",
}


def design(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    """`orbitrig design ARGS...` as a script piping its output runs it (in this process: 80 columns)."""
    p = orbitrig_here("design", *args, columns=80)
    if check:
        assert p.returncode == 0, p.stderr
    return p


def test_json_keys_and_numbers():
    obj = json.loads(design("--model", "kcd11", "--spin", "1000", "--json").stdout)
    assert set(obj) == KEYS
    assert set(obj["candidate"]) == LIST_KEYS | {"source", "warnings"}
    assert set(obj["proposal"]) == LIST_KEYS | {"warnings"}
    names = obj["coefficients"]
    assert len(names) == 11 and names[-1] == "Dyy"
    for lst in (obj["candidate"], obj["proposal"]):
        assert list(lst["std_errors"]) == names
        assert lst["worst_relative_pct"] == pytest.approx(max(lst["relative_pct"].values()))
        assert lst["orbit_hz"] == pytest.approx(np.array(lst["ratios"]) * 1000 / 60, rel=1e-12)
        assert lst["orbit_hz"] == [in_hz(r * (1000 * RPM)) for r in lst["ratios"]]  # as the run plans them
    # no target: the same number of frequencies, a lower worst relative error, inside the band, off 1
    c, p = obj["candidate"], obj["proposal"]
    assert len(p["ratios"]) == len(c["ratios"]) == 10
    assert p["worst_relative_pct"] < c["worst_relative_pct"]
    assert all(0.1 <= r <= 1.5 and abs(r - 1) >= 0.1 - 1e-9 for r in p["ratios"])
    assert any("0.977778" in w for w in c["warnings"])  # the paper's list has a ratio next to 1
    assert obj["noise"]["u_revolution"] == {"x": 1e-7, "y": 1e-7, "fx": 20.0, "fy": 20.0}


def test_a_ratio_at_the_keep_away_distance_is_not_warned_as_within_it():
    """0.9 and 1.1 are 0.1 from 1 (1 - 0.9 < 0.1 in floating point): the candidate is not warned
    for them, as the proposal may use them and a matrix's plan is not warned; 0.95 is within."""
    obj = json.loads(design("--model", "kc8", "--spin", "1000", "--ratios", "0.5,0.9,0.95,1.1", "--json").stdout)
    within = [w for w in obj["candidate"]["warnings"] if "of Omega/omega = 1" in w]
    assert len(within) == 1 and within[0].startswith("ratio 0.95 is within 0.1 of Omega/omega = 1")
    assert near_one([0.9, 1.1, -0.9, 0.95, -1.05, 0.5, 0.99], 0.1).tolist() == [0, 0, 0, 1, 1, 0, 1]


def test_target_is_reached_in_less_rig_time():
    obj = json.loads(
        design(
            "--model", "kc8", "--spin", "1000", "--matrix", "demo", "--target", "0.2", "--no-model-test", "--json"
        ).stdout
    )
    c, p = obj["candidate"], obj["proposal"]
    assert c["ratios"] == [0.3, 0.5, 0.7, 0.9, 1.2] and obj["target_pct"] == 0.2
    assert p["reaches_target"] is True and p["worst_relative_pct"] <= 0.2 * (1 + 1e-9)
    assert len(p["revolutions"]) == len(p["ratios"]) == len(p["target_pct"])  # one count, one target per ratio
    # the candidate list with just enough revolutions to reach the target takes longer
    n_c = int(np.ceil(50 * (c["worst_relative_pct"] / 0.2) ** 2))
    c_at_target = json.loads(
        design("--model", "kc8", "--spin", "1000", "--matrix", "demo", "--revolutions", str(n_c), "--json").stdout
    )["candidate"]
    assert c_at_target["worst_relative_pct"] <= 0.2 * (1 + 1e-9)
    assert p["rig_time_s"] < c_at_target["rig_time_s"]
    # variance ~ 1/n: the predicted errors scale with the revolutions stated (kc8 goes to one ratio)
    assert len(p["ratios"]) == 1
    halved = json.loads(
        design(
            "--model",
            "kc8",
            "--spin",
            "1000",
            "--ratios",
            ",".join(map(str, p["ratios"])),
            "--revolutions",
            str(4 * p["revolutions"][0]),
            "--radius",
            "5.76",
            "--json",
        ).stdout
    )["candidate"]
    assert halved["worst_relative_pct"] == pytest.approx(p["worst_relative_pct"] / 2, rel=1e-6)


def test_match_gives_every_coefficient_the_candidates_error_in_half_the_time():
    """--match --no-model-test against the paper's list (kcd11, 15 N / 20 nm per revolution,
    2.4 um orbit): no coefficient's predicted standard error grows, the rig time halves (hand
    check: the paper's 20 blocks take 115 s of orbits + 41 s of settling + 4 s of ramps)."""
    args = ("--model", "kcd11", "--spin", "1000", "--force-noise", "15", "--probe-noise", "20", "--radius", "2.4")
    obj = json.loads(design(*args, "--match", "--no-model-test", "--json").stdout)
    assert obj["model_test"] is None
    c, p = obj["candidate"], obj["proposal"]
    assert obj["match_candidate"] is True and c["rig_time_s"] == pytest.approx(162.9, abs=0.5)
    for name in obj["coefficients"]:
        assert p["std_errors"][name] <= c["std_errors"][name] * (1 + 1e-9)
    assert p["rig_time_s"] < 0.52 * c["rig_time_s"]
    assert all(n >= 10 for n in p["revolutions"]) and all(0 < t < 100 for t in p["target_pct"])
    bad = design(*args, "--match", "--target", "1", check=False)
    assert bad.returncode == 2 and "not both" in bad.stderr


def test_match_keeps_the_model_test_by_default():
    """--match (model test on, the paper matrix's models): K = 5 (kcd11 power:1: Omega^0..3 in
    the real part, plus one), one ratio at least in each fifth of 0.2 .. 1.2, every kcd11 and
    kcd11 power:1 coefficient at most the paper list's error; it costs rig time (a list for the
    constant model alone takes half, about 0.65 here), still less than the paper's."""
    args = ("--model", "kcd11", "--spin", "1000", "--force-noise", "15", "--probe-noise", "20", "--radius", "2.4")
    obj = json.loads(design(*args, "--matrix", "paper", "--match", "--json").stdout)
    c, p, mt = obj["candidate"], obj["proposal"], obj["model_test"]
    assert (mt["model"], mt["freq_dep"], mt["frequencies"], mt["kept"]) == ("kcd11", "power:1", 5, True)
    assert len(p["ratios"]) >= 5 and "distinct orbit frequencies" in mt["reason"]
    for a, b in zip(mt["slices"][:-1], mt["slices"][1:]):
        assert any(a - 1e-9 <= r <= b + 1e-9 for r in p["ratios"])
    for name in obj["coefficients"]:
        assert p["std_errors"][name] <= c["std_errors"][name] * (1 + 1e-6)
    assert p["test_worst_vs_reference"] <= 1 + 1e-6
    assert 0.5 * c["rig_time_s"] < p["rig_time_s"] < 0.8 * c["rig_time_s"]
    text = design(*args, "--matrix", "paper", "--match").stdout
    assert "model test kept: yes: the adequacy test of kcd11 power:1" in text


def test_a_candidate_list_that_cannot_identify_the_tested_model_exits_2_naming_it():
    """--match keeps the adequacy test of kcd11 poly:1 against the candidate list: five ratios
    within 0.0004 of each other are five distinct frequencies (K = 5), but no list can show
    the Omega terms there: the refusal names the list, the coefficients and the way out, no
    proposal is printed (the list identifies the constant model; without the test it is matched)."""
    close = ("--model", "kcd11", "--spin", "1000", "--ratios", "0.5,0.5001,0.5002,0.5003,0.5004", "--match")
    p = design(*close, check=False)
    said = " ".join(p.stderr.split())
    assert p.returncode == 2 and p.stdout == "" and "Traceback" not in p.stderr and "Warning" not in p.stderr
    assert said.startswith(
        "orbitrig design: error: the model test: the reference list (ratios 0.5, 0.5001, 0.5002, 0.5003, 0.5004) "
        "cannot identify kcd11 poly:1: Kxx, Kxy, Kyx, Kyy, Kxx_1, Kxy_1, Kyx_1, Kyy_1, Dxx, Dxy, Dyy, Dxx_1, "
        "Dxy_1, Dyy_1 undetermined (the forces do not change when the coefficients move along Kxx + "
    ), said
    assert said.endswith("may separate them (or give --no-model-test)")
    obj = json.loads(design(*close, "--no-model-test", "--json").stdout)
    assert obj["candidate"]["identifiable"] and obj["proposal"]["reaches_target"]


def test_a_narrow_candidate_the_grid_cannot_spread_over_names_the_model_test_not_identifiability():
    """Five ratios 0.01 apart identify kcd11 and kcd11 poly:1, but the model test's five slices of
    0.3 .. 0.34 are 0.008 wide and the proposal's 0.05 grid has only 0.3 there: no proposal
    keeps the test. The refusal says so and what to do (not "cannot identify the model");
    without the test the list is matched."""
    narrow = ("--model", "kcd11", "--spin", "1500", "--ratios", "0.3,0.31,0.32,0.33,0.34", "--match")
    p = design(*narrow, check=False)
    said = " ".join(p.stderr.split())
    assert p.returncode == 2 and p.stdout == "" and "Traceback" not in p.stderr
    assert "cannot identify" not in said
    assert said.startswith(
        "orbitrig design: error: the model test cannot be kept: the adequacy test of kcd11 poly:1 needs 5 distinct "
        "ratios, one at least in each of 5 equal slices of the candidate's span, and no list of the allowed "
        "ratios (the 0.05 grid of the drives' band) has that: the 5 slices of 0.3 .. 0.34 are 0.008 wide, and "
        "of the ratios a list may use only 0.3 in 0.3 .. 0.34 (none in 0.308 .. 0.316, 0.316 .. 0.324, "
        "0.324 .. 0.332, 0.332 .. 0.34)."
    ), said
    assert said.endswith(
        "give candidate ratios spread wider (slices of at least 0.05: a span of 0.25 or more), or --no-model-test"
    )
    obj = json.loads(design(*narrow, "--no-model-test", "--json").stdout)
    assert obj["candidate"]["identifiable"] and obj["proposal"]["reaches_target"]


def test_match_of_a_candidate_that_cannot_identify_the_model_names_why():
    """--match of a candidate that cannot identify kcd11 - one ratio (8 real equations, 11
    coefficients), or two 1e-9 apart - has nothing to match, said with the cause."""
    p = design("--model", "kcd11", "--spin", "1000", "--ratios", "0.5", "--match", check=False)
    assert p.returncode == 2 and p.stdout == ""
    assert " ".join(p.stderr.split()) == (
        "orbitrig design: error: --match: there is nothing to match: the list (ratios 0.5) has 8 real equations, "
        "too few for 11 coefficients"
    )
    # condition number ~1e9: identify refuses such data (tests/design/test_rank_rule.py); so does design
    near = ("--model", "kcd11", "--spin", "1000", "--ratios", "0.5,0.500000001")
    assert json.loads(design(*near, "--json").stdout)["candidate"]["identifiable"] is False
    p = design(*near, "--match", check=False)
    assert p.returncode == 2 and p.stdout == ""
    assert " ".join(p.stderr.split()).startswith(
        "orbitrig design: error: --match: there is nothing to match: the list (ratios 0.5, 0.500000001) cannot identify "
        "kcd11 none: Kxx, Kxy, Kyx, Kyy, Dxx, Dxy, Dyy undetermined (the forces do not change when the "
        "coefficients move along Kxx + 0.0003648*Dxx; Kxy + Kyx + 0.0003648*Dxy; Kyy + 0.0003648*Dyy)"
    )


def test_text_output_and_saved_design(tmp_path):
    rig = tmp_path / "config" / "rig.toml"
    rig.parent.mkdir()
    rig.write_text((ROOT / "config" / "rig.toml").read_text())
    p = design("--model", "kc8", "--spin", "1000", "--target", "0.2", "--save", "kc8fast", "--config", str(rig))
    assert "proposal :" in p.stdout and "target 0.2 %: reached" in p.stdout
    said = " ".join(p.stdout.split())  # the table's rel % is of the matrix's size, which it says
    assert said.endswith(
        "rel % = SE relative to the size of the coefficient's matrix (RMS of the prior's K, C or D "
        "diagonal), not to the coefficient itself: a small cross term's rel % is of its diagonal"
    )
    assert re.search(r"orbit radius [0-9.]+ \u00b5m, directions", p.stdout) and " um" not in p.stdout
    comment = (tmp_path / "config" / "designs" / "kc8fast.toml").read_text(encoding="utf-8").splitlines()[1]
    assert re.search(r"; orbit radius [0-9.]+ \u00b5m$", comment), comment
    saved = tomllib.loads((tmp_path / "config" / "designs" / "kc8fast.toml").read_text())
    assert saved["model"] == "kc8" and len(saved["ratios"]) == len(saved["revolutions"]) == len(saved["target_pct"])
    header = (tmp_path / "config" / "designs" / "kc8fast.toml").read_text().splitlines()[0]
    assert header == "# orbitrig design --model kc8 --freq-dep none --spin 1000 --target 0.2"
    one = design(
        "--model", "kc8", "--spin", "1000", "--match", "--no-model-test", "--save", "kc8one", "--config", str(rig)
    )
    said = " ".join(one.stdout.split())  # folded to 80 columns: piped
    assert "warning (proposal): one ratio: a matrix needs 2 at least, so no sweep runs this list" in said
    header = (tmp_path / "config" / "designs" / "kc8one.toml").read_text().splitlines()[0]
    assert header == "# orbitrig design --model kc8 --freq-dep none --spin 1000 --match --no-model-test"  # as made


def test_the_text_table_reads_k_c_d_in_the_units_of_identify_and_reduce():
    """The terminal's table gives prior and standard errors in MN/m, kN s/m and kg (rigunits.display_unit,
    as identify, reduce and the sweep's closing table; it printed 3.8e+07 N/m); the JSON stays SI."""
    text = design("--model", "kcd11", "--spin", "1000").stdout
    obj = json.loads(design("--model", "kcd11", "--spin", "1000", "--json").stdout)
    rows = {line.split()[0]: line for line in text.splitlines() if re.match(r"[KCD](xx|xy|yx|yy) ", line)}
    assert len(rows) == 11
    for name, line in rows.items():
        unit, scale = display_unit(name)
        cells = line[len(name) :].split()
        assert " ".join(cells[: len(unit.split())]) == unit, line
        prior, cand_se = (float(c) for c in cells[len(unit.split()) : len(unit.split()) + 2])
        assert prior == pytest.approx(obj["prior"]["coefficients"][name] * scale, rel=1e-3), line
        assert cand_se == pytest.approx(obj["candidate"]["std_errors"][name] * scale, rel=1e-3), line
    assert rows["Kxx"].split()[1:3] == ["MN/m", "38"] and rows["Cxx"].split()[1:4] == ["kN", "s/m", "100"]
    assert obj["units"]["Kxx"] == "N/m" and obj["prior"]["coefficients"]["Kxx"] == pytest.approx(3.8e7)


def test_an_empty_save_name_exits_2_and_writes_nothing(tmp_path):
    """`--save ""` (an unset shell variable) wrote nothing and exited 0."""
    rig = tmp_path / "config" / "rig.toml"
    rig.parent.mkdir()
    rig.write_text((ROOT / "config" / "rig.toml").read_text())
    p = design(
        "--model",
        "kc8",
        "--spin",
        "1000",
        "--match",
        "--no-model-test",
        "--save",
        "",
        "--config",
        str(rig),
        check=False,
    )
    assert p.returncode == 2 and p.stderr == "orbitrig design: error: --save '': use letters, digits, - and _ only\n"
    assert not (tmp_path / "config" / "designs").exists() or not list((tmp_path / "config" / "designs").iterdir())


@pytest.mark.parametrize(
    "args, message",
    [
        (("--model", "kcd11", "--spin", "3000"), "above the rig's drives.max_spin_rpm = 2500"),
        (("--model", "kcd11", "--spin", "1000", "--ratios", "0.2,x"), "give numbers"),
        (("--model", "kcd13", "--spin", "1000"), "unknown model 'kcd13'"),
        (("--model", "kcd11", "--spin", "1000", "--ratios", "0.5", "--matrix", "demo"), "not both"),
        (("--model", "kcd11", "--spin", "1000", "--ratios", "0.3,inf,0.5"), "give distinct finite ratios > 0"),
        (
            ("--model", "kcd11", "--spin", "1000", "--revolutions", "-5"),
            "--revolutions -5: at least 2 revolutions per block",
        ),
        (
            ("--model", "kcd11", "--spin", "1000", "--radius", "nan"),
            "--radius nan \u00b5m: the orbit radius must be > 0 and below",
        ),
        (("--model", "kcd11", "--spin", "1000", "--radius", "60"), "below the bearing's clearance (60 \u00b5m"),
        (("--model", "kcd11", "--spin", "1000", "--target", "-1"), "--target -1: a relative standard error in percent"),
        (("--model", "kcd11", "--spin", "1000", "--per-direction"), "--per-direction: give --match or --target"),
        (
            ("--model", "kcd11", "--spin", "1000", "--keep-away", "nan"),
            "--keep-away nan: a distance from Omega/omega = 1",
        ),
        (
            ("--model", "kcd11", "--spin", "1000", "--force-noise", "nan"),
            "--force-noise nan: a per-revolution noise in N",
        ),
        (
            ("--model", "kcd11", "--spin", "1000", "--probe-noise", "-3"),
            "--probe-noise -3: a per-revolution noise in nm",
        ),
    ],
)
def test_operator_mistakes_exit_2(args, message):
    p = design(*args, check=False)
    assert p.returncode == 2 and message in p.stderr and "Traceback" not in p.stderr and p.stdout == ""


def test_noise_and_prior_from_a_simulated_run(tmp_path):
    matrix = tmp_path / "small.toml"
    matrix.write_text(demo_text("small", 10))
    run = tmp_path / "run"
    p = orbitrig(
        "sweep", "--sim", "--matrix", str(matrix), "--out", str(run), "--speedup", "40", timeout=300, columns=None
    )
    assert p.returncode == 0, p.stderr
    obj = json.loads(design("--model", "kcd11", "--spin", "1000", "--noise-from", str(run), "--json").stdout)
    noise = obj["noise"]
    assert noise["ratios"] == [0.3, 0.5, 0.7, 0.9, 1.2] and "measured: run" in noise["source"]
    assert all(5.0 < u < 60.0 for u in noise["u_revolution"]["fx"])  # the simulator's force noise per revolution
    assert obj["prior"]["source"].startswith("identified: run")
    assert obj["prior"]["coefficients"]["Kxx"] > 1e7
    assert 1e-6 < obj["orbit_radius_m"] < 1e-5  # the run's measured orbit (demo: eps_d 0.096)
    # kc8 has no D: the run cannot vouch that moving the frequencies leaves its K alone
    kc8 = json.loads(
        design(
            "--model", "kc8", "--spin", "1000", "--noise-from", str(run), "--match", "--no-model-test", "--json"
        ).stdout
    )
    assert kc8["proposal"]["ratios"] == [1.5] and len(kc8["warnings"]) == 1
    assert "kc8 leaves out terms of kcd12" in kc8["warnings"][0] or "terms kc8 leaves out" in kc8["warnings"][0]
    assert " MN/m " in kc8["warnings"][0]  # how far K could move, in the unit the table beside it reads
    copy = tmp_path / "sent to a colleague.h5"  # the run file itself, under any name: the same noise and prior
    shutil.copyfile(run / "run.h5", copy)
    from_file = json.loads(design("--model", "kcd11", "--spin", "1000", "--noise-from", str(copy), "--json").stdout)
    assert (from_file["noise"]["u_revolution"], from_file["prior"]["coefficients"]) == (
        noise["u_revolution"],
        obj["prior"]["coefficients"],
    )
    p = design("--model", "kcd11", "--spin", "1000", "--noise-from", str(tmp_path), check=False)
    assert p.returncode == 2 and "Traceback" not in p.stderr


def test_a_matrix_by_name_comes_from_the_labs_folder(tmp_path):
    """`design --config LAB/rig.toml --matrix NAME` reads LAB/matrices/NAME.toml, as the sweep does."""
    assert orbitrig_here("init", str(tmp_path / "lab")).returncode == 0
    text = demo_text("mine")
    text = re.sub(r"ratios = \[[^\]]*\]", "ratios = [0.25, 0.55, 1.35]", text)
    (tmp_path / "lab/matrices/mine.toml").write_text(text)
    p = design(
        "--model", "kc8", "--spin", "1000", "--config", str(tmp_path / "lab/rig.toml"), "--matrix", "mine", "--json"
    )
    candidate = json.loads(p.stdout)["candidate"]
    assert candidate["source"] == "matrix mine" and candidate["ratios"] == [0.25, 0.55, 1.35]
