"""A record measured on the simulator names its scenario's file and the SHA-256 of its text
(``simulator``, ``simulator_sha256``); every --sim entry point (`sweep --sim`, `sweep --dry-run
--sim`, `serve --sim` with or without --sim-config at its start and at each start of a run) warns through one check
(orbitrig.config.other_scenario) when the active record was measured on another scenario, compared
by content: a copy of the scenario elsewhere is the same one, the file edited since is not. A
record written before the digest is compared by the resolved path, as before.

Real parts: the `orbitrig` command line (subprocesses; the dry runs, which start nothing, in the
test's process), the simulator process, the lab folder's files; the service's start with no broker to reach (it keeps trying) shows its start's warning."""

from __future__ import annotations

import logging
import re
import shutil
import time

import pytest

from orbitrig.cli.serve import _reloaded
from orbitrig.cli.scenarios import default_scenario
from orbitrig.config import digest, load_rig, other_scenario
from orbitrig.run.scenario import Scenario
from sim.scenario_files import scenario_path
from support.cli_helpers import orbitrig, orbitrig_here
from support.mqtt_helpers import Service, interrupt
from support.paths import ROOT
from support.rig_configs import sealed, patient_rig_config

pytestmark = pytest.mark.timeout(240)
WARNED = "measured on the simulator scenario"


def _lab(tmp_path, simulator: str, sha256: str | None):
    """A lab folder whose active record says it was measured on the scenario file `simulator`
    (with `sha256` as its content's digest; None: an older record without one)."""
    patient_rig_config(tmp_path)  # a link that holds with both cores busy
    shutil.copytree(ROOT / "config/calibration", tmp_path / "calibration")
    record = tmp_path / "calibration" / f"{load_rig(tmp_path / 'rig.toml').calibration_record}.toml"
    keys = f"simulator = {simulator!r}\n" + (f"simulator_sha256 = {sha256!r}\n" if sha256 is not None else "")
    record.write_text(sealed(record.read_text().replace('\nprevious = ""\n', f'\nprevious = ""\n{keys}')))
    return tmp_path / "rig.toml"


def _copy_of_clean(tmp_path, name="copy.toml"):
    copy = tmp_path / name
    copy.write_text(scenario_path("clean").read_text())
    return copy


def test_the_scenarios_are_compared_by_content_and_older_records_by_path(tmp_path):
    clean = scenario_path("clean").read_text()
    copy = _copy_of_clean(tmp_path)
    rig = load_rig(_lab(tmp_path, str(scenario_path("clean")), digest(clean)))
    assert other_scenario(rig, str(copy), clean) is None  # a copy elsewhere: the same scenario
    paper = default_scenario()
    warning = other_scenario(rig, paper.name, paper.text)
    assert warning is not None and f"(SHA-256 {digest(clean)[:12]}), this run runs {paper.name} " in warning
    # the record's own file edited since it was measured
    edited = (tmp_path / "edited").mkdir() or _lab(tmp_path / "edited", str(copy), digest(clean))
    copy.write_text(clean.replace("[noise]", "[noise]\n# retuned", 1))
    warning = other_scenario(load_rig(edited), str(copy), copy.read_text())
    assert warning is not None and f"this run runs {copy} (SHA-256 {digest(copy.read_text())[:12]}: edited since)" in (
        warning
    )
    old = (tmp_path / "old").mkdir() or _lab(tmp_path / "old", str(scenario_path("clean")), None)
    assert other_scenario(load_rig(old), str(scenario_path("clean")), "any text") is None  # by path
    assert WARNED in (other_scenario(load_rig(old), str(copy), clean) or "")


def test_the_dry_run_on_the_simulator_warns_as_the_sweep_does(tmp_path):
    rig = _lab(tmp_path, str(scenario_path("clean")), digest(scenario_path("clean").read_text()))
    p = orbitrig_here("sweep", "--dry-run", "--sim", "--config", str(rig))
    assert p.returncode == 0, p.stderr
    warning = next((x for x in p.stderr.splitlines() if WARNED in x), "")
    assert warning.startswith("warning: the calibration record ") and default_scenario().name in warning, p.stderr
    assert "matrix demo:" in p.stdout  # the plan is printed all the same
    q = orbitrig_here(
        "sweep", "--dry-run", "--sim", "--sim-config", str(_copy_of_clean(tmp_path)), "--config", str(rig)
    )
    assert q.returncode == 0 and WARNED not in q.stderr, q.stderr
    r = orbitrig_here("sweep", "--dry-run", "--sim", "--sim-config", str(tmp_path / "nope.toml"), "--config", str(rig))
    assert r.returncode == 2 and "nope.toml" in r.stderr and "Traceback" not in r.stderr, r.stderr


