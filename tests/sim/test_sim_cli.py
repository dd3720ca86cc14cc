"""`orbitrig sim` as a separate process: endpoints line, streaming, clean exit; the refusals of a
scenario or a speed-up, made before anything starts, in this process."""

from __future__ import annotations

import json
import math
import signal
import socket
import subprocess
import sys
import time

import pytest

from sim.scenario_files import scenario_names
from support.cli_helpers import orbitrig, orbitrig_cmd, orbitrig_here, orbitrig_started, reaped, started
from support.sim_reader import parse, revolutions


def start(*args: str, module: str = "orbitrig") -> subprocess.Popen:
    cmd = orbitrig_cmd("sim") if module == "orbitrig" else [sys.executable, "-m", "sim"]
    return started([*cmd, *args], stdin=None)


def control(port: int, obj: dict) -> dict:
    with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
        s.sendall(json.dumps(obj).encode() + b"\n")
        return json.loads(s.makefile().readline())


@pytest.mark.parametrize(
    ("module", "sig"),
    [("orbitrig", signal.SIGINT), ("orbitrig", signal.SIGTERM), ("sim", signal.SIGINT)],
    ids=["ctrl-c", "sigterm", "python-m-sim"],
)
def test_sim_command_runs_streams_and_stops_cleanly(module, sig):
    can = ("--can-port", "0") if module == "orbitrig" else ()  # orbitrig sim: CAN on a TCP bus by default
    scenario = "--sim-config" if module == "orbitrig" else "--config"  # python -m sim: the simulator's own options
    args = ("--modbus-port", "0", "--adc-port", "0", *can, "--speedup", "5", scenario, "config/sim.toml")
    with reaped(start(*args, module=module)) as proc:
        ep = json.loads(proc.stdout.readline())
        assert set(ep) == {"modbus", "adc", "adc_pty", "control", "can", "can_node_id"}
        assert ep["modbus"].startswith("tcp://127.0.0.1:") and ep["adc"].startswith("socket://127.0.0.1:")
        assert ep["adc_pty"].startswith("/dev/pts/")
        assert ep["can"] is None if module == "sim" else ep["can"].startswith("socket://127.0.0.1:")
        cport = int(ep["control"].rsplit(":", 1)[1])
        state = control(cport, {"cmd": "state"})
        assert state["spin"] == 0.0 and state["orbit"] == 0.0  # both drives start stopped
        assert control(cport, {"cmd": "local_control", "spin": 120.0, "orbit": -2 * math.pi * 20})["ok"]
        aport = int(ep["adc"].rsplit(":", 1)[1])
        buf = b""
        with socket.create_connection(("127.0.0.1", aport), timeout=5) as s:
            t0 = time.monotonic()
            while len(revolutions(parse(buf)[0])) < 2 and time.monotonic() - t0 < 10:
                buf += s.recv(65536)
        assert len(revolutions(parse(buf)[0])) >= 2
        proc.send_signal(sig)
        assert proc.wait(timeout=10) == 0
        err = proc.stderr.read()
        assert "Traceback" not in err and "deprecated" not in err


