"""A small run directory from synthetic data of known coefficients, written by the
sweep's own storage (orbitrig.store.writer.RunStore) along the sweep's data path
(plan -> blocks -> orbit tables -> identify -> results -> complete flag), without
the rig or the simulator: the fast stand-in for `orbitrig sweep --sim`."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from orbitrig import config as cfg
from orbitrig.run.identification import identify_operating_point
from orbitrig.run.plan import operating_points
from orbitrig.store.writer import BlockRecord, RunStore
from orbitrig.store.status import RunStatus

MATRIX = """
name = "synthetic"
description = "report tests: known coefficients, 0.1 % force noise"

[operating]
spin_rpm = [1000.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.25]
static_eccentricity = [{eps}]
dynamic_eccentricity = [0.04]

[orbit]
ratios = [0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.1, 1.2]
directions = ["forward", "backward"]

[[models]]
model = "kcd11"

[[models]]
model = "kc7"

[[models]]
model = "kcd11"
freq_dep = "power:1"

[[models]]
model = "kcd12"
freq_dep = "poly:8"
"""
# hydrostatic-bearing-like true coefficients (SI); D symmetric so kcd11 fits them exactly
K_TRUE = np.array([[3.3e7, 4.0e6], [-3.5e6, 3.1e7]])
C_TRUE = np.array([[5.2e4, 1.5e3], [1.5e3, 4.9e4]])
D_TRUE = np.array([[18.0, 2.0], [2.0, 21.0]])
# the strain-gauge system reads 1.8 % and 0.3 deg off the piezoelectric one (paper Fig. 4a)
STRAIN_GAIN = 1.018 * np.exp(1j * np.radians(0.3))
N_REV = 8


SAMPLES = 45  # per channel: 360 slots over 8 multiplexed channels
WAVE_NOISE = 0.03  # per-sample noise of one revolution, relative to the channel's amplitude


def _waveforms(ph, records, gains, wave_rng):
    """Raw counts (N, 8, S) of each revolution, q = dc + Re(q_r e^{i theta}) + noise, at the
    slots of a sequential 8-channel board; their average is the stored `mean` (as daq's)."""
    slots = np.arange(360, dtype=np.int16).reshape(SAMPLES, 8).T  # channel c: slots c, c + 8, ...
    theta = 2 * np.pi * slots / 360.0
    dc = 0.1 * np.abs(ph)
    values = dc[None, :, None] + np.real(records[:, :, None] * np.exp(1j * theta)[None])
    values += WAVE_NOISE * np.abs(ph)[None, :, None] * wave_rng.standard_normal(values.shape)
    counts = np.round(values / gains[None, :, None]).astype(np.int16)
    return slots, counts, counts.mean(axis=0) * gains[:, None]


def _record(block, radius, rng, noise, ch, gains, wave_rng) -> BlockRecord:
    w = abs(block.orbit)
    x = radius * (1 + 0.01 * rng.standard_normal())
    y = -1j * block.direction * radius * (1 + 0.01 * rng.standard_normal())
    z = K_TRUE + 1j * w * C_TRUE - w**2 * D_TRUE
    f = -z @ np.array([x, y])
    f = f + noise * np.abs(f).mean() * (rng.standard_normal(2) + 1j * rng.standard_normal(2))
    ph = np.zeros(8, complex)
    ph[[ch["x_a"], ch["x_b"]]] = x
    ph[[ch["y_a"], ch["y_b"]]] = y
    ph[[ch["fx_piezo"], ch["fy_piezo"]]] = f
    ph[[ch["fx_strain"], ch["fy_strain"]]] = f * STRAIN_GAIN
    records = ph[None, :] * (1 + 0.02 * rng.standard_normal((N_REV, 8)))
    for axis in ("fx", "fy"):  # both systems measure the same force in each revolution
        records[:, ch[f"{axis}_strain"]] = records[:, ch[f"{axis}_piezo"]] * STRAIN_GAIN
    slots, counts, mean = _waveforms(ph, records, gains, wave_rng)
    return BlockRecord(
        block=block,
        measured_orbit_speed=w,
        raw_counts=counts,
        slots=slots,
        gains=gains,
        offsets=np.zeros(8),
        mean=mean,
        record_phasors=records,
        phasors=ph,
        dc=0.1 * np.abs(ph),
        rms_residual=np.zeros(8),
        coherence=np.clip(0.995 - 0.04 * rng.random((2, 4)), 0, 1),
        stats={"frames_good": N_REV, "revolutions_used": N_REV},
    )


def write_synthetic_run(
    directory: Path,
    *,
    noise=1e-3,
    seed=1,
    n_points=2,
    incomplete=1,
    finished=True,
    provenance: dict | None = None,
    calibration: cfg.CalibrationUncertainty | None = None,
    record_text: str = "",
    scenario: tuple[str, str] = ("", ""),
) -> Path:
    """n_points complete operating points (static eccentricity 0, 0.15, ...) and
    `incomplete` more whose blocks are stored but which are never marked complete.
    finished=False leaves the run as a kill -9 does: status 'running', no run.h5.
    `calibration`: the rig's stated calibration uncertainty the sweep judges the fits with
    (uncertainty budget, combined LMS consistency); none by default. `record_text`: the
    calibration record's TOML text the run stores; `scenario`: the simulator scenario's
    (name, TOML text)."""
    directory = Path(directory)
    rng = np.random.default_rng(seed)
    wave_rng = np.random.default_rng(seed + 1000)  # waveforms only: the phasors stay as before
    total = n_points + incomplete
    step = 0.15 if total <= 6 else 0.9 / (total - 1)  # static eccentricity < 1 for a bench's 108 points
    eps = ", ".join(f"{step * i:g}" for i in range(total))
    rig = cfg.load_rig()
    matrix = cfg.matrix_from_text(MATRIX.format(eps=eps), "synthetic.toml")
    ch = rig.channel_index
    gains = np.asarray(rig.gains, dtype=float)
    store = RunStore.create(
        directory,
        rig_text=rig.text,
        matrix_text=matrix.text,
        matrix_name=matrix.name,
        sim=True,
        provenance=provenance,
        record_text=record_text,
        scenario_name=scenario[0],
        scenario_text=scenario[1],
        channels=[(c.name, c.unit) for c in rig.ordered_channels],
    )
    for point in operating_points(matrix, rig):
        store.begin_point(point)
        recs = []
        for block in point.blocks:
            recs.append(_record(block, point.orbit_radius, rng, noise, ch, gains, wave_rng))
            store.write_block(point.index, recs[-1])
        if point.index >= n_points:
            continue  # as after a kill -9: blocks stored, point never completed
        recs.sort(key=lambda r: (r.block.freq, -r.block.direction))
        n = len(recs)
        truth = {
            "orbit_hz": [r.block.orbit_hz for r in recs],
            "orbit": [r.block.orbit for r in recs],
            "K": [K_TRUE.tolist()] * n,
            "C": [C_TRUE.tolist()] * n,
            "D": [D_TRUE.tolist()] * n,
            "K0": K_TRUE.tolist(),
            "C0": C_TRUE.tolist(),
            "D0": D_TRUE.tolist(),
        }
        store.write_results(
            point.index, identify_operating_point(point.spin, recs, ch, matrix.models, truth, calibration)
        )
        store.complete_point(point.index)
    if finished:
        store.set_status(RunStatus.STOPPED if incomplete else RunStatus.COMPLETED, "synthetic run")
    return directory