def test_a_sim_sweep_on_its_scenario_file_edited_since_warns(tmp_path):
    copy = _copy_of_clean(tmp_path)
    rig = _lab(tmp_path, str(copy), digest(copy.read_text()))
    copy.write_text(copy.read_text().replace("[noise]", "[noise]\n# retuned", 1))
    s = orbitrig("sweep", "--sim", "--sim-config", str(copy), "--config", str(rig), "--out", str(tmp_path / "run"))
    assert s.returncode == 0, s.stderr
    warning = next((x for x in s.stderr.splitlines() if WARNED in x), "")
    assert f"this run runs {copy} (SHA-256 {digest(copy.read_text())[:12]}: edited since)" in warning, s.stderr
    # its resume runs the stored scenario with the stored record: warned the same, naming that copy
    # (its last point's commit record removed: a point left to measure; a run whose points are all
    # complete starts no simulator)
    last = max((tmp_path / "run" / "points").iterdir())
    (last / "complete.json").unlink()
    r = orbitrig("sweep", "--sim", "--resume", "--out", str(tmp_path / "run"))
    assert r.returncode == 0, r.stderr
    again = next((x for x in r.stderr.splitlines() if WARNED in x), "")
    name = load_rig(rig).calibration_record
    assert again.startswith(f"warning: the calibration record {name} (the copy stored in {tmp_path}/run/run.json) "), (
        r.stderr
    )


@pytest.mark.parametrize("sim_config", [None, "compressible"])
def test_serve_on_the_simulator_warns_at_its_start_and_at_each_start_of_a_run(tmp_path, caplog, sim_config):
    """Its start names the scenario of its runs: --sim-config's (a shipped NAME: its file), else the default."""
    rig = _lab(tmp_path, str(scenario_path("clean")), digest(scenario_path("clean").read_text()))
    (tmp_path / "matrices").mkdir()  # beside rig.toml: its options are right, the service starts
    given = ("--sim-config", sim_config) if sim_config else ()
    args = ["--sim", *given, "--broker", "mqtt://127.0.0.1:1", "--config", str(rig), "--speedup", "20"]
    svc = Service(args, tmp_path)
    try:
        deadline = time.monotonic() + 60
        while WARNED not in svc.text() and svc.proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
        runs = str(scenario_path(sim_config)) if sim_config else default_scenario().name
        said = rf"WARNING .*the calibration record .* {WARNED} .*this run runs {re.escape(runs)} "
        assert re.search(said, svc.text()), svc.text()
        assert svc.proc.poll() is None, svc.text()  # warned as it starts, not refused
    finally:
        interrupt(svc.proc)
    with caplog.at_level(logging.WARNING, logger="orbitrig.cli.serve"):
        _reloaded(rig, load_rig(rig), on_the_rig=False, scenario=default_scenario())
    assert [r.getMessage() for r in caplog.records if WARNED in r.getMessage()], caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="orbitrig.cli.serve"):
        clean = scenario_path("clean")
        _reloaded(rig, load_rig(rig), on_the_rig=False, scenario=Scenario(str(clean), clean.read_text()))
    assert WARNED not in caplog.text


def test_a_sim_step_starting_from_a_record_of_another_scenario_warns(tmp_path):
    """Its record keeps the earlier record's other sections (measured on clean) under the step's
    scenario: said, with the same check, before the step runs."""
    rig = _lab(tmp_path, str(scenario_path("clean")), digest(scenario_path("clean").read_text()))
    p = orbitrig("calibrate", "runout", "--sim", "--config", str(rig), "--revolutions", "4")
    assert p.returncode == 0, p.stderr
    warning = next((x for x in p.stderr.splitlines() if WARNED in x), "")
    assert warning.startswith("warning: the calibration record ") and warning.endswith(
        "keeps what it does not measure from that record, under this step's scenario"
    ), p.stderr
    assert f"this run runs {default_scenario().name} (SHA-256 " in warning


def test_a_sim_run_with_a_record_measured_on_the_real_rig_warns(tmp_path):
    """A measured record without `simulator` was measured on the real rig: its runout and lags
    correct the simulated blocks. The same check (other_scenario) warns, by `sweep --dry-run
    --sim` and a `calibrate ... --sim` step; the shipped `initial` record (typed in) is no warning."""
    patient_rig_config(tmp_path)  # a link that holds with both cores busy
    shutil.copytree(ROOT / "config/calibration", tmp_path / "calibration")
    rig = tmp_path / "rig.toml"
    record = tmp_path / "calibration" / f"{load_rig(rig).calibration_record}.toml"
    initial = orbitrig_here("sweep", "--dry-run", "--sim", "--config", str(rig))
    assert initial.returncode == 0 and "warning:" not in initial.stderr, initial.stderr
    record.write_text(sealed(record.read_text().replace('step = "initial"', 'step = "runout"')))
    paper = default_scenario()
    said = (
        f"warning: the calibration record {record} was measured on the real rig, this run runs the simulator "
        f"scenario {paper.name}: its runout, lags and gains are the rig's"
    )
    assert said.removeprefix("warning: ") in (other_scenario(load_rig(rig), paper.name, paper.text) or "")
    p = orbitrig_here("sweep", "--dry-run", "--sim", "--config", str(rig))
    assert p.returncode == 0 and said in p.stderr and "matrix demo:" in p.stdout, p.stderr
    q = orbitrig("calibrate", "runout", "--sim", "--config", str(rig), "--revolutions", "4", "--no-activate")
    assert q.returncode == 0 and said in q.stderr, q.stderr
    assert "; the record this step writes keeps what it does not measure from that record" in q.stderr
