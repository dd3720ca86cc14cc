"""A run made with a lab's own calibration record (one `orbitrig calibrate` wrote, not a shipped
one) stores its A/D channels' names and units, in run.json while it runs and in run.h5 after,
so that every reader can name them (the Python API's waveforms, the report's Fig. 4)."""

from __future__ import annotations

import dataclasses
import json

import pytest

from orbitrig import config as cfg
from orbitrig.analysis.signals import channel_map
from orbitrig.store.reader import read_run
from orbitrig.store.run_data import open_run

from support.rig_configs import LAB_RECORD, lab_record_config, loads_record
from support.store_checks import small_matrix
from support.cli_helpers import orbitrig

pytestmark = pytest.mark.timeout(240)


@pytest.fixture(scope="module")
def lab_run(tmp_path_factory):
    """(run directory, channel names, units) of a one-point --sim sweep in a lab of its own record."""
    tmp_path = tmp_path_factory.mktemp("lab_run")
    rig_path = lab_record_config(tmp_path / "lab", loads_record(1.0))
    rig = cfg.load_rig(rig_path)
    names = [c.name for c in rig.ordered_channels]
    units = [c.unit for c in rig.ordered_channels]
    assert len(names) == 8 and all(units)
    (tmp_path / "m.toml").write_text(small_matrix("lab", 8, spin_rpm=(1000.0,)))
    out = tmp_path / "run"
    args = ("sweep", "--sim", "--config", str(rig_path), "--matrix", str(tmp_path / "m.toml"), "--out", str(out))
    done = orbitrig(*args, "--speedup", "20", "--no-draw-figures", timeout=200, columns=None)
    assert done.returncode == 0, done.stderr
    return out, names, units


def test_a_run_with_a_lab_record_names_its_channels(lab_run):
    out, names, units = lab_run
    header = json.loads((out / "run.json").read_text())
    assert header["channels"] == names and header["channel_units"] == units
    run = read_run(out)
    assert run.channels == names and run.channel_units == units
    assert LAB_RECORD not in run.calibration_record_text  # the record's text, not its name
    assert 'step = "loads"' in run.calibration_record_text
    waves = open_run(out).waveforms(0)
    assert list(waves["channel"].values) == names
    assert waves["mean"].shape[1] == 8


def test_a_run_stored_without_channel_names_is_named_from_its_stored_record(lab_run):
    """Runs stored before the channels were passed on have none: the report names them from
    the stored rig configuration and the record stored with it, not the lab's folder."""
    out, names, _ = lab_run
    run = dataclasses.replace(read_run(out), channels=[], channel_units=[])
    assert channel_map(run) == {name: i for i, name in enumerate(names)}
