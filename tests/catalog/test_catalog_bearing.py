"""Which bearing a run tested, on real sweeps: a `sweep --sim` run of the default scenario, one
of `--sim-config paper` (the same rig: both record config/sim.toml, its name and text) and one of
`--sim-config compressible` at the same operating point. The catalog records the
scenario (name, SHA-256 of its text, seed) and the rig's journal and clearance; the compressible
run is no repeat of the other two, in SQLite and in PostgreSQL; a catalog of the earlier table
gains the columns with its rows kept."""

from __future__ import annotations

import hashlib
import json
import math

import pytest
from sqlalchemy import func, select

from orbitrig.catalog.bearing import SIM_DEFAULT_SEED, bearing_label
from orbitrig.catalog.compare import repeat_groups, repeatability
from orbitrig.catalog.rows import run_rows
from orbitrig.catalog.schema import fits
from orbitrig.catalog.store import Catalog
from orbitrig.store.reader import read_run
from rigunits import without_noise
from sim.config import SimConfig
from support.catalog_earlier import NEW, write_earlier_catalog
from support.cli_helpers import orbitrig
from support.paths import ROOT

ONE_FIT = "lms = piezo and model = kcd11 and freq_dep = none"
PAPER = ROOT / "config" / "sim.toml"  # the default scenario (sim.config.SimConfig())


def _sweep(out, *extra: str) -> None:
    p = orbitrig("sweep", "--sim", "--out", str(out), *extra, cwd=out.parent, timeout=300)
    assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """{name: run directory}: paper-1 (the default scenario), paper-2 (`--sim-config paper`), compressible."""
    base = tmp_path_factory.mktemp("bearings")
    out = {name: base / name for name in ("paper-1", "paper-2", "compressible")}
    _sweep(out["paper-1"])
    _sweep(out["paper-2"], "--sim-config", "paper")
    _sweep(out["compressible"], "--sim-config", "compressible")
    return out


def test_computed_numbers_are_kept_without_float_noise():
    """The catalog's lengths and planned frequencies as every file keeps them (rigunits.without_noise):
    the float noise of a unit conversion or a product goes, a value with no short decimal stays."""
    assert (without_noise(60 * 1e-6), without_noise(19.05 * 1e-3)) == (6e-05, 0.01905)
    spin = 1000 * 2 * math.pi / 60  # rad/s
    orbit_hz = [ratio * spin / (2 * math.pi) for ratio in (0.3, 0.5, 1.2)]
    assert (60 * 1e-6, orbit_hz) == (5.9999999999999995e-05, [4.999999999999999, 8.333333333333332, 19.999999999999996])
    assert [without_noise(f) for f in orbit_hz] == [5.0, 8.333333333333332, 20.0]


def test_a_rigs_bearing_is_named_by_its_clearance_in_micrometres():
    """A run of the rig (no scenario) is named by its rig id and the stored clearance (m), shown as
    the rest of the CLI shows a length: the micro sign, never an ASCII 'um'."""
    assert bearing_label({"rig_id": "SAC-DS-1", "bearing_clearance": 6e-05}) == "SAC-DS-1 c = 60 \u00b5m"
    assert bearing_label({"rig_id": "SAC-DS-1", "bearing_clearance": 60 * 1e-6}) == "SAC-DS-1 c = 60 \u00b5m"
    assert bearing_label({"rig_id": "", "bearing_clearance": None}) == "rig"


def test_the_default_seed_is_the_simulators():
    assert SIM_DEFAULT_SEED == SimConfig().seed


def test_rows_name_the_scenario_and_the_bearing(runs):
    scenario_file = ROOT / "config" / "sim" / "compressible.toml"
    paper, named = (run_rows(read_run(runs[name]))[0] for name in ("paper-1", "paper-2"))
    compressible = run_rows(read_run(runs["compressible"]))[0]
    assert paper["sim_scenario"] == named["sim_scenario"] == str(PAPER)  # the default is the paper's rig, by name
    assert (
        paper["sim_scenario_sha256"] == named["sim_scenario_sha256"] == hashlib.sha256(PAPER.read_bytes()).hexdigest()
    )
    assert compressible["sim_scenario"] == str(scenario_file)
    assert compressible["sim_scenario_sha256"] == hashlib.sha256(scenario_file.read_bytes()).hexdigest()
    assert paper["sim_seed"] == compressible["sim_seed"] == 1
    for row in (paper, compressible):  # config/rig.toml [bearing]: radius 19.05 mm, clearance 60 um
        assert (row["bearing_radius"], row["bearing_clearance"]) == (0.01905, 6e-05)
        # the demo's ratios 0.3 ... 1.2 of 1000 rpm, as written (not 4.999999999999999 Hz)
        planned = json.loads(row["orbit_hz"])
        assert planned == pytest.approx([5.0, 25 / 3, 35 / 3, 15.0, 20.0], rel=1e-15)
        assert [planned[i] for i in (0, 3, 4)] == [5.0, 15.0, 20.0]


