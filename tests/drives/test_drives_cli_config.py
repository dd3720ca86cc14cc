"""`orbitrig drives` with a rig configuration: URL and limits from the file, the
command line only tightening them, and `run --hold` (against the simulator's drives: in a
subprocess where the command is signalled or the drives stopped by another client while it runs,
in this process where it runs to its end on its own; every test ends on the drives' own registers).
"""

from __future__ import annotations

import asyncio
import json
import re
import signal

import pytest
from support.cli_helpers import orbitrig_started_async, reaped_async
from support.drives_testkit import CLI_START_S, CW_RAMP_STOP, CW_RUN, invoke_cli, run_cli
from support.paths import ROOT
from support.rig_configs import without_can_node

from orbitrig.cli.drives import effective_limits
from orbitrig.config import Drives

pytestmark = pytest.mark.timeout(150)

SW_AT_SETPOINT = 0x100
CW_READY = 0x0476  # the spec's "ready to switch on" word


def rig_config(tmp_path, url: str, **drives) -> str:
    """config/rig.toml with the simulator's URL and the given [drives] values; no CAN node (the
    simulator's drives alone)."""
    text = without_can_node((ROOT / "config" / "rig.toml").read_text())
    text = re.sub(r'(?m)^modbus_url = ".*"', f'modbus_url = "{url}"', text)
    for key, value in drives.items():
        text, n = re.subn(rf"(?m)^{key} = [^#\n]*", f"{key} = {value!r}", text)
        assert n == 1, key
    path = tmp_path / "rig.toml"
    path.write_text(text)
    return str(path)


def untouched(sim) -> bool:
    return all(sim.regs(dev)["CW"] == 0 and sim.regs(dev)["REF"] == 0 for dev in (1, 2))


def test_limits_come_from_the_config_and_options_only_tighten(threaded_tcp_sim, tmp_path):
    sim = threaded_tcp_sim
    cfg = rig_config(tmp_path, sim.url, max_spin_rpm=1000.0, max_orbit_rpm=500.0, min_ratio=0.1, max_ratio=1.0)
    refused = [
        (["--spin", "1500", "--orbit", "300"], "max_spin"),  # over the config's 1000 rpm
        (["--spin", "800", "--orbit", "-600"], "max_orbit"),
        (["--spin", "900", "--orbit", "50"], r"\|Omega\|/omega"),  # below min_ratio 0.1
        (["--spin", "600", "--orbit", "300", "--max-spin", "500"], "max_spin"),  # tightened
    ]
    for args, match in refused:
        code, out, err = invoke_cli("drives", "run", "--config", cfg, *args)
        assert code == 2 and "error (limit)" in err and "nothing sent" in err, err
        assert re.search(match, err), err
    looser = [
        (["--max-spin", "3000"], "--max-spin 3000 rpm is above the rig's drives.max_spin_rpm = 1000 rpm"),
        (["--max-orbit", "600"], "--max-orbit 600 rpm is above the rig's drives.max_orbit_rpm = 500"),
        (["--min-ratio", "0.05"], "--min-ratio 0.05 is below the rig's drives.min_ratio = 0.1"),
        (["--max-ratio", "2"], "--max-ratio 2 is above the rig's drives.max_ratio = 1"),
    ]
    for args, message in looser:  # a legal speed, refused for the looser limit alone
        code, out, err = invoke_cli("drives", "run", "--config", cfg, "--spin", "600", "--orbit", "300", *args)
        assert code == 2 and message in err and "only tighten" in err and "nothing sent" in err, err
        assert cfg in err
    assert untouched(sim)  # nothing was written by any of them
    assert sim.regs(1)["ACT"] == sim.regs(2)["ACT"] == 0


def test_effective_limits_merge():
    d = Drives(max_spin_rpm=2000.0, max_orbit_rpm=1000.0, min_ratio=None, max_ratio=1.5)
    lim = effective_limits(d, max_spin=1500.0, min_ratio=0.2)
    rpm = 2 * 3.141592653589793 / 60
    assert lim.max_spin == pytest.approx(1500 * rpm) and lim.max_orbit == pytest.approx(1000 * rpm)
    assert (lim.min_ratio, lim.max_ratio) == (0.2, 1.5)
    with pytest.raises(ValueError, match="min ratio 2 > max ratio 1.5"):
        effective_limits(d, min_ratio=2.0)
    with pytest.raises(ValueError, match="--max-spin inf"):
        effective_limits(d, max_spin=float("inf"))


