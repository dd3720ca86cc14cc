"""Each block's spin turns per board revolution, the ratio its runout is placed with (run.h5's
/points/PPPP/runout_turns, docs/storage.md), in every export where per-block data lives, each
field with its unit (pint parses it) and description, read with the readers a lab uses: scipy.io
and GNU Octave (.mat), npTDMS (.tdms), h5py and GNU Octave (.h5), csv."""

from __future__ import annotations

import csv
import json
import math

import h5py
import numpy as np
import pytest
from nptdms import TdmsFile
from scipy.io import loadmat

from orbitrig.store import export_content as content
from orbitrig.store.export import export_run
from support.octave import octave_eval
from support.units import UREG

NUMBERS = ("orbit_hz", "direction", "commanded", "fitted", "u", "used")
UNITS = {"orbit_hz": "Hz", "direction": "1", "commanded": "1", "fitted": "1", "u": "1", "resolved": "1", "used": "1"}


@pytest.fixture(scope="module")
def stored(sim_run):
    """run.h5's runout_turns of point 0000, read with h5py."""
    with h5py.File(sim_run / "run.h5", "r") as f:
        turns = json.loads(f["points/0000/runout_turns"].attrs["json"])
        rows = f["points/0000/table/piezo/orbit"].shape[0]
    assert len(turns["used"]) == rows == 10 and all(isinstance(u, float) for u in turns["used"])
    # both kinds of block: fitted, and not (near a ratio of 1 a revolution's spin and orbit content
    # are too alike to tell apart: no spin harmonic stands out of its noise)
    assert any(turns["unfitted"]) and not all(turns["unfitted"])
    return turns


@pytest.fixture(scope="module")
def exported(sim_run, tmp_path_factory):
    out = tmp_path_factory.mktemp("export_turns")
    for fmt in ("csv", "mat", "tdms", "h5"):
        export_run(sim_run, fmt, out)
    return out


def _numbers(values) -> np.ndarray:
    return np.array([math.nan if v is None else float(v) for v in values])


def _same(got: dict, stored: dict) -> None:
    """Every field equal to the last bit (None: NaN), resolved as 1/0, unfitted as text."""
    for name in NUMBERS:
        np.testing.assert_array_equal(np.ravel(got[name]).astype(float), _numbers(stored[name]), err_msg=name)
    assert [int(v) for v in np.ravel(got["resolved"])] == [int(v) for v in stored["resolved"]]
    texts = [v if isinstance(v, str) else "" for v in got["unfitted"]]  # loadmat: an empty text as []
    assert [t.strip() for t in texts] == stored["unfitted"]


def test_mat_carries_each_blocks_spin_turns_with_units(exported, stored):
    p = loadmat(exported / "run.mat", simplify_cells=True)["points"]["p0000"]
    _same(p["runout_turns"], stored)
    assert p["runout_turns_units"] | {"unfitted": ""} == UNITS | {"unfitted": ""}
    assert "runout is placed with" in p["runout_turns_description"]["used"]
    for unit in UNITS.values():
        UREG.parse_units(unit)


def test_tdms_carries_each_blocks_spin_turns_with_units(exported, stored):
    group = TdmsFile.read(exported / "run.tdms")["runout_turns 0000"]
    got = {c.name: c[:] for c in group.channels()}
    _same(got, stored)
    for c in group.channels():
        assert c.properties["unit_string"] == UNITS.get(c.name, ""), c.name
        assert c.properties["description"], c.name


def test_h5_export_carries_each_blocks_spin_turns_as_datasets(exported, stored):
    with h5py.File(exported / "run.h5", "r") as f:
        g = f["points/0000/runout_turns"]
        got = {k: g[k][()] for k in g}
        _same(got | {"unfitted": g["unfitted"].asstr()[()]}, stored)
        assert g["unfitted"].dtype.kind == "S" and g["resolved"].dtype == np.uint8  # Octave reads both
        for name, unit in UNITS.items():
            assert g[name].attrs["units"] == unit and g[name].attrs["description"], name
        assert json.loads(g.attrs["json"]) == stored


