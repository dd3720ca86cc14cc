"""`orbitrig sweep --sim` of a matrix with per-ratio revolutions or per-ratio adaptive targets:
every stored block averaged its own ratio's count, or stopped by its own ratio's target."""

from __future__ import annotations

from pathlib import Path

import h5py
import pytest
from support.cli_helpers import orbitrig
from support.sweep_helpers import demo_text

pytestmark = pytest.mark.timeout(300)


def sweep(tmp_path: Path, orbit_keys: str, extra: str = "") -> dict[str, tuple[int, str, int]]:
    """Run the demo point at ratios 1.2, 0.5, 0.8 (in that order) with these [orbit] keys;
    per stored block: (n_records, stop_reason, rows of raw_counts)."""
    text = demo_text("perratio").replace(
        "ratios = [0.3, 0.5, 0.7, 0.9, 1.2]", "ratios = [1.2, 0.5, 0.8]\n" + orbit_keys
    )
    path = tmp_path / "perratio.toml"
    path.write_text(text + extra)
    out = tmp_path / "run"
    p = orbitrig("sweep", "--sim", "--matrix", str(path), "--out", str(out), timeout=240)
    assert p.returncode == 0, p.stdout + p.stderr
    with h5py.File(out / "run.h5", "r") as f:
        assert f.attrs["status"] == "completed"
        return {
            tag: (int(b.attrs["n_records"]), str(b.attrs["stop_reason"]), b["raw_counts"].shape[0])
            for tag, b in f["points/0000/frequencies"].items()
        }


def test_each_block_averages_its_ratios_count(tmp_path):
    blocks = sweep(tmp_path, "revolutions = [14, 6, 9]")
    # tags number the ratios ascending: 00 = 0.5, 01 = 0.8, 02 = 1.2
    want = {"00": 6, "01": 9, "02": 14}
    assert sorted(blocks) == sorted(f"{k}_{d}" for k in want for d in ("fwd", "bwd"))
    for tag, (n, why, rows) in blocks.items():
        assert (n, why, rows) == (want[tag[:2]], "count", want[tag[:2]]), tag


def test_each_block_stops_at_its_ratios_target(tmp_path):
    blocks = sweep(
        tmp_path, "target_pct = [50, 0.001, 50]", "\n[averaging]\nmin_revolutions = 5\nmax_revolutions = 15\n"
    )
    assert len(blocks) == 6
    for tag, (n, why, rows) in blocks.items():
        assert 5 <= n <= 15 and rows == n and why in ("target", "max"), tag
        # ratio 0.5 (tag 00) cannot reach 0.001 %; 0.8 and 1.2 reach 50 % at the minimum
        assert (n, why) == ((15, "max") if tag.startswith("00") else (5, "target")), tag
