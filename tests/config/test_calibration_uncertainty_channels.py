"""The stated calibration uncertainty has a table per A/D channel, its channels those of
fields.ChannelName (one owner: a channel added there has its table here), read and written as
before: a record already written loads, and a record written now has the same [uncertainty]
tables, key for key and in the same order."""

from __future__ import annotations

import math
import subprocess
import sys
import tomllib

import pytest

from orbitrig.config import CHANNEL_NAMES, CalibrationUncertainty, read_record, rig_from_text, write_record
from orbitrig.config.toml_out import render

from support.cli_helpers import child_env
from support.paths import ROOT

SHIPPED_RECORD = "2026-11-26T214732Z-initial"


def _section(text: str, table: str) -> str:
    """The lines of `text` from ``[table]`` to the next table not under it."""
    lines = text.splitlines()
    start = lines.index(f"[{table}]")
    end = next(
        (i for i in range(start + 1, len(lines)) if lines[i].startswith("[") and not lines[i].startswith(f"[{table}.")),
        len(lines),
    )
    return "\n".join(lines[start:end]).strip()


def test_a_record_written_before_loads_and_is_written_again_table_for_table(tmp_path):
    folder = ROOT / "config" / "calibration"
    record, text = read_record(folder, SHIPPED_RECORD)  # its seal checked: the text as written then
    stated = record.uncertainty
    assert stated.probe_sensitivity == pytest.approx(0.01)
    assert stated.channel("fx_strain").gain == pytest.approx(0.025)
    assert stated.channel("fy_piezo").phase == pytest.approx(math.radians(0.05))
    assert stated.channel("y_b").delay == pytest.approx(10e-6)
    _, again = write_record(tmp_path, record)
    assert _section(again, "uncertainty") == _section(text, "uncertainty")
    assert list(tomllib.loads(text)["uncertainty"]) == ["probe_sensitivity_pct", *CHANNEL_NAMES]


def test_every_channel_reads_its_own_table_of_rig_toml():
    """Each channel of ChannelName a different gain, phase and delay in rig.toml's
    [calibration_uncertainty]: channel(name) gives that channel's, SI; another name is a KeyError."""
    shipped = (ROOT / "config" / "rig.toml").read_text()  # its [calibration_uncertainty] ends the file
    head = shipped[: shipped.index("[calibration_uncertainty]")].replace(
        "calibration_record =", "# calibration_record ="
    )
    tables = {
        name: {"gain_pct": 0.1 * (i + 1), "phase_deg": 0.01 * (i + 1), "delay_us": float(i + 1)}
        for i, name in enumerate(CHANNEL_NAMES)
    }
    rig = rig_from_text(head + render({"calibration_uncertainty": {"probe_sensitivity_pct": 0.7, **tables}}))
    assert rig.calibration_record is None  # no record's table in its place
    stated = rig.calibration_uncertainty
    assert stated is not None
    assert stated.probe_sensitivity == pytest.approx(0.007)
    for i, name in enumerate(CHANNEL_NAMES):
        c = stated.channel(name)
        assert (c.gain, c.phase, c.delay) == pytest.approx(
            (0.001 * (i + 1), math.radians(0.01 * (i + 1)), 1e-6 * (i + 1))
        )
    with pytest.raises(KeyError):
        stated.channel("probe_sensitivity_pct")
    assert CalibrationUncertainty().channel("x_a").gain == 0.0  # a channel left out: zero


ADDED = """
import typing
from importlib import reload
import orbitrig.config.fields as fields
fields.ChannelName = typing.Literal[(*typing.get_args(fields.ChannelName), "z_c")]
fields.CHANNEL_NAMES = typing.get_args(fields.ChannelName)
import orbitrig.config.calibration as calibration
reload(calibration)
stated = calibration.CalibrationUncertainty.model_validate({"z_c": {"gain_pct": 3.0}, "x_a": {"delay_us": 4.0}})
print(stated.channel("z_c").gain, stated.channel("x_a").delay, list(stated.model_dump())[-1])
"""


def test_a_channel_added_to_channel_name_has_its_table():
    """ChannelName with a ninth channel: the stated uncertainty takes its table and channel()
    finds it, with no line of orbitrig/config/calibration.py changed."""
    done = subprocess.run(
        [sys.executable, "-c", ADDED], cwd=ROOT, env=child_env(), capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["0.03", "4e-06", "z_c"]
