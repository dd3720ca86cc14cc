"""docs/catalog.md, ROSS export, Signs: ROSS spins the journal from +x towards +y as the rig
does, so a bearing's cross-coupling goes across unchanged. Measured on the page's example rotor:
Kxy > 0, Kyx = -Kxy (the rig's forward-whirl drive) takes damping from ROSS's forward mode and
gives it to the backward one."""

from __future__ import annotations

import contextlib
import io

import numpy as np

from orbitrig.analysis.ross_elements import import_ross


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
