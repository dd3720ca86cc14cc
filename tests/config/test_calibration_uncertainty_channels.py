"""The stated calibration uncertainty has a table per A/D channel, its channels those of
fields.ChannelName (a channel added there and not here is refused at import), read and written as
before: a record already written loads, and a record written now has the same [uncertainty]
tables, key for key and in the same order."""

from __future__ import annotations

import math
import subprocess
import sys
import tomllib
from typing import get_args

import pytest

from orbitrig.config import CHANNEL_NAMES, CalibrationUncertainty, read_record, rig_from_text, write_record
from orbitrig.config.fields import ChannelName
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
"""


def test_a_channel_added_to_channel_name_without_its_field_is_refused_at_import():
    """ChannelName with a ninth channel and no field for it in CalibrationUncertainty: importing
    the module fails, naming the channel missing (not a channel with no uncertainty table)."""
    done = subprocess.run(
        [sys.executable, "-c", ADDED], cwd=ROOT, env=child_env(), capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 1, done.stdout
    assert "TypeError: CalibrationUncertainty: its fields after ['probe_sensitivity_pct']" in done.stderr
    assert "(missing ['z_c'], not a channel [])" in done.stderr


def test_the_fields_are_the_channels_of_channel_name_in_order():
    """The explicit fields (typed: a misspelt channel is a type error) are ChannelName's, in its
    order, after probe_sensitivity_pct: the TOML keys and their order."""
    assert tuple(CalibrationUncertainty.model_fields) == ("probe_sensitivity_pct", *get_args(ChannelName))
    stated = CalibrationUncertainty.model_validate({"x_a": {"gain_pct": 2.0}, "y_b": {"delay_us": 3.0}})
    assert (stated.x_a.gain, stated.channel("x_a").gain) == pytest.approx((0.02, 0.02))
    assert stated.channel("y_b") is stated.y_b
