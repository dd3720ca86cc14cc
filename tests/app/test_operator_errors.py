"""Operator mistakes: each gives one clear message (file, line, key), no traceback, a non-zero exit.

Commands refused before they start anything run in the test's process (support.cli_helpers.orbitrig_here);
a sweep, the simulator and a run on the rig in their own."""

import shutil
import signal
import subprocess
from pathlib import Path

import pytest

from orbitrig import config as cfg
from orbitrig.errors import ConfigError

from support.cli_helpers import orbitrig, orbitrig_here, orbitrig_started, reaped

RIG_TEXT = cfg.default_rig_path().read_text()
DEMO_TEXT = cfg.default_matrix_path("demo").read_text()


def _line_no(text: str, startswith: str) -> int:
    return next(n for n, line in enumerate(text.splitlines(), 1) if line.startswith(startswith))


def _run(*args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    return orbitrig(*args, timeout=timeout, columns=None)


def _here(*args: str) -> subprocess.CompletedProcess:
    """`orbitrig ARGS...` of a command that starts nothing, in this process, as `_run` has it (piped)."""
    return orbitrig_here(*args, columns=80)


@pytest.mark.parametrize(
    "old, new, key, message",
    [
        ("clearance_um = 60.0", "clearence_um = 60.0", "bearing.clearence_um", "unknown key"),
        ("revolutions = 50 ", 'revolutions = "fifty" ', "averaging.revolutions", "'fifty'"),
        ("hold_s = 2.0 ", "hold_s = -2.0 ", "settle.hold_s", "greater than or equal to 0"),
        ('adc_mode = "sequential"', 'adc_mode = "sequental"', "transports.adc_mode", "'sequental'"),
    ],
)
def test_bad_rig_value_names_file_line_and_key(old, new, key, message):
    text = RIG_TEXT.replace(old, new, 1)
    with pytest.raises(ConfigError) as info:
        cfg.rig_from_text(text, "bad_rig.toml")
    (problem,) = info.value.problems
    assert problem.startswith(f"line {_line_no(text, new.strip())}: key '{key}'")
    assert message in problem


def test_table_level_error_points_at_the_table_and_does_not_dump_it():
    text = RIG_TEXT.replace("orbit_id = 2", "orbit_id = 1", 1)
    with pytest.raises(ConfigError) as info:
        cfg.rig_from_text(text, "bad_rig.toml")
    (problem,) = info.value.problems
    header = [n for n, line in enumerate(text.splitlines(), 1) if line.startswith("[drives]")][0]
    assert problem == f"line {header}: key 'drives': spin_id and orbit_id must differ"


def test_missing_matrix_key_names_its_table_line():
    text = "\n".join(line for line in DEMO_TEXT.splitlines() if not line.startswith("spin_rpm"))
    with pytest.raises(ConfigError) as info:
        cfg.matrix_from_text(text, "m.toml")
    assert info.value.problems == [
        f"line {_line_no(text, '[operating]')}: key 'operating.spin_rpm': required key is missing"
    ]


def test_matrix_beyond_drive_limits_is_refused_before_the_simulator_starts(tmp_path):
    matrix = tmp_path / "fast.toml"
    matrix.write_text(DEMO_TEXT.replace("spin_rpm = [1000.0]", "spin_rpm = [9000.0]"))
    p = _here("sweep", "--sim", "--matrix", str(matrix), "--out", str(tmp_path / "run"))
    assert p.returncode == 2
    assert "Traceback" not in p.stderr
    assert f"{matrix}: line {_line_no(matrix.read_text(), 'spin_rpm')}: key 'operating.spin_rpm': 9000 rpm" in p.stderr
    assert "points" not in p.stderr  # no progress bars: nothing was started
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("kind", ["missing-parent", "file"])
def test_unusable_out_gives_a_message_not_a_traceback(tmp_path, kind):
    if kind == "file":
        out = tmp_path / "a_file"
        out.write_text("x")
        expect = "--out is a file, not a directory"
    else:
        out = Path("/proc/orbitrig-no-such-dir")  # /proc refuses new directories, even to root
        expect = "cannot create the run directory"
    p = _here("sweep", "--sim", "--out", str(out))
    assert p.returncode == 2
    assert "Traceback" not in p.stderr
    assert f"error: {out}: {expect}" in p.stderr


def test_out_holding_a_run_is_refused_before_anything_starts(tmp_path):
    (tmp_path / "run.h5").write_bytes(b"")
    p = _here("sweep", "--sim", "--out", str(tmp_path))
    assert p.returncode == 2
    assert f"{tmp_path / 'run.h5'}: already exists: use --resume" in p.stderr
    assert "points" not in p.stderr


def test_sweep_help_keeps_its_defaults_visible():
    p = _here("sweep", "--help")
    assert p.returncode == 0
    flat = " ".join(p.stdout.replace("│", " ").split())
    assert "rig.toml in $ORBITRIG_HOME" in flat and "matrices/demo.toml" in flat


def test_closed_stdin_at_a_confirmation_stops_the_run_instead_of_hanging(tmp_path):
    """On the rig (no --sim) a manual-settings prompt with nobody to answer stops the run safely."""
    import json

    sim = orbitrig_started("sim", "--modbus-port", "0", "--adc-port", "0", "--can-port", "0", stderr=subprocess.DEVNULL)
    with reaped(sim, signal.SIGTERM):
        ends = json.loads(sim.stdout.readline())
        rig = tmp_path / "rig.toml"
        rig.write_text(
            RIG_TEXT.replace('"socket://127.0.0.1:5000"', json.dumps(ends["adc"]), 1)
            .replace('"tcp://127.0.0.1:5020"', json.dumps(ends["modbus"]), 1)
            .replace('can_channel = "can0"', f"can_channel = {json.dumps(ends['can'])}", 1)
            .replace('can_interface = "socketcan"', 'can_interface = "serial"', 1)  # the simulator's node
        )
        p = orbitrig(
            "sweep",
            "--config",
            str(rig),
            "--matrix",
            str(cfg.default_matrix_path("demo")),
            "--out",
            str(tmp_path / "run"),
            timeout=60,
            columns=None,
        )
        assert p.returncode == 3, p.stderr
        assert "standard input is closed" in p.stderr and "Traceback" not in p.stderr
        status = _run("drives", "status", "--modbus", ends["modbus"], "--json")
        assert status.returncode == 0, status.stderr
        drives = json.loads(status.stdout)
        for name in ("spin", "orbit"):
            assert drives[name]["running"] is False and drives[name]["reference_rpm"] == 0.0, drives


def test_dry_run_has_a_column_header_and_names_steps_in_the_rigs_words():
    p = _here("sweep", "--sim", "--dry-run", "--steps")  # every step (without --steps: one line per point)
    assert p.returncode == 0, p.stderr
    lines = p.stdout.splitlines()
    heads = [line for line in lines if line and not line.startswith(" ")]  # a folded line goes on indented
    assert heads[0].startswith("matrix demo: 1 operating point,") and heads[1].startswith("by step: ")  # totals first
    assert heads[2].startswith("predicted uncertainty")  # then each model's predicted uncertainty
    header = next(i for i, line in enumerate(lines) if line.split()[:1] == ["#"])
    assert lines[header].split()[:5] == ["#", "starts", "at", "where", "duration"] and lines[header - 1] == ""
    by_step = " ".join(p.stdout.split("by step: ")[1].split("predicted uncertainty")[0].split())
    assert "manual settings 2:00" in by_step and "stop drives" in by_step and "SetManual" not in by_step


@pytest.fixture(scope="module")
def demo_sweep(tmp_path_factory) -> tuple[subprocess.CompletedProcess, Path]:
    """(the process, its run directory) of `sweep --sim` of the demo matrix, made once: the tests
    read its output or resume a copy of its run; nobody writes to this one."""
    out = tmp_path_factory.mktemp("demo") / "run"
    return _run("sweep", "--sim", "--out", str(out)), out


def test_sweep_coefficient_table_states_units(demo_sweep):
    p, _ = demo_sweep
    assert p.returncode == 0, p.stderr
    assert "units: K MN/m, C kN s/m, D kg" in p.stdout  # as reduce's and identify's text tables
    assert "piezo kcd11" in p.stdout  # the table still fits 80 columns without wrapping its headers


def test_resume_with_another_matrix_is_refused_before_anything_starts(demo_sweep, tmp_path):
    done, run = demo_sweep
    assert done.returncode == 0, done.stderr
    out = shutil.copytree(run, tmp_path / "run")  # a run directory holds no path of its own
    other = tmp_path / "other.toml"
    other.write_text(DEMO_TEXT.replace("dynamic_eccentricity = [0.096]", "dynamic_eccentricity = [0.1]"))
    p = _here("sweep", "--sim", "--resume", str(out), "--matrix", str(other))
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert f"{other}: differs from the matrix of the run being resumed" in p.stderr
    assert "points" not in p.stderr


def test_sim_on_a_port_in_use_names_the_port_without_a_traceback():
    import socket

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        p = _run("sim", "--modbus-port", str(port), "--adc-port", "0", timeout=30)
    assert p.returncode == 1
    assert "Traceback" not in p.stderr
    assert f"ports: Modbus {port}, A/D 0" in p.stderr


def test_identify_of_a_missing_table_says_it_cannot_be_read(tmp_path):
    p = _here("identify", str(tmp_path / "nope.csv"), "--model", "kc8")
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert f"orbitrig identify: error: {tmp_path / 'nope.csv'}: cannot read the file" in p.stderr
    assert "malformed" not in p.stderr


def test_missing_default_config_says_how_to_give_one(tmp_path, monkeypatch):
    from orbitrig.config import home

    monkeypatch.setattr(home, "shipped_config", lambda: tmp_path / "config")  # an install without its data
    monkeypatch.delenv(home.HOME_ENV, raising=False)
    monkeypatch.chdir(tmp_path)
    for load, option in ((cfg.load_rig, "--config"), (cfg.load_matrix, "--matrix")):
        with pytest.raises(ConfigError) as info:
            load()
        assert info.value.file.startswith(str(tmp_path / "config"))
        assert info.value.problems[0].startswith(
            f"the default file is not there: give {option} FILE, set ORBITRIG_HOME"
        )


def test_a_config_file_not_there_says_what_to_give(tmp_path):
    """`--config` naming no file (a typo) or the lab folder itself: the message says what to give."""
    missing = _here("sweep", "--sim", "--dry-run", "--config", str(tmp_path / "rig.tmol"))
    folder = _here("calibrate", "list", "--config", str(tmp_path))
    for p, path, found in ((missing, tmp_path / "rig.tmol", "no such file"), (folder, tmp_path, "is a folder")):
        assert p.returncode == 2 and "Traceback" not in p.stderr
        assert f"{path}: {found}: give --config a rig.toml (`orbitrig init DIR` writes DIR/rig.toml" in p.stderr
    with pytest.raises(ConfigError) as info:
        cfg.load_matrix(tmp_path / "paper.tmol")
    assert info.value.problems == [
        "no such file: give --matrix a matrix TOML file or the name of one in the configuration's matrices/"
    ]
