"""Shared helpers of the sweep tests: small matrices and a run on the real simulator."""

from __future__ import annotations

import asyncio
import sys
from pathlib import Path

from orbitrig import config as cfg

ROOT = Path(__file__).resolve().parents[2]
SPEEDUP = 40.0


def small_matrix(revolutions: int = 10, **operating) -> cfg.MatrixConfig:
    """The demo matrix with fewer revolutions per block (and other operating values)."""
    text = cfg.default_matrix_path("demo").read_text()
    text = text.replace('name = "demo"', f'name = "small"\nrevolutions = {revolutions}')
    for key, values in operating.items():
        lines = [ln for ln in text.splitlines() if ln.startswith(f"{key} =")]
        text = text.replace(lines[0], f"{key} = {values!r}")
    return cfg.matrix_from_text(text, "small.toml")


def orbitrig_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "orbitrig", *args]


async def wait_for(predicate, timeout: float = 30.0, what: str = "condition") -> None:
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while not predicate():
        if loop.time() > end:
            raise AssertionError(f"timed out waiting for {what}")
        await asyncio.sleep(0.01)

