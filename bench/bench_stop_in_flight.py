"""A stop behind a Modbus request in flight: from `RigDrives.stop_now` to both drives holding the
emergency stop word, while the request on the link goes unanswered (the worst case: a drive
that answers late answers within the request timeout).

Cases, on TCP and on RTU (a pty): the link idle; the poll's status read unanswered (on TCP it
gives way to the stop, drives/link.py); a write unanswered (never given up). The simulator's
drives behind its real Modbus servers drop the request (`drop_next`); the stop word is seen in
the drive models' registers, polled every 0.5 ms.

    python3 -m bench.bench_stop_in_flight [--trials 7] [--timeout 0.15]

Exit 1 when a case's slowest stop misses its target (`target_ms`).
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import math
import statistics
import time

CW_EMERGENCY = 0x047B  # the contract's emergency stop word (drive-modbus.md)
REF2 = 2  # the contract's unused second reference: a harmless write
CASES = ("link idle", "poll read unanswered", "write unanswered")


async def trial(kind: str, case: str, timeout: float) -> float:
    """Seconds from the stop asked to both drives holding OFF3, in `case`."""
    from drives.limits import DriveLimits
    from drives.rig import RigDrives
    from sim.drive_model import DriveModel
    from sim.modbus_server import serve_modbus_rtu_pty, serve_modbus_tcp

    t0 = time.monotonic()
    models = {
        1: DriveModel(1, clock=lambda: (time.monotonic() - t0) * 25, bidirectional=False),
        2: DriveModel(2, clock=lambda: (time.monotonic() - t0) * 25, bidirectional=True),
    }
    endpoint = await (serve_modbus_tcp if kind == "tcp" else serve_modbus_rtu_pty)(models)
    limits = DriveLimits(max_spin=250.0, max_orbit=250.0)
    try:
        async with RigDrives(endpoint.url, limits, poll_interval=0.1, timeout=timeout, comm_loss_timeout=2.0) as rig:
            await rig.set_speeds(60.0, 30.0)
            await asyncio.sleep(0.3)
            writing = await _in_flight(rig, endpoint, case)
            t_ask = time.monotonic()
            stop = rig.stop_now(emergency=True)
            while not all(m.read(0, 1)[0] == CW_EMERGENCY for m in models.values()):
                await asyncio.sleep(0.0005)
            took = time.monotonic() - t_ask
            await stop
            if writing is not None:
                await asyncio.gather(writing, return_exceptions=True)
            return took
    finally:
        await endpoint.aclose()


async def _in_flight(rig, endpoint, case: str) -> asyncio.Task | None:
    """Until the request of `case` has reached the simulator and gone unanswered (None: the
    link idle, just after a poll); the write's task, to be awaited."""
    if case == CASES[0]:
        polls = rig.link.requests
        while rig.link.requests == polls:
            await asyncio.sleep(0.0005)
        await asyncio.sleep(0.002)
        return None
    endpoint.drop_next(1)
    writing = asyncio.create_task(rig.link.write(1, REF2, [0])) if case == CASES[2] else None
    while endpoint.requests_to_drop:  # the server's own count of requests left to drop
        await asyncio.sleep(0.0005)
    return writing


def target_ms(kind: str, case: str, timeout: float) -> float:
    """The slowest stop allowed (ms): on TCP a poll's read gives way at once (under half the
    timeout); anything else waits at most for the request's timeout, then on RTU the settle time
    after a missed answer (min(timeout, 0.05 s)), with 0.1 s for a loaded machine."""
    if kind == "tcp" and case == "poll read unanswered":
        return 1e3 * timeout / 2
    return 1e3 * (timeout + min(timeout, 0.05) + 0.1)


async def main(trials: int, timeout: float) -> int:
    logging.basicConfig(level=logging.CRITICAL)
    missed = 0
    for kind in ("tcp", "rtu"):
        for case in CASES:
            ms = [1e3 * await trial(kind, case, timeout) for _ in range(trials)]
            limit = target_ms(kind, case, timeout)
            missed += max(ms) > limit
            print(
                f"{kind} {case:21s} (timeout {timeout:g} s): {min(ms):6.1f}-{max(ms):6.1f} ms, "
                f"median {statistics.median(ms):6.1f} ms over {trials} (target < {limit:.0f} ms: "
                f"{'NOT met' if max(ms) > limit else 'met'})"
            )
    return 1 if missed else 0


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=7)
    ap.add_argument("--timeout", type=float, default=0.15, help="Modbus request timeout, s (shipped: 0.15)")
    args = ap.parse_args()
    if args.trials < 1 or not (math.isfinite(args.timeout) and args.timeout > 0):
        ap.error("--trials at least 1, --timeout a positive time")
    raise SystemExit(asyncio.run(main(args.trials, args.timeout)))