def test_url_from_the_config_run_status_stop(threaded_tcp_sim, tmp_path):
    sim = threaded_tcp_sim
    cfg = rig_config(tmp_path, sim.url)
    code, out, err = invoke_cli(
        "drives", "run", "--config", cfg, "--spin", "1000", "--orbit", "-400", "--settle", "0.05"
    )
    assert code == 0, err
    assert sim.regs(1)["REF"] == 6667 and sim.regs(2)["REF"] == -2667
    code, out, err = invoke_cli("drives", "status", "--config", cfg, "--json")
    assert code == 0, err
    status = json.loads(out)
    assert status["modbus"] == sim.url
    assert status["orbit"]["reference_rpm"] == pytest.approx(-400, abs=0.1)
    assert status["spin"]["id_from"] == status["orbit"]["id_from"] == "configuration" and "WARNING" not in err
    code, out, err = invoke_cli("drives", "stop", "--config", cfg)
    assert code == 0, err
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP
    assert sim.regs(1)["ACT"] == sim.regs(2)["ACT"] == 0
    # an explicit --modbus wins over the file's URL
    dead = rig_config(tmp_path, "tcp://127.0.0.1:9")
    code, out, err = invoke_cli("drives", "stop", "--config", dead, "--modbus", sim.url)
    assert code == 0, err


def test_an_unreadable_config_stop_goes_to_the_built_in_ids_saying_so(threaded_tcp_sim, tmp_path):
    """A rig.toml that cannot be read: `stop --modbus URL` still stops the drives, at the built-in
    ids 1 and 2, with a WARNING naming the file and its error before and after; `status` marks
    each id from the defaults; without --modbus nothing is sent (exit 2). Done, they exit 3: the
    rig configuration has errors."""
    sim, broken = threaded_tcp_sim, tmp_path / "rig.toml"
    broken.write_text("[drives\nspin_id = 5\n")
    said = f"WARNING: rig configuration not read ({broken}: not valid TOML"
    code, out, err = invoke_cli("drives", "stop", "--config", str(broken))
    assert code == 2 and "error (config)" in err and untouched(sim), err
    for dev in (1, 2):  # both turning (ready to switch on, then run: the spec's words)
        for address, word in ((1, 3000), (0, CW_READY), (0, CW_RUN)):
            sim.in_loop(sim.models[dev].write, address, [word])
    code, out, err = invoke_cli("drives", "status", "--modbus", sim.url, "--config", str(broken), "--json")
    status = json.loads(out)
    assert code == 3 and said in err and status["spin"]["running"], err
    assert status["spin"]["id_from"] == status["orbit"]["id_from"] == "built-in default"
    code, out, err = invoke_cli("drives", "status", "--modbus", sim.url, "--config", str(broken), "--orbit-id", "2")
    assert code == 3 and "spin  (id 1, built-in default): running" in out and "orbit (id 2): running" in out, out
    assert "orbit (id 2, option)" in err and "give --spin-id/--orbit-id" in err, err
    code, out, err = invoke_cli("drives", "stop", "--modbus", sim.url, "--config", str(broken))
    lines = err.strip().splitlines()
    assert code == 3 and lines[0].startswith(f"orbitrig drives stop: {said}"), err
    assert "drives addressed: spin (id 1, built-in default), orbit (id 2, built-in default)" in lines[0]
    assert lines[-2] == (
        "orbitrig drives stop: WARNING: the stop was addressed to device ids not from the rig configuration: "
        "spin (id 1, built-in default), orbit (id 2, built-in default)"
    )
    assert sim.regs(1)["CW"] == sim.regs(2)["CW"] == CW_RAMP_STOP and sim.regs(1)["ACT"] == sim.regs(2)["ACT"] == 0
    code, out, err = invoke_cli(
        "drives", "stop", "--modbus", sim.url, "--config", str(broken), "--spin-id", "1", "--orbit-id", "2"
    )
    assert code == 3 and said in err and "spin (id 1, option), orbit (id 2, option)" in err, err
    assert "give --spin-id" not in err and "addressed to device ids not from" not in err, err


async def test_hold_keeps_the_drives_at_speed_and_stops_them_on_sigint(sim, tmp_path):
    cfg = rig_config(tmp_path, sim.url)
    proc = await orbitrig_started_async(
        "drives",
        "run",
        "--config",
        cfg,
        "--spin",
        "900",
        "--orbit",
        "-450",
        "--settle",
        "0.05",
        "--hold",
        "--status-every",
        "0.5",
    )
    async with reaped_async(proc):
        await sim.wait_for(
            lambda: sim.regs(1)["SW"] & SW_AT_SETPOINT and sim.regs(2)["SW"] & SW_AT_SETPOINT,
            CLI_START_S,
            "at setpoint",
        )
        assert sim.models[1].parameter(104) == 10  # the drives' watchdog: 1 s
        await asyncio.sleep(2.0)  # twice the watchdog: only the hold's polling keeps them going
        for dev in (1, 2):
            regs = sim.regs(dev)
            assert regs["CW"] == CW_RUN and regs["FAULT"] == 0, regs
        assert sim.rpm(1) == pytest.approx(900, abs=5) and sim.rpm(2) == pytest.approx(-450, abs=5)
        proc.send_signal(signal.SIGINT)
        out, err = await asyncio.wait_for(proc.communicate(), 15)
    out, err = out.decode(), err.decode()
    assert proc.returncode == 0, err
    assert len(re.findall(r"(?m)^holding \d+ s: spin 9\d\d\.\d rpm \(at setpoint\)", out)) >= 2, out
    assert "SIGINT: ramping both drives to zero" in err
    assert "both drives stopped" in out
    for dev in (1, 2):  # stopped by command, not by the watchdog
        regs = sim.regs(dev)
        assert regs["CW"] == CW_RAMP_STOP and regs["ACT"] == 0 and sim.not_the_watchdog(dev), regs