def test_sim_command_rejects_a_bad_config(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[noise]\nwhite = 1\n")
    with reaped(start("--sim-config", str(bad), "--modbus-port", "0", "--adc-port", "0")) as proc:
        out, err = proc.communicate(timeout=30)
    assert proc.returncode == 2 and out == ""
    assert "bad.toml" in err and "noise.white" in err


def test_sim_config_is_the_scenario_option_and_config_its_deprecated_alias(tmp_path):
    """`orbitrig sim` takes the scenario as --sim-config, as sweep, calibrate and serve do (their
    --config is rig.toml); --config still works for it, said deprecated once; both at once exit 2."""
    bad = tmp_path / "bad.toml"
    bad.write_text("[noise]\nwhite = 1\n")
    old = orbitrig_here("sim", "--config", str(bad))
    assert old.returncode == 2 and "noise.white" in old.stderr, old.stderr
    assert old.stderr.count("--config is deprecated here: give the simulator scenario as --sim-config") == 1
    new = orbitrig_here("sim", "--sim-config", str(bad))
    assert new.returncode == 2 and "noise.white" in new.stderr and "deprecated" not in new.stderr, new.stderr
    both = orbitrig_here("sim", "--sim-config", "clean", "--config", str(bad))
    assert both.returncode == 2 and "--sim-config and --config both given" in both.stderr, both.stderr
    assert "noise.white" not in both.stderr
    shown = orbitrig_here("sim", "--help")
    assert "--sim-config" in shown.stdout and "--config" not in shown.stdout.replace("--sim-config", "")


def test_sim_config_takes_a_shipped_scenario_by_name_from_any_folder(tmp_path):
    """`--sim-config clean` from a folder without config/: the shipped scenario (as sweep's);
    an unknown name exits 2 naming the known ones."""
    ports = ("--modbus-port", "0", "--adc-port", "0", "--can-port", "0")
    bad = orbitrig("sim", *ports, "--sim-config", "nosuch", cwd=tmp_path, columns=None)
    assert bad.returncode == 2
    known = ", ".join(scenario_names())  # the folder's: paper, clean, compressible, ...
    assert known.startswith("paper, ") and "clean" in known and "compressible" in known
    assert f"nosuch: no such file; unknown simulator scenario 'nosuch'; known: {known}" in bad.stderr
    with reaped(orbitrig_started("sim", *ports, "--sim-config", "clean", cwd=tmp_path, stdin=None)) as proc:
        assert json.loads(proc.stdout.readline())["modbus"].startswith("tcp://127.0.0.1:")
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=30) == 0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("sim", "--speedup", "inf"), "orbitrig sim: error: --speedup inf: a finite factor > 0 and at most 10000"),
        (("sim", "--speedup", "0"), "orbitrig sim: error: --speedup 0: a finite factor > 0 and at most 10000"),
        (("sweep", "--sim", "--out", "{tmp}/run", "--speedup", "1e12"), "Invalid value for '--speedup'"),
        (("calibrate", "loads", "--sim", "--speedup", "inf"), "Invalid value for '--speedup'"),
        (("serve", "--sim", "--broker", "mqtt://127.0.0.1:1", "--speedup", "inf"), "--speedup inf: a finite factor"),
    ],
    ids=["sim-inf", "sim-0", "sweep", "calibrate", "serve"],
)
def test_a_speedup_beyond_the_simulators_exits_2_before_anything_starts(tmp_path, args, message):
    """An infinite speed-up made the simulator's loops raise by the hundred (sim) or started a run
    that failed with exit 1 (sweep); every command taking one refuses it, with the same bound."""
    p = orbitrig_here(*(a.replace("{tmp}", str(tmp_path)) for a in args))
    assert p.returncode == 2 and message in p.stderr and "Traceback" not in p.stderr, p.stderr
    assert not (tmp_path / "run").exists()


def test_a_scenario_with_an_infinite_speedup_is_refused(tmp_path):
    bad = tmp_path / "fast.toml"
    bad.write_text("speedup = inf\n")
    p = orbitrig_here("sim", "--sim-config", str(bad))
    assert (
        p.returncode == 2 and "fast.toml" in p.stderr and "speedup must be > 0 and at most 10000 (got inf)" in p.stderr
    )


def test_a_scenario_saved_with_a_byte_order_mark_is_refused_saying_so(tmp_path):
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbfspeedup = 2.0\n")
    p = orbitrig_here("sim", "--sim-config", str(bom))
    assert p.returncode == 2 and f"{bom}: line 1: starts with a byte order mark (BOM)" in p.stderr
    assert "Invalid statement" not in p.stderr


@pytest.mark.parametrize("command", [("sim", "--sim-config"), ("sweep", "--sim", "--out", "{tmp}/run", "--sim-config")])
def test_a_scenario_nested_too_deeply_exits_2_naming_it(tmp_path, command):
    """tomllib recurses per level: a RecursionError traceback (exit 1) before."""
    deep = tmp_path / "deep.toml"
    deep.write_text("x = " + "[" * 3000 + "]" * 3000 + "\n")
    p = orbitrig(*(a.replace("{tmp}", str(tmp_path)) for a in command), str(deep), timeout=60)
    assert p.returncode == 2, p.stderr
    assert f"{deep}: not valid TOML: arrays or tables nested too deeply" in p.stderr and "Traceback" not in p.stderr
    assert not (tmp_path / "run").exists()


def test_the_command_lines_speedup_bound_is_the_simulators():
    """The options check --speedup against the simulator's own limit without loading the simulator
    (a dry run loads no sim module): one number, held equal here."""
    from orbitrig.cli import sim_options
    from sim.config import MAX_SPEEDUP

    assert sim_options.MAX_SPEEDUP == MAX_SPEEDUP == 1e4
