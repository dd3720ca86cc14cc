"""In-process throughput of the acquisition pipeline: decode + assemble + average.

Frames are made once (by the tests' encoder written from the spec, tests/support/daq_encoder.py),
then the byte stream is fed in chunks through FrameDecoder -> RevolutionAssembler
-> StreamingAverager on one core. Prints samples per second for several board
layouts with the paper's fixed rule (50 revolutions), and for the simulator's
layout with an adaptive rule (per-revolution phasors and running uncertainty
checked on every revolution), and the loss counts (zero on a clean stream).

    python3 -m bench.bench_daq_decode [--revolutions 4000] [--chunk 65536]
Target: >= 10 million samples/s.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from daq.averaging_rule import AveragingRule
from daq.averager import StreamingAverager
from daq.frames import FrameDecoder
from daq.revolutions import RevolutionAssembler
from tests.support.daq_encoder import SIMULTANEOUS, TRIGGER, frame


def make_stream(n_revs: int, channels: int, mode: str, frame_slots: int, seed: int = 1) -> bytes:
    rng = np.random.default_rng(seed)
    n_ch = channels if mode == "simultaneous" else 1
    flag_mode = SIMULTANEOUS if mode == "simultaneous" else 0
    # a few distinct revolutions, repeated (encoding speed is not what is measured)
    revs = rng.normal(0, 3000, (8, 360, n_ch)).astype("<i2")
    out, seq = [], 0
    for r in range(n_revs):
        t_rev = r * 80_000
        samples = revs[r % 8]
        for fs in range(0, 360, frame_slots):
            ns = min(frame_slots, 360 - fs)
            flags = (TRIGGER if fs == 0 else 0) | flag_mode
            out.append(frame(flags, seq, r, fs, samples[fs : fs + ns], t_rev + fs * 80_000 // 360))
            seq += 1
    return b"".join(out)


def run(
    data: bytes, channels: int, mode: str, chunk: int, rule: AveragingRule = AveragingRule.fixed(50)
) -> tuple[float, dict]:
    dec, asm, avg = FrameDecoder(), RevolutionAssembler(channels, mode), StreamingAverager(rule)
    blocks = 0
    t0 = time.perf_counter()
    for i in range(0, len(data), chunk):
        blocks += len(avg.push_batch(asm.push_batch(dec.feed_batch(data[i : i + chunk]))))
    blocks += len(avg.push_batch(asm.flush()))
    dt = time.perf_counter() - t0
    return dt, dict(
        revolutions=asm.revolutions_good,
        blocks=blocks,
        frames_good=dec.frames_good,
        frames_bad=dec.frames_bad,
        bytes_skipped=dec.bytes_skipped,
        revolutions_dropped=asm.revolutions_dropped,
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--revolutions", type=int, default=4000)
    ap.add_argument("--chunk", type=int, default=1 << 16, help="bytes per feed (one link read)")
    args = ap.parse_args()
    print(f"decode + assemble + average, one core, {args.revolutions} revolutions, {args.chunk} bytes per feed")
    rates = {}
    for channels, mode, frame_slots in [
        (8, "sequential", 45),
        (8, "sequential", 180),
        (8, "sequential", 15),
        (8, "simultaneous", 45),
        (8, "simultaneous", 15),
    ]:
        data = make_stream(args.revolutions, channels, mode, frame_slots)
        best = min(run(data, channels, mode, args.chunk)[0] for _ in range(3))
        _, c = run(data, channels, mode, args.chunk)
        samples = c["revolutions"] * 360 * (channels if mode == "simultaneous" else 1)
        rate = samples / best
        rates[(mode, frame_slots)] = rate
        print(
            f"  {mode:12s} C={channels} {frame_slots:3d} slots/frame: {rate / 1e6:7.1f} M samples/s "
            f"({len(data) / best / 1e6:6.1f} MB/s)  revolutions {c['revolutions']}, blocks {c['blocks']}, "
            f"frames bad {c['frames_bad']}, bytes skipped {c['bytes_skipped']}, "
            f"revolutions dropped {c['revolutions_dropped']}"
        )
        assert c["frames_bad"] == c["bytes_skipped"] == c["revolutions_dropped"] == 0
    adaptive = AveragingRule.adaptive(1e-3, 10, 200)  # these random revolutions never meet it: 200 each
    data = make_stream(args.revolutions, 8, "sequential", 45)
    best = min(run(data, 8, "sequential", args.chunk, adaptive)[0] for _ in range(3))
    _, c = run(data, 8, "sequential", args.chunk, adaptive)
    print(
        f"  adaptive rule (0.1 %, 10..200), sequential C=8 45 slots/frame: {c['revolutions'] * 360 / best / 1e6:7.1f} "
        f"M samples/s, blocks {c['blocks']}"
    )
    print(
        f"the simulator's layout (sequential, 45 slots per frame): {rates[('sequential', 45)] / 1e6:.1f} "
        f"M samples/s (target >= 10); slowest layout: {min(rates.values()) / 1e6:.1f} M samples/s"
    )
    return 0 if rates[("sequential", 45)] >= 10e6 else 1


if __name__ == "__main__":
    sys.exit(main())