def test_csv_carries_each_blocks_spin_turns_with_units(exported, stored):
    with open(exported / "runout_turns_0000.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    assert set(rows[0]) == {*(f"{k} [{u}]" for k, u in UNITS.items()), "unfitted"}  # a number's unit in its header
    columns = {h.split(" [")[0]: [r[i] for r in rows[1:]] for i, h in enumerate(rows[0])}
    _same({k: [v if v else "nan" for v in vs] for k, vs in columns.items() if k != "unfitted"}
          | {"unfitted": columns["unfitted"]}, stored)  # fmt: skip


def test_octave_reads_each_blocks_spin_turns(exported, stored, tmp_path):
    """One octave-cli start: the .mat's and the .h5 export's used ratios, to the last bit, and the
    units Octave finds beside them."""
    script = (
        f"m = load('{exported / 'run.mat'}'); t = m.points.p0000.runout_turns;\n"
        "printf('mat %.17g %d\\n', [t.used(:) double(t.resolved(:))]');\n"
        "printf('matunit %s\\n', m.points.p0000.runout_turns_units.used);\n"
        f"x = load('{exported / 'run.h5'}'); g = x.points._0000.runout_turns;\n"
        "printf('h5 %.17g %d\\n', [g.used(:) double(g.resolved(:))]');\n"
        "printf('h5unit %s\\n', x.attributes.points._0000.runout_turns.used.units);\n"
    )
    done = octave_eval(script, tmp_path)
    assert done.returncode == 0 and "warning" not in done.stderr, done.stdout[-2000:] + done.stderr[-2000:]
    rows: dict[str, list[str]] = {}
    for line in done.stdout.splitlines():
        key, _, rest = line.partition(" ")
        rows.setdefault(key, []).append(rest)
    want = [(u, int(r)) for u, r in zip(stored["used"], stored["resolved"])]
    for key in ("mat", "h5"):
        assert [(float(a), int(b)) for a, b in (r.split() for r in rows[key])] == want, key
    assert rows["matunit"] == ["1"] and rows["h5unit"] == ["1"]


def test_a_later_csv_export_removes_an_earlier_ones_runout_turns_file(sim_run, tmp_path):
    """An earlier csv export's runout_turns_PPPP.csv of a point no longer exported is removed as
    its point_PPPP_<lms>.csv is (csv_manifest.txt)."""
    export_run(sim_run, "csv", tmp_path)
    (tmp_path / "runout_turns_0007.csv").write_text("orbit_hz [Hz]\n5.0\n")  # as of a point 0007 exported before
    manifest = tmp_path / "csv_manifest.txt"
    manifest.write_text(manifest.read_text() + "runout_turns_0007.csv\n")
    done = export_run(sim_run, "csv", tmp_path)
    assert not (tmp_path / "runout_turns_0007.csv").exists(), done.selection.notes
    assert (tmp_path / "runout_turns_0000.csv").is_file()


def test_a_block_without_a_fitted_ratio_exports_nan_and_says_why():
    """None (not fitted) is NaN, resolved 1/0, unfitted the text; a point of an earlier run: none."""
    turns = {
        "orbit_hz": [5.0, 5.0], "direction": [1, -1], "commanded": [2.0, 2.0], "fitted": [2.004, None],
        "u": [1e-4, None], "resolved": [True, False], "used": [2.004, 2.0], "unfitted": ["", "no samples"],
    }  # fmt: skip
    cols = content.runout_turns_columns(turns)
    assert list(cols) == list(content.RUNOUT_TURNS)
    assert np.isnan(cols["fitted"][0][1]) and np.isnan(cols["u"][0][1]) and cols["fitted"][0][0] == 2.004
    assert cols["resolved"][0].tolist() == [1, 0] and cols["unfitted"][0].tolist() == ["", "no samples"]
    assert {k: u for k, (_, u) in cols.items()} == UNITS | {"unfitted": ""}
    assert content.runout_turns_columns(None) == {}
