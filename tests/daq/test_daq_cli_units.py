"""`orbitrig acquire` table: every row says its unit (N / m from the rig config, or counts) and channel name."""

from __future__ import annotations

import asyncio
import json
import math

import pytest

from sim.rig import SimRig

from support.cli_helpers import orbitrig_async
from support.paths import ROOT

pytestmark = pytest.mark.timeout(60)


async def test_rows_name_channel_and_unit():
    async with SimRig(speedup=20.0, can_channel=None) as rig:
        rig.local_control(spin=150.0, orbit=2 * math.pi * 12.5)
        await asyncio.sleep(0.05)
        code, out, err = await orbitrig_async(
            "acquire", "--adc", rig.adc_url, "--rig", str(ROOT / "config" / "rig.toml"), "--revolutions", "10"
        )
        assert code == 0, err
        lines = out.splitlines()
        assert lines[0].startswith("10 revolutions averaged, 0 dropped, frames bad 0")
        assert lines[1].split()[-2:] == ["unit", "name"]
        rows = [row.split() for row in lines[2:]]
        assert all(len(r[7].replace(".", "").lstrip("0")) <= 2 for r in rows), lines  # u %: 2 digits, not 3 decimals
        assert [row[-2:] for row in rows] == [
            ["N", "fx_piezo"],
            ["N", "fy_piezo"],
            ["N", "fx_strain"],
            ["N", "fy_strain"],
            ["m", "x_a"],
            ["m", "y_a"],
            ["m", "x_b"],
            ["m", "y_b"],
        ]
        code, out, err = await orbitrig_async(
            "acquire", "--adc", rig.adc_url, "--rig", str(ROOT / "config" / "rig.toml"), "--revolutions", "5", "--json"
        )
        assert code == 0, err
        assert [[c["unit"], c["name"]] for c in json.loads(out)["channels"]] == [r[-2:] for r in rows]
        code, out, err = await orbitrig_async("acquire", "--adc", rig.adc_url, "--revolutions", "5", "--counts")
        assert code == 0, err
        assert all(row.split()[-1] == "count" for row in out.splitlines()[2:])  # the unit as pint spells it
