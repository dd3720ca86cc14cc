"""Soak: does memory stay bounded over a long campaign?

1. A sweep in process: the paper matrix (or its first --points points) on an in-process
   simulator at a high speed-up; the resident size (RSS) is sampled after every completed
   point and once more after run.h5 is written. The growth after the first ten points is
   fitted by least squares, in MB per 100 points.
2. `orbitrig serve --sim` under a real mosquitto (the test broker of tests/mqtt): --runs
   consecutive runs of a small matrix started and confirmed over MQTT; the service's RSS
   is read from /proc after each run has ended.

Prints the figures; exits 1 when the sweep grows by more than 20 MB per 100 points after
the first ten, or the service by more than 20 MB from the end of its first run to the
end of its last.

    python3 bench/bench_soak.py [--points 108] [--speedup 80] [--runs 10] [--sim-watchdog S] [--skip-sweep] [--skip-serve]
"""

from __future__ import annotations

import argparse
import asyncio
import logging
import resource
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))  # run as a script: the repository root (bench/ is the script's own folder)

from bench_sweep import _subset  # noqa: E402

from orbitrig import config as cfg  # noqa: E402
from orbitrig.run.engine import RunEngine  # noqa: E402
from orbitrig.run.events import ResultEvent  # noqa: E402
from orbitrig.run.plan import make_plan  # noqa: E402

LIMIT_PER_100_POINTS_MB = 20.0
LIMIT_SERVE_MB = 20.0


