"""The trend history of one rig for the page's charts, in bounded memory.

From the service's ``live`` payloads (up to 5 a second) :class:`TrendHistory` takes one
sample every ``period`` s: speeds (rpm), torques (percent), pressures (Pa),
temperatures (K), flow (m^3/s) and the pressure ratio, as the payload states them.
It keeps two views, both bounded whatever the run's length (a month is fine):

- ``recent``: every sample of the last ``recent_s`` s (a ring);
- ``run``: the whole run in at most ``run_cap`` samples, each the mean of the samples
  of its ``run_step`` s (time: the first one's); when full, neighbouring samples are
  merged pairwise and ``run_step`` doubles.

A new ``run_id`` starts a new run view (the recent ring goes on).
"""

from __future__ import annotations

import collections
import math
from typing import Any

#: The quantities of a sample: name -> (where in the live payload, key).
TREND_KEYS: dict[str, tuple[str, ...]] = {
    "spin_rpm": ("drives", "spin", "actual_rpm"),
    "spin_set_rpm": ("drives", "spin", "reference_rpm"),
    "orbit_rpm": ("drives", "orbit", "actual_rpm"),
    "orbit_set_rpm": ("drives", "orbit", "reference_rpm"),
    "torque_spin": ("drives", "spin", "torque_pct"),
    "torque_orbit": ("drives", "orbit", "torque_pct"),
    **{
        k: ("aux", k)
        for k in (
            "p_supply",
            "p_recess_1",
            "p_recess_2",
            "p_recess_3",
            "p_recess_4",
            "t_supply",
            "t_recess",
            "t_groove",
            "flow",
            "beta",
        )
    },
}


def sample_of(live: dict[str, Any], t: float) -> dict[str, float | None]:
    """One trend sample (``t``: wall clock, s since the epoch) of a live payload."""
    out: dict[str, float | None] = {"t": round(t, 3)}
    for name, path in TREND_KEYS.items():
        v: Any = live
        for key in path:
            v = v.get(key) if isinstance(v, dict) else None
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        out[name] = float(f"{v:.6g}") if ok else None  # 6 digits: more than any sensor gives
    return out


def _mean(samples: list[dict]) -> dict:
    """One sample for ``samples``: the first time, each value's mean over the samples that have it."""
    out: dict[str, float | None] = {"t": samples[0]["t"]}
    for k in TREND_KEYS:
        values = [v for s in samples if (v := s.get(k)) is not None]
        out[k] = sum(values) / len(values) if values else None
    return out


class TrendHistory:
    """Recent samples and the whole run's, each bounded (see the module docstring)."""

    def __init__(self, period: float = 1.0, recent_s: float = 1800.0, run_cap: int = 720):
        self.period, self.run_cap = period, run_cap
        self.recent: collections.deque[dict] = collections.deque(maxlen=max(1, int(recent_s / period)))
        self.run: list[dict] = []
        self.run_id: str | None = None
        self.run_step = period  # s between the run view's samples
        self.step_samples: list[dict] = []  # the samples of the run view's newest step
        self.last_sample_s = -math.inf  # when the last sample was taken (s, as ``now``)

    def add(self, live: dict[str, Any], now: float) -> dict | None:
        """Take a sample of ``live`` at ``now`` (s) when ``period`` has passed; the sample or None."""
        run_id = live.get("run_id")
        if run_id != self.run_id:
            self.run_id, self.run, self.run_step, self.step_samples = run_id, [], self.period, []
        if now - self.last_sample_s < self.period * 0.95:
            return None
        self.last_sample_s = now
        sample = sample_of(live, now)
        self.recent.append(sample)
        if self.step_samples and sample["t"] - self.step_samples[0]["t"] >= self.run_step * 0.95:
            self.run.append(_mean(self.step_samples))
            self.step_samples = []
        self.step_samples.append(sample)
        if len(self.run) >= self.run_cap:
            pairs = zip(self.run[0::2], self.run[1::2])
            self.run = [_mean([a, b]) for a, b in pairs] + (self.run[-1:] if len(self.run) % 2 else [])
            self.run_step *= 2
        return sample

    def history(self) -> dict[str, Any]:
        """Both views for a newly connected page."""
        run = self.run + ([_mean(self.step_samples)] if self.step_samples else [])
        return {"run_id": self.run_id, "run_step_s": self.run_step, "recent": list(self.recent), "run": run}

    def seed(self, other: TrendHistory) -> None:
        """Start from another session's history of the same rig (a sign-in in the middle of a run)."""
        self.recent.extend(other.recent)
        self.run, self.run_id, self.run_step, self.last_sample_s = (
            list(other.run),
            other.run_id,
            other.run_step,
            other.last_sample_s,
        )
        self.step_samples = list(other.step_samples)
