"""docs/catalog.md's ROSS example runs as written: on a simulated run in `runs/demo`, after
`orbitrig export runs/demo --format ross` (as the page says), its rotor is built from the
exported bearing and its modal analysis prints six log decrements. And the page's Signs: ROSS
spins the journal from +x towards +y as the rig does, so a bearing's cross-coupling goes across
unchanged. Measured on the page's example rotor: Kxy > 0, Kyx = -Kxy (the rig's forward-whirl
drive) takes damping from ROSS's forward mode and gives it to the backward one. (One file: ROSS's
import and first modal analysis take most of a minute, paid once.)"""

from __future__ import annotations

import contextlib
import io
import re
import warnings

import numpy as np
from typer.testing import CliRunner

from orbitrig.analysis.ross_elements import import_ross
from orbitrig.cli import app
from support.paths import ROOT


def test_the_ross_example_runs_verbatim(sim_run, tmp_path, monkeypatch):
    (code,) = re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "catalog.md").read_text(), re.S)
    assert 'bearing_elements("runs/demo/export/ross_bearings.json"' in code
    export = tmp_path / "runs" / "demo" / "export"  # the export of the run, beside it as `export` writes it
    res = CliRunner().invoke(app, ["export", str(sim_run), "--format", "ross", "--out", str(export)])
    assert res.exit_code == 0, res.output
    monkeypatch.chdir(tmp_path)
    printed = io.StringIO()
    with warnings.catch_warnings(), contextlib.redirect_stdout(printed):
        warnings.simplefilter("ignore")  # what the bearings' numbers warn of: tests/report/test_ross_*
        names: dict[str, object] = {}
        exec(compile(code, "docs/catalog.md, python", "exec"), names)
    last = printed.getvalue().strip().rsplit("[", 1)[-1]  # after ross' own notices: the printed array
    log_dec = np.array(last.rstrip("]").split(), dtype=float)
    assert log_dec.shape == (6,) and np.isfinite(log_dec).all(), printed.getvalue()[-500:]
    assert len(names["rotor"].bearing_elements) == 2  # type: ignore[attr-defined]  # nodes 0 and 6


def _first_pair(kxy: float) -> dict[str, float]:
    """Log decrement of the rotor's lowest forward and backward modes at 100 rad/s, the example's
    shaft and disk on two bearings of K = 33 MN/m, C = 100 kN s/m and cross-coupling kxy."""
    with contextlib.redirect_stdout(io.StringIO()):
        ross = import_ross()
    steel, d = ross.materials.steel, 0.0381
    shaft = [ross.ShaftElement(L=0.2, idl=0.0, odl=d, material=steel) for _ in range(6)]
    disk = ross.DiskElement.from_geometry(n=3, material=steel, width=0.07, i_d=d, o_d=0.3)
    bearings = [ross.BearingElement(n=n, kxx=3.3e7, kyy=3.3e7, kxy=kxy, kyx=-kxy, cxx=1e5, cyy=1e5) for n in (0, 6)]
    modal = ross.Rotor(shaft, [disk], bearings).run_modal(speed=100.0, num_modes=12)
    near = np.isclose(modal.wn, 117.8, rtol=0.01)  # the disk's first bending pair (the others: the film's)
    whirl = np.asarray(modal.whirl_direction())
    return {w: float(modal.log_dec[near & (whirl == w)][0]) for w in ("Forward", "Backward")}


def test_the_rigs_forward_whirl_drive_drives_rosss_forward_mode():
    plain, crossed = _first_pair(0.0), _first_pair(5.4e6)
    np.testing.assert_allclose([plain["Forward"], plain["Backward"]], 0.0097, atol=0.0005)
    assert crossed["Forward"] < plain["Forward"] - 0.003  # 0.0057 measured
    assert crossed["Backward"] > plain["Backward"] + 0.002  # 0.0125 measured
