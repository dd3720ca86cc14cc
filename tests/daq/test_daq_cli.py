"""`orbitrig acquire` as a user runs it, against the simulator (TCP and pty); its refusals in this process."""

from __future__ import annotations

import asyncio
import json
import math

import numpy as np
import pytest

from sim.scenario_files import scenario
from sim.rig import SimRig


from support.cli_helpers import orbitrig_async, orbitrig_here
from support.sim_thread import sim_in_thread
from support.paths import ROOT

pytestmark = pytest.mark.timeout(60)
ORBIT = 2 * math.pi * 12.5


@pytest.fixture
async def rig():
    async with SimRig(scenario("clean"), speedup=20.0, can_channel=None) as r:  # phasors to 1 %
        r.local_control(spin=150.0, orbit=ORBIT)
        await asyncio.sleep(0.05)
        yield r


async def test_json_over_tcp_in_counts(rig):
    code, out, err = await orbitrig_async("acquire", "--adc", rig.adc_url, "--json", "--revolutions", "40", "--counts")
    assert code == 0, err
    d = json.loads(out)
    assert list(d) == [
        "revolutions_used",
        "revolutions_dropped",
        "frames_bad",
        "bytes_skipped",
        "orbit_hz",
        "stop_reason",
        "channels",
    ]
    assert d["stop_reason"] == "count"
    assert d["revolutions_used"] == 40 and d["revolutions_dropped"] == 0 and d["frames_bad"] == 0
    assert d["orbit_hz"] == pytest.approx(12.5, rel=2e-3)
    assert [c["index"] for c in d["channels"]] == list(range(8))
    gains = np.array(rig.config.adc.gains)
    truth = np.array(list(rig.true_phasors(150.0, ORBIT).values())) / gains  # counts
    for c, q in zip(d["channels"], truth):
        assert set(c) == {"index", "name", "unit", "re", "im", "amplitude", "phase_deg", "rms_residual", "uncertainty"}
        assert (c["name"], c["unit"]) == ("", "count")  # raw counts: pint parses "count"
        assert 0 < c["uncertainty"] < 0.01 * c["amplitude"]
        got = complex(c["re"], c["im"])
        assert abs(got - q) < 0.01 * abs(q)
        assert c["amplitude"] == pytest.approx(abs(got))
        assert c["phase_deg"] == pytest.approx(math.degrees(np.angle(got)))
        assert 0 < c["rms_residual"] < 0.05 * abs(q)


async def test_table_over_pty_with_rig_config(rig):
    code, out, err = await orbitrig_async(
        "acquire", "--adc", rig.adc_pty_path, "--rig", str(ROOT / "config" / "rig.toml"), "--revolutions", "20"
    )
    assert code == 0, err
    assert out.startswith("20 revolutions averaged, 0 dropped")
    rows = [line.split() for line in out.splitlines()[2:]]
    truth = list(rig.true_phasors(150.0, ORBIT).values())  # engineering units (N, m)
    assert len(rows) == 8
    for row, q in zip(rows, truth):
        assert abs(float(row[3]) - abs(q)) < 0.01 * abs(q)


async def test_json_with_rig_config_names_each_channel_and_its_unit(rig):
    """What a program reads: every channel's name and unit (pint parses it), as the table shows them."""
    from support.units import UREG

    code, out, err = await orbitrig_async(
        "acquire", "--adc", rig.adc_url, "--rig", str(ROOT / "config" / "rig.toml"), "--revolutions", "20", "--json"
    )
    assert code == 0, err
    channels = json.loads(out)["channels"]
    assert [(c["name"], c["unit"]) for c in channels] == [
        ("fx_piezo", "N"),
        ("fy_piezo", "N"),
        ("fx_strain", "N"),
        ("fy_strain", "N"),
        ("x_a", "m"),
        ("y_a", "m"),
        ("x_b", "m"),
        ("y_b", "m"),
    ]
    truth = list(rig.true_phasors(150.0, ORBIT).values())  # N, m
    for c, q in zip(channels, truth):
        amplitude = UREG.Quantity(c["amplitude"], c["unit"])
        assert abs(amplitude.to_base_units().magnitude - abs(q)) < 0.01 * abs(q)


def test_exit_2_with_a_clear_message():
    """Run in this process (typer's runner), the simulator served from another thread."""

    def acquire(*args: str) -> tuple[int, str, str]:
        done = orbitrig_here("acquire", *args)
        return done.returncode, done.stdout, done.stderr

    code, out, err = acquire("--adc", "socket://127.0.0.1:1")
    assert code == 2 and out == "" and "orbitrig acquire: error: socket://127.0.0.1:1: cannot connect" in err
    code, _, err = acquire("--adc", "/dev/no-such-port")
    assert code == 2 and "/dev/no-such-port: cannot open serial port" in err
    with sim_in_thread() as adc_url:
        code, _, err = acquire("--adc", adc_url, "--mode", "simultaneous", "--timeout", "0.5")
        assert (
            code == 2
            and "no good revolution within 0.5 s" in err
            and "in another A/D mode than the one configured" in err
        )
        code, _, err = acquire("--adc", adc_url, "--mode", "parallel")
        assert code == 2 and "orbitrig acquire: error: --mode must be sequential or simultaneous, not 'parallel'" in err
        code, _, err = acquire("--adc", adc_url, "--channels", "7")
        assert code == 2 and "--channels 7 but the rig config calibrates 8 channels" in err
        code, _, err = acquire("--adc", adc_url, "--channels", "7", "--counts")
        assert code == 2 and "channels=7" in err
