"""Per-point identification time of the paper matrix's models, with the uncertainty budget,
model adequacy, LMS consistency and derived quantities (orbitrig.run.point_analysis).

One operating point of config/matrices/paper.toml (10 orbit frequencies, forward and
backward, 50 revolutions each) simulated revolution by revolution with the default
simulator scenario and kept as the board gives it (counts of the simulator's channel gains,
from which each block's spin ratio is fitted); both load measuring systems; the rig.toml
calibration uncertainty. Prints the median wall time of `identify_operating_point` (what the
engine runs in its worker thread per point; per block) and of the bare identifications alone.

    python3 -m bench.bench_point_analysis
"""

from __future__ import annotations

import statistics
import time

import numpy as np


from orbitrig import config as cfg
from orbitrig.config import LMS
from orbitrig.run.identification import identify_operating_point, orbit_table
from orbitrig.run.plan import make_plan
from orbitrig.store.records import BlockRecord
from reduction.identify import identify
from sim.config import CHANNEL_GAINS, SimConfig
from sim.physics import RigPhysics
from sim.revolutions import revolution_phasors, simulate_revolutions

REPEATS = 7


def point_records(rig, point, revolutions: int = 50) -> list[BlockRecord]:
    ph = RigPhysics(SimConfig())
    ph.set_manual(orbit_radius=point.orbit_radius)
    recs = []
    gains = np.asarray(CHANNEL_GAINS)
    for b in point.blocks:
        slots, simulated = simulate_revolutions(ph, point.spin, b.orbit, revolutions)
        counts = np.round(simulated / gains[None, :, None]).astype(np.int16)  # as the board gives them
        values = counts * gains[None, :, None]
        rp = revolution_phasors(slots, values)
        empty = np.zeros(len(gains))
        recs.append(
            BlockRecord(
                block=b,
                measured_orbit_speed=abs(b.orbit),
                raw_counts=counts,
                slots=slots,
                gains=gains,
                offsets=empty,
                mean=values.mean(axis=0),
                record_phasors=rp,
                phasors=rp.mean(axis=0),
                dc=empty,
                rms_residual=empty,
                coherence=np.full((2, 4), 0.95),
                revolutions=np.arange(revolutions),
            )
        )
    return recs


def median_time(fn) -> float:
    times = []
    for _ in range(REPEATS):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    rig = cfg.load_rig()
    plan = make_plan(cfg.load_matrix(cfg.default_matrix_path("paper")), rig)
    point, models = plan.points[0], plan.matrix.models
    recs = point_records(rig, point)
    ch = rig.channel_index
    tables = {lms: orbit_table(point.spin, recs, ch, lms) for lms in LMS}

    def bare():
        for lms in LMS:
            for m in models:
                identify(tables[lms], model=m.model, freq_dep=m.freq_dep, method=m.method)

    full = median_time(
        lambda: identify_operating_point(point.spin, recs, ch, models, None, rig.calibration_uncertainty)
    )
    plain = median_time(bare)
    names = ", ".join(f"{m.model} {m.freq_dep}" for m in models)
    print(f"paper point 0000: {len(point.blocks)} blocks, models {names}, 2 load measuring systems")
    print(f"identifications alone ({2 * len(models)} fits):           {plain * 1e3:7.1f} ms")
    print(f"identify_operating_point (fits + budget, adequacy, LMS consistency, derived): {full * 1e3:7.1f} ms")
    print(f"  per block: {full * 1e3 / len(recs):.2f} ms")
    print(f"per point x {len(plan.points)} points: {full * len(plan.points):.1f} s of worker-thread time")


if __name__ == "__main__":
    main()