@pytest.mark.parametrize(
    "args, says",
    [
        (["--timeout", "-1"], "--timeout -1 s must be finite, > 0"),
        (["--timeout", "nan"], "--timeout nan s must be finite"),
        (["--timeout", "inf"], "--timeout inf s must be finite"),
        (["--settle", "nan"], "--settle nan s must be finite, >= 0"),
        (["--status-every", "0"], "--status-every 0 s must be finite, > 0"),
        (["--spin-id", "999999"], "--spin-id 999999 is not a Modbus device id (1..247)"),
        (["--orbit-id", "0"], "--orbit-id 0 is not a Modbus device id (1..247)"),
    ],
)
def test_run_refuses_bad_options_and_sends_nothing(threaded_tcp_sim, tmp_path, args, says):
    tcp_sim = threaded_tcp_sim
    cfg = rig_config(tmp_path, tcp_sim.url)
    code, out, err = invoke_cli("drives", "run", "--config", cfg, "--spin", "900", "--orbit", "300", *args)
    assert code == 2 and says in err and "nothing sent" in err, err
    assert "Traceback" not in err
    assert untouched(tcp_sim)


def test_stop_refuses_a_timeout_that_is_not_finite(threaded_tcp_sim, tmp_path):
    tcp_sim = threaded_tcp_sim
    code, out, err = invoke_cli("drives", "stop", "--config", rig_config(tmp_path, tcp_sim.url), "--timeout", "nan")
    assert code == 2 and "--timeout nan s must be finite" in err and untouched(tcp_sim)


async def test_hold_notices_the_drives_stopped_by_another_client(tcp_sim, tmp_path):
    sim = tcp_sim
    cfg = rig_config(tmp_path, sim.url)
    proc = await orbitrig_started_async(
        "drives",
        "run",
        "--config",
        cfg,
        "--spin",
        "900",
        "--orbit",
        "450",
        "--settle",
        "0.05",
        "--hold",
        "--status-every",
        "0.5",
    )
    async with reaped_async(proc):
        await sim.wait_for(
            lambda: sim.regs(1)["SW"] & SW_AT_SETPOINT and sim.regs(2)["SW"] & SW_AT_SETPOINT,
            CLI_START_S,  # the interpreter's start, the link and the ramps
            "at setpoint",
        )
        code, _, stop_err = await run_cli("drives", "stop", "--config", cfg)  # another client
        assert code == 0, stop_err
        out, err = await asyncio.wait_for(proc.communicate(), 30)
    out, err = out.decode(), err.decode()
    assert proc.returncode == 2, err
    assert "is no longer running" in err and "stopped or changed by another client" in err, err
    assert "the hold was ended by another client" in out and "both drives stopped" in out
    for dev in (1, 2):
        regs = sim.regs(dev)
        assert regs["ACT"] == 0 and sim.not_the_watchdog(dev), regs  # stopped by the other client's stop


def test_status_of_a_rig_toml_without_a_hardware_key_uses_its_drives_saying_so_run_refuses(threaded_tcp_sim, tmp_path):
    """A rig.toml that leaves out a key of the rig's hardware (here the bearing's clearance) is
    refused for a run; `status` and `stop` still reach the drives it names (its [transports] and
    [drives], its errors said on stderr, exit 3): a stop does not wait for a bearing's clearance."""
    sim = threaded_tcp_sim
    path = rig_config(tmp_path, sim.url)
    text = open(path).read()
    with open(path, "w") as f:
        f.write(re.sub(r"(?m)^clearance_um = .*\n", "", text))
    code, out, err = invoke_cli("drives", "status", "--config", path, "--json")
    assert code == 3 and json.loads(out)["spin"]["id_from"] == "configuration", err
    assert f"\n{path}: line " in err and "key 'bearing.clearance_um': missing" in err
    assert "orbitrig drives status: WARNING: the rig configuration has errors" in err, err
    code, out, err = invoke_cli("drives", "run", "--config", path, "--spin", "100", "--orbit", "50")
    assert code == 2 and f"orbitrig drives run: error (config): {path}: line " in err, err
    assert "clearance_um" in err and untouched(sim)