def test_runs_of_another_scenario_are_no_repeats(catalog, runs):
    for run in runs.values():
        catalog.add(run_rows(read_run(run)))
    rows = catalog.rows(ONE_FIT)
    assert len(rows) == 3 and {r["sim_seed"] for r in rows} == {1}
    groups = repeat_groups(rows)
    assert [len(g) for g in groups] == [2]
    assert {r["sim_scenario"] for r in groups[0]} == {str(PAPER)}  # the default scenario and `paper`: one bearing
    rep = repeatability(rows, "Cxx")
    assert (rep.groups, rep.dof) == (1, 1)
    # the compressible bearing's damping is about half the paper's: as one group it fails any test
    cxx = {r["sim_scenario"] == str(PAPER): r["Cxx"] for r in rows}
    assert cxx[False] < 0.7 * cxx[True]
    mixed = repeatability([{**r, "sim_scenario": "", "sim_scenario_sha256": ""} for r in rows], "Cxx")
    assert (mixed.groups, mixed.dof) == (1, 2) and mixed.p_value < 1e-6
    assert (
        len(catalog.rows(f"{ONE_FIT} and sim_scenario_sha256 = {hashlib.sha256(PAPER.read_bytes()).hexdigest()}")) == 2
    )
    # the same scenario file at another path (another machine's checkout) is the same bearing
    comp = next(r for r in rows if r["sim_scenario"] != str(PAPER))
    moved = {**comp, "run_id": "SAC-DS-1@elsewhere", "sim_scenario": "/home/ada/orbitrig/config/sim/compressible.toml"}
    assert sorted(len(g) for g in repeat_groups([*rows, moved])) == [2, 2]


def test_an_earlier_catalog_gains_the_columns_and_keeps_its_rows(catalog, runs):
    url = catalog.url
    catalog.close()
    old_rows = [{k: v for k, v in r.items() if k not in NEW} for r in run_rows(read_run(runs["paper-1"]))]
    write_earlier_catalog(url, old_rows)

    reopened = Catalog(url, create=False)
    try:
        stored = reopened.rows()
        assert len(stored) == len(old_rows) and all(r[c] is None for r in stored for c in NEW)
        assert {r["Kxx"] for r in stored} == {r["Kxx"] for r in old_rows}
        reopened.add(run_rows(read_run(runs["paper-1"])))  # add again: the new columns filled
        with reopened.engine.connect() as conn:
            assert conn.execute(select(func.count()).select_from(fits)).scalar() == len(old_rows)
        assert {r["sim_seed"] for r in reopened.rows()} == {1}
        Catalog(url).close()  # opening an up-to-date catalog changes nothing
    finally:
        with reopened.engine.begin() as conn:  # leave the session's server with the table of this version
            conn.exec_driver_sql("DROP TABLE fits")
        reopened.close()
        Catalog(url).close()


def test_the_compare_legend_names_the_bearings_when_they_differ(runs):
    """`compare` of the three runs: each legend entry says which bearing; of the two repeats alone,
    the run ids only; and the legend stays inside the figure."""
    from orbitrig.catalog.compare import Variable
    from orbitrig.catalog.compare_plot import compare_figure

    rows = [r for run in runs.values() for r in run_rows(read_run(run)) if (r["lms"], r["model"]) == ("piezo", "kcd11")]

    def labels(rows):
        fig = compare_figure(rows, Variable.STATIC_ECCENTRICITY, ["Kxx", "Cxx"], title="t")
        fig.draw_without_rendering()
        box = fig.legends[0].get_window_extent(fig.canvas.get_renderer())
        assert box.x0 >= 0 and box.x1 <= fig.bbox.width
        return sorted(t.get_text() for t in fig.legends[0].get_texts())

    both = labels(rows)
    assert sorted(t.rsplit(" (", 1)[1] for t in both) == ["sim compressible)", "sim paper)", "sim paper)"]
    assert all(t.startswith("SAC-DS-1@") for t in both)
    repeats = labels([r for r in rows if r["sim_scenario"] == str(PAPER)])
    assert len(repeats) == 2 and all(" (" not in t for t in repeats)
