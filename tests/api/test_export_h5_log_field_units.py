"""The h5 export's logs state their units as run.h5's do (docs/storage.md): GNU Octave reads
a compound log as zeros, so the export writes each log as a group with one dataset per field;
each such dataset (``/logs/can/p_supply``) has its own ``description`` and, when numeric,
``units`` (the field's unit in run.h5's ``field_units``), as every numeric dataset of run.h5
has, and those attributes are mirrored under ``/attributes`` like every other one. Read with
h5py and pint, as a lab reads it."""

from __future__ import annotations

import h5py
import numpy as np
import pint
import pytest

from orbitrig.store.export import export_run

UREG = pint.UnitRegistry()


@pytest.fixture(scope="module")
def exported(sim_run, tmp_path_factory):
    out = tmp_path_factory.mktemp("export_h5_logs")
    export_run(sim_run, "h5", out)
    return out


def test_h5_export_log_fields_state_their_units(exported, sim_run):
    with h5py.File(sim_run / "run.h5", "r") as run, h5py.File(exported / "run.h5", "r") as f:
        for log in ("events", "commands", "can", "drives"):
            stored = run[f"logs/{log}"]
            fields = list(stored.attrs["fields"].astype(str))
            for name, unit in zip(fields, stored.attrs["field_units"].astype(str)):
                ds = f[f"logs/{log}/{name}"]
                assert ds.attrs["description"], f"/logs/{log}/{name}: no description"
                if ds.dtype.kind in "biuf":
                    assert ds.attrs.get("units") == unit, f"/logs/{log}/{name}: units {ds.attrs.get('units')!r}"
                    UREG.parse_units(unit)
                else:  # text: no unit, as every text dataset
                    assert "units" not in ds.attrs, f"/logs/{log}/{name}"
        p = f["logs/can/p_supply"]
        supply = UREG.Quantity(np.nanmax(p[()]), p.attrs["units"]).to("MPa").magnitude  # the supply at about 1.2 MPa
        assert p.attrs["units"] == "Pa" and 0.5 < supply < 5.0
        assert f["logs/drives/spin_act"].attrs["units"] == "rad/s"
        # the new attributes are mirrored for GNU Octave's load, as every attribute is
        assert f["attributes/logs/can/p_supply/units"][()] == b"Pa"