def rss_mb(pid: int | str = "self") -> float:
    """Resident set size of a process in MB (VmRSS of /proc/PID/status)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError(f"no VmRSS for process {pid}")


def slope_per_100(samples: list[tuple[int, float]]) -> float:
    """Least-squares slope of RSS (MB) against the point count, times 100."""
    n = len(samples)
    if n < 2:
        return 0.0
    mx = sum(p for p, _ in samples) / n
    my = sum(m for _, m in samples) / n
    sxx = sum((p - mx) ** 2 for p, _ in samples)
    return 100 * sum((p - mx) * (m - my) for p, m in samples) / sxx if sxx else 0.0


async def soak_sweep(points: int | None, speedup: float, watchdog_s: float = 0.0) -> bool:
    from orbitrig.cli.simulated_rig import simulated_rig
    from orbitrig.run.heap import tune_heap

    tune_heap()  # as `orbitrig sweep` does at its start
    rig = cfg.load_rig(None)
    if watchdog_s:  # a loaded machine: Modbus requests may take 0.5 s, an acquisition S s more
        text = rig.text
        polls = max(3, int(0.7 * watchdog_s / 0.6))  # the link declared lost after 70 % of S
        for old, new in (("timeout_s = 0.15", "timeout_s = 0.5"), ("link_loss_polls = 3", f"link_loss_polls = {polls}"),
                         ("timeout_margin_s = 2.0", f"timeout_margin_s = {watchdog_s * speedup:g}"),
                         ("comm_loss_timeout_s = 1.0", f"comm_loss_timeout_s = {watchdog_s:g}")):
            assert old in text, old
            text = text.replace(old, new)
        rig = cfg.rig_from_text(text, str(cfg.default_rig_path()))
    plan = make_plan(_subset(cfg.load_matrix(cfg.default_matrix_path("paper")), points), rig)
    samples: list[tuple[int, float]] = []

    def on_event(ev) -> None:
        if isinstance(ev, ResultEvent):
            samples.append((len(samples) + 1, rss_mb()))

    out = Path(tempfile.mkdtemp(prefix="bench-soak-")) / "run"
    start = rss_mb()
    t0 = time.monotonic()
    async with simulated_rig(speedup) as (sim, access):
        engine = RunEngine(rig, out_dir=out, access=access, confirm_mode="auto")
        engine.subscribe(on_event)
        outcome = await engine.run(plan)
    wall = time.monotonic() - t0
    end = rss_mb()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    if not samples:
        print(f"sweep: {outcome.status} ({outcome.message}) before any point completed")
        return False
    later = [s for s in samples if s[0] > 10]
    slope = slope_per_100(later)
    print(f"sweep: {outcome.status}, {len(samples)} points in {wall:.0f} s at speed-up {speedup:g} ({out})")
    print(f"  RSS start {start:.0f} MB, after point 10 {samples[min(9, len(samples) - 1)][1]:.0f} MB, "
          f"after the last point {samples[-1][1]:.0f} MB, after run.h5 {end:.0f} MB, peak {peak:.0f} MB")
    print(f"  growth after the first ten points: {slope:+.1f} MB per 100 points "
          f"(limit {LIMIT_PER_100_POINTS_MB:g})")
    return outcome.status == "completed" and len(later) >= 2 and slope <= LIMIT_PER_100_POINTS_MB


def soak_serve(runs: int, speedup: float) -> bool:
    from tests.support.mqtt_helpers import ACCOUNTS, Broker, RigClient, Service, write_matrices

    work = Path(tempfile.mkdtemp(prefix="bench-soak-serve-"))
    broker = Broker(work / "broker")
    broker.start()
    pw = work / "service.pw"
    pw.write_text(ACCOUNTS["orbitrig-service"] + "\n")
    pw.chmod(0o600)
    args = ["--sim", "--broker", broker.url, "--rig-id", "soak", "--username", "orbitrig-service",
            "--password-file", str(pw), "--matrices", str(write_matrices(work / "matrices")),
            "--out", str(work / "runs"), "--speedup", str(speedup), "--verbose",
            "--log-file", str(work / "serve-rotating.log"), "--log-max-mb", "0.2", "--log-backups", "2"]
    svc = Service(args, work)
    rig = RigClient(broker, "soak", svc)
    after: list[float] = []
    t0 = time.monotonic()
    try:
        rig.status(lambda s: True, timeout=60)
        for _ in range(runs):
            mark = rig.watch.mark()
            reply = rig.command({"cmd": "start", "matrix": "quick"}, timeout=30)
            if reply.get("ok") is not True:
                print(f"serve: start refused after {len(after)} runs: {reply}")
                break
            run_id = rig.status("waiting", start=mark, timeout=60)["run_id"]
            assert rig.command({"cmd": "confirm", "step": "manual:0000"}, timeout=30)["ok"] is True
            end = rig.status(lambda s, r=run_id: s["state"] in ("idle", "faulted") and s["run_id"] == r, start=mark,
                             timeout=180)
            after.append(rss_mb(svc.proc.pid))
            if end["state"] == "faulted":  # e.g. the simulator starved on a loaded machine
                print(f"serve: run {len(after)} faulted: {end['message']}")
                break
    finally:
        rig.close()
        svc.stop()
        broker.stop()
    growth = after[-1] - after[0]
    print(f"serve: {len(after)} runs in {time.monotonic() - t0:.0f} s; RSS after each run (MB): "
          + " ".join(f"{m:.0f}" for m in after))
    print(f"  growth from the first run to the last: {growth:+.1f} MB (limit {LIMIT_SERVE_MB:g})")
    logs = sorted(work.glob("serve-rotating.log*"))
    sizes = [f.stat().st_size for f in logs]
    print(f"  service log (--verbose, --log-max-mb 0.2, --log-backups 2): {len(logs)} files, largest "
          f"{max(sizes, default=0) / 1e3:.0f} kB, {sum(sizes) / 1e3:.0f} kB in all")
    logs_ok = len(logs) <= 3 and max(sizes, default=0) <= 200_000
    return len(after) == runs and growth <= LIMIT_SERVE_MB and logs_ok


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--points", type=int, default=None, help="about this many points of the paper matrix")
    ap.add_argument("--speedup", type=float, default=80.0)
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--sim-watchdog", type=float, default=0.0, metavar="S",
                    help="a loaded machine: the in-process sweep's simulated drives trip on a link silent for S s "
                         "(default: theirs, 1 s), acquisitions wait S s longer, Modbus requests 0.5 s, and the "
                         "link is declared lost after 0.7 S s")
    ap.add_argument("--skip-sweep", action="store_true")
    ap.add_argument("--skip-serve", action="store_true")
    args = ap.parse_args()
    logging.basicConfig(level=logging.ERROR)
    ok = True
    if not args.skip_sweep:
        ok &= asyncio.run(soak_sweep(args.points, args.speedup, args.sim_watchdog))
    if not args.skip_serve:
        ok &= soak_serve(args.runs, min(args.speedup, 50.0))
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
