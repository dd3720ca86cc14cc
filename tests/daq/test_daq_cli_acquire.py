"""`orbitrig acquire` defaults: the rig config's calibration, a wait that scales with
the revolutions asked and the orbit period, adaptive averaging, errors that hint
at the cause."""

from __future__ import annotations

import asyncio
import json
import math

import pytest
from typer.testing import CliRunner

import orbitrig.cli.acquire as cli_acquire
from orbitrig.cli import app
from sim.scenario_files import scenario
from sim.rig import SimRig

from support.cli_helpers import orbitrig_async, orbitrig_here
from support.sim_thread import sim_in_thread

ORBIT = 2 * math.pi * 12.5  # rad/s
pytestmark = pytest.mark.timeout(60)


@pytest.fixture
async def rig():
    async with SimRig(scenario("clean"), speedup=20.0, can_channel=None) as r:  # exact phasors, low noise
        r.local_control(spin=150.0, orbit=ORBIT)
        await asyncio.sleep(0.05)
        yield r


async def test_calibrated_by_the_rig_config_by_default(rig):
    code, out, err = await orbitrig_async("acquire", "--adc", rig.adc_url, "--revolutions", "10", "--json")
    assert code == 0, err
    truth = list(rig.true_phasors(150.0, ORBIT).values())  # N, m
    for c, q in zip(json.loads(out)["channels"], truth):
        assert abs(complex(c["re"], c["im"]) - q) < 0.01 * abs(q)


async def test_adaptive_averaging_from_the_command_line(rig):
    code, out, err = await orbitrig_async(
        "acquire", "--adc", rig.adc_url, "--target", "0.5", "--min-revolutions", "5", "--revolutions", "300", "--json"
    )
    assert code == 0, err
    d = json.loads(out)
    assert d["stop_reason"] == "target" and 5 <= d["revolutions_used"] < 300
    assert all(c["uncertainty"] <= 0.005 * c["amplitude"] for c in d["channels"])
    code, out, err = await orbitrig_async(
        "acquire", "--adc", rig.adc_url, "--target", "1e-6", "--min-revolutions", "5", "--revolutions", "20"
    )
    assert code == 0, err
    assert out.startswith("20 revolutions averaged (stopped: max), 0 dropped")
    assert "u %" in out.splitlines()[1]


def _acquire(*args: str) -> tuple[int, str, str]:
    """`orbitrig acquire ARGS...` in this process (cli_helpers.orbitrig_here): (exit status, stdout, stderr)."""
    done = orbitrig_here("acquire", *args)
    return done.returncode, done.stdout, done.stderr


def test_errors_hint_at_the_cause():
    with sim_in_thread(orbit=0.0) as adc_url:  # the board is clocked by the orbit: no frames
        code, out, err = _acquire("--adc", adc_url, "--timeout", "0.5")
        assert code == 2 and out == ""
        assert "no good revolution within 0.5 s" in err and "is the orbit turning?" in err
        assert "orbitrig drives run" in err and "--hold" in err and "raise --timeout" in err
        code, _, err = _acquire("--adc", "socket://127.0.0.1:1")
        assert code == 2 and "cannot connect" in err and "is the A/D board (or `orbitrig sim`) serving there?" in err
        for bad in ("nan", "-1", "inf", "0"):
            code, _, err = _acquire("--adc", adc_url, "--timeout", bad)
            assert code == 2 and "Traceback" not in err and "--timeout" in err, (bad, err)
        code, _, err = _acquire("--adc", adc_url, "--target", "1", "--revolutions", "1")
        assert code == 2 and "min_revolutions >= 2" in err and "Traceback" not in err


def test_the_default_wait_scales_with_revolutions_and_orbit_period(monkeypatch):
    # 150 revolutions at 250 per wall second take 0.6 s; the wait for the first one is
    # cut to 0.3 s: only the part that scales with the measured period lets it finish
    monkeypatch.setattr(cli_acquire, "FIRST_WAIT_S", 0.3)
    with sim_in_thread() as url:
        r = CliRunner().invoke(app, ["acquire", "--adc", url, "--revolutions", "150", "--json"])
        assert r.exit_code == 0, r.output
        assert json.loads(r.stdout)["revolutions_used"] == 150
        # 1000 revolutions take 4 s: more than a stalled simulator's catch-up can deliver in 0.3 s
        r = CliRunner().invoke(app, ["acquire", "--adc", url, "--revolutions", "1000", "--timeout", "0.3"])
        assert r.exit_code == 2 and "of 1000 good revolutions within 0.3 s" in r.output


@pytest.mark.parametrize(
    "args, message",
    [
        (("--revolutions", "100000000000"), "--revolutions 100000000000: at most 10000"),
        (("--channels", "0"), "Invalid value for '--channels'"),
    ],
)
def test_counts_out_of_range_exit_2_before_the_link_opens(args, message):
    """An absurd count is refused (it once allocated for every revolution asked: a MemoryError
    traceback); the URL is one nothing serves, so reaching the link would say so instead."""
    code, out, err = _acquire("--adc", "socket://127.0.0.1:1", *args)
    assert code == 2 and message in err and "Traceback" not in err and out == ""
