"""Live acquisition rate over a pty, with zero loss: AdcReader.acquire end to end.

Two sources, each in its own process (the reader has this process's core):
  sim     the simulator (SimRig) streaming its A/D board to a pty at a high
          speed-up: the real path, limited by how fast the simulator makes data
  writer  a plain writer replaying pre-encoded frames into a pty as fast as the
          pty takes them: the reader's own ceiling

Prints samples/s of good revolutions averaged and the loss counts (revolutions
dropped, frames bad, bytes skipped, link drops; for the simulator also the
frames its board lost because the pty backed up).

    python3 -m bench.bench_daq_live [--seconds 4] [--speedup 10] [--speedup-sequential 80] [--orbit-hz 50]
Target: zero loss from both sources, and the reader's ceiling (the writer source) >= 1 million
samples/s; exit 1 otherwise.
"""

from __future__ import annotations

import argparse
import asyncio
import math
import multiprocessing as mp
import os
import select
import sys
import time
import tty

import numpy as np

from daq.adc import AdcReader
from tests.support.daq_encoder import SIMULTANEOUS, TRIGGER, frame


# ------------------------------------------------------------------ sources
def sim_source(conn, mode: str, speedup: float, orbit_hz: float) -> None:
    from sim.config import SimConfig
    from sim.rig import SimRig

    async def run() -> None:
        cfg = SimConfig()
        cfg.adc.mode = mode
        async with SimRig(cfg, speedup=speedup, can_channel=None) as rig:
            rig.local_control(spin=2 * math.pi * 30, orbit=2 * math.pi * orbit_hz)
            conn.send(rig.adc_pty_path)
            loop = asyncio.get_running_loop()
            marks = []
            while True:
                msg = await loop.run_in_executor(None, conn.recv)
                marks.append((rig.board.frames_lost, rig.adc_server.pty.chunks_dropped))
                if msg == "stop":
                    break
            conn.send(marks)

    asyncio.run(run())


def writer_source(conn, mode: str, frame_slots: int = 45) -> None:
    """Replays 64 random revolutions as frames (seq, rev, clock counting on) into a
    pty, as fast as the pty takes them (it blocks the writer: no loss on this side)."""
    master, slave = os.openpty()
    tty.setraw(slave)
    os.set_blocking(master, False)
    conn.send(os.ttyname(slave))
    n_ch = 8 if mode == "simultaneous" else 1
    rng = np.random.default_rng(0)
    revs = [rng.normal(0, 2000, (360, n_ch)).astype("<i2") for _ in range(64)]
    flag_mode = SIMULTANEOUS if mode == "simultaneous" else 0
    period_us, seq, r = 20_000, 0, 0
    pending = memoryview(b"")
    while True:
        if not pending:
            out = []
            for _ in range(32):
                samples = revs[r % len(revs)]
                for fs in range(0, 360, frame_slots):
                    ns = min(frame_slots, 360 - fs)
                    flags = (TRIGGER if fs == 0 else 0) | flag_mode
                    t_us = r * period_us + fs * period_us // 360
                    out.append(frame(flags, seq, r, fs, samples[fs : fs + ns], t_us))
                    seq += 1
                r += 1
            pending = memoryview(b"".join(out))
        readable, writable, _ = select.select([conn], [master], [], 1.0)
        if readable and conn.recv() == "stop":
            break
        if writable:
            try:
                pending = pending[os.write(master, pending) :]
            except BlockingIOError:
                pass
    conn.send([])
    os.close(master)
    os.close(slave)


# ------------------------------------------------------------------ reader
async def measure(
    path: str, mode: str, seconds: float, expected_revs_per_s: float | None, conn
) -> tuple[float, object, float]:
    channels = 8
    spr = 360 * (channels if mode == "simultaneous" else 1)
    async with AdcReader(path, channels=channels, mode=mode) as adc:
        await adc.acquire(20, timeout=20)  # warm-up: the link runs, speed is reached
        if expected_revs_per_s is None:  # calibrate the rate
            t0 = time.perf_counter()
            await adc.acquire(200, timeout=30)
            expected_revs_per_s = 200 / (time.perf_counter() - t0)
        n = max(50, int(expected_revs_per_s * seconds))
        conn.send("mark")
        t0 = time.perf_counter()
        block = await adc.acquire(n, timeout=seconds * 10 + 10)
        elapsed = time.perf_counter() - t0
        conn.send("stop")
    return n * spr / elapsed, block, elapsed


def run_source(target, args, mode, seconds, expected):
    ctx = mp.get_context("spawn")
    parent, child = ctx.Pipe()
    proc = ctx.Process(target=target, args=(child, *args), daemon=True)
    proc.start()
    try:
        path = parent.recv()
        rate, block, elapsed = asyncio.run(measure(path, mode, seconds, expected, parent))
        marks = parent.recv()
    finally:
        proc.join(5)
        if proc.is_alive():
            proc.terminate()
    src_lost = None
    if len(marks) == 2:
        src_lost = (marks[1][0] - marks[0][0], marks[1][1] - marks[0][1])
    return rate, block, elapsed, src_lost


def report(name, rate, block, elapsed, src_lost) -> bool:
    """Zero loss: every revolution the board numbered inside the window was averaged
    (the block's rev numbers are consecutive), and nothing was bad or skipped."""
    stats = block.stats
    span = int((block.revs[-1] - block.revs[0]) & 0xFFFFFFFF) + 1
    missing = span - len(block.revs)
    loss = missing + stats.revolutions_dropped + stats.frames_bad + stats.bytes_skipped + stats.link_drops
    extra = ""
    if src_lost is not None:
        extra = f"; simulator during the run: board frames lost {src_lost[0]}, pty chunks dropped {src_lost[1]}"
    print(
        f"  {name}: {rate / 1e6:6.2f} M samples/s over {elapsed:.1f} s, {stats.revolutions_used} revolutions "
        f"of {span} numbered; dropped {stats.revolutions_dropped} {stats.drop_reasons or ''}, "
        f"frames bad {stats.frames_bad}, bytes skipped {stats.bytes_skipped}, link drops {stats.link_drops}"
        f"{extra} -> {'zero loss' if loss == 0 else 'LOSS'}"
    )
    return loss == 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=4.0)
    ap.add_argument("--speedup", type=float, default=10.0, help="simulator speed-up, simultaneous mode")
    ap.add_argument("--speedup-sequential", type=float, default=80.0)
    ap.add_argument("--orbit-hz", type=float, default=50.0, help="orbit frequency in simulated time")
    args = ap.parse_args()
    print(f"live over a pty, AdcReader.acquire end to end ({args.seconds:g} s per run)")
    speedup = {"simultaneous": args.speedup, "sequential": args.speedup_sequential}
    ok: list[bool] = []
    for mode in ("simultaneous", "sequential"):
        result = run_source(
            sim_source, (mode, speedup[mode], args.orbit_hz), mode, args.seconds, args.orbit_hz * speedup[mode]
        )
        ok.append(report(f"simulator {mode:12s} x{speedup[mode]:g} at {args.orbit_hz:g} Hz", *result))
    for mode in ("simultaneous", "sequential"):
        result = run_source(writer_source, (mode,), mode, args.seconds, None)
        ok.append(report(f"own writer {mode:12s}", *result) and result[0] >= 1e6)
    print("target: zero loss from both sources; the own writer >= 1 M samples/s")
    return 0 if all(ok) else 1


if __name__ == "__main__":
    sys.exit(main())
