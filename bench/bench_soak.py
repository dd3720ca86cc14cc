"""Soak: does memory stay bounded over a long campaign, and do the logs?

1. `orbitrig sweep --sim` in process (the CLI's own sweep: terminal progress, closing
   table; the simulator in its own process): the paper matrix (or its first --points
   points) at a high speed-up. The resident size (RSS) of this process is sampled at one
   moment of every point: when the point is complete (its results published, after the
   heap trim that follows the commit). The next point is being measured then (the run
   identifies one point while it measures the next), so the sample also holds 0 to 20
   of its blocks; that count is recorded with the sample and fitted as a second
   regressor: RSS = a + b * points + c * blocks held, least squares over the points after
   the tenth. b is the growth (MB per 100 points), c what one held block costs.
   The sizes of run.log and journal.jsonl are read at the same moments: run.log may grow
   by at most RUN_LOG_HEAD + RUN_LOG_TAIL + 1 lines between two completed points.
2. `orbitrig serve --sim` under a real mosquitto (the test broker of tests/mqtt): --runs
   consecutive runs of a small matrix started and confirmed over MQTT; the service's RSS
   is read from /proc once each run has ended (the service trims its heap then), and its
   rotating log (--log-max-mb 0.2, --log-backups 2) must stay within 3 x 0.2 MB.

Prints the figures; exits 1 on a miss: the sweep not completed, growing by more than 20 MB
per 100 points after the first ten, or its run.log over its quota; the service growing by
more than 20 MB from the end of its first run to the end of its last, or over its log quota.

    python3 -m bench.bench_soak [--points 108] [--speedup 80] [--runs 10] [--sim-watchdog S] [--skip-sweep] [--skip-serve]
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import resource
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.bench_sweep import first_points

from orbitrig import config as cfg
from orbitrig.run.events import ProgressEvent, ResultEvent
from orbitrig.run.plan import make_plan
from orbitrig.store.quota import RUN_LOG_HEAD, RUN_LOG_TAIL

LIMIT_PER_100_POINTS_MB = 20.0
LIMIT_SERVE_MB = 20.0
FIRST_POINTS_LEFT_OUT = 10  # the growth is fitted over the points after these (imports, caches, first figures)


def rss_mb(pid: int | str = "self") -> float:
    """Resident set size of a process in MB (VmRSS of /proc/PID/status)."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    raise RuntimeError(f"no VmRSS for process {pid}")


@dataclass(frozen=True)
class Sample:
    """One completed point: the count so far, RSS (MB), blocks of later points held, log sizes."""

    points: int
    rss: float
    held: int
    run_log_lines: int
    journal_bytes: int


class PointSampler:
    """An engine subscriber: a Sample when each point is complete (its ResultEvent)."""

    def __init__(self, out: Path):
        self.out = out
        self.samples: list[Sample] = []
        self.frequencies: dict[int, int] = {}  # started point (1-based count) -> its blocks
        self.now = (0, 0)  # (point being measured, its block being acquired), 1-based

    def __call__(self, ev) -> None:
        if isinstance(ev, ProgressEvent):
            self.frequencies[ev.point] = ev.frequencies
            self.now = (ev.point, ev.frequency)
        elif isinstance(ev, ResultEvent):
            done = len(self.samples) + 1
            point, block = self.now
            held = sum(self.frequencies.get(i, 0) for i in range(done + 1, point)) + max(0, block - 1) * (point > done)
            s = Sample(done, rss_mb(), held, _lines(self.out / "run.log"), _size(self.out / "journal.jsonl"))
            self.samples.append(s)
            with open(self.out.parent / "samples.txt", "a") as fh:  # to watch a long soak
                fh.write(
                    f"{time.monotonic():.1f} {s.points} {s.rss:.1f} {s.held} {s.run_log_lines} {s.journal_bytes}\n"
                )


def _lines(path: Path) -> int:
    try:
        with path.open("rb") as fh:
            return sum(1 for _ in fh)
    except OSError:
        return 0


def _size(path: Path) -> int:
    try:
        return path.stat().st_size
    except OSError:
        return 0


def growth_fit(samples: list[Sample]) -> tuple[float, float, float, float]:
    """Least squares RSS = a + b n + c held over the samples after the first ten points:
    (b x 100 in MB per 100 points, its standard error, c in MB per held block, residual rms MB)."""
    later = [s for s in samples if s.points > FIRST_POINTS_LEFT_OUT]
    if len(later) < 4:
        return float("nan"), float("nan"), float("nan"), float("nan")
    held = np.array([s.held for s in later], float)
    cols = [np.ones(len(later)), np.array([s.points for s in later], float)] + ([held] if np.ptp(held) else [])
    a = np.column_stack(cols)
    y = np.array([s.rss for s in later])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    resid = y - a @ coef
    dof = max(1, len(y) - a.shape[1])
    cov = (resid @ resid / dof) * np.linalg.inv(a.T @ a)
    c = float(coef[2]) if a.shape[1] == 3 else 0.0
    return 100 * float(coef[1]), 100 * float(np.sqrt(cov[1, 1])), c, float(np.sqrt(resid @ resid / dof))


def _rig(watchdog_s: float, speedup: float):
    """The shipped rig; with a watchdog S (a loaded machine) the drives trip on a link silent for
    S s, Modbus requests may take 0.5 s, acquisitions wait S s longer."""
    rig = cfg.load_rig(None)
    if not watchdog_s:
        return rig
    text = rig.text
    polls = max(3, int(0.7 * watchdog_s / 0.6))  # the link declared lost after 70 % of S
    for old, new in (
        ("timeout_s = 0.15", "timeout_s = 0.5"),
        ("link_loss_polls = 3", f"link_loss_polls = {polls}"),
        ("timeout_margin_s = 2.0", f"timeout_margin_s = {watchdog_s * speedup:g}"),
        ("comm_loss_timeout_s = 1.0", f"comm_loss_timeout_s = {watchdog_s:g}"),
    ):
        assert old in text, old
        text = text.replace(old, new)
    return cfg.rig_from_text(text, str(cfg.default_rig_path()))


async def soak_sweep(points: int | None, speedup: float, watchdog_s: float = 0.0) -> bool:
    from orbitrig.cli.sweep import sweep_scenario, run_sweep, print_table

    plan = make_plan(first_points(cfg.load_matrix(cfg.default_matrix_path("paper")), points), _rig(watchdog_s, speedup))
    out = Path(tempfile.mkdtemp(prefix="bench-soak-")) / "run"
    out.mkdir()
    sampler = PointSampler(out)
    start = rss_mb()
    t0 = time.monotonic()
    with (
        open(out.parent / "terminal.txt", "w") as term,
        contextlib.redirect_stdout(term),
        contextlib.redirect_stderr(term),
    ):  # the progress bars and the closing table
        outcome = await run_sweep(
            plan,
            out=out,
            sim=sweep_scenario(None),
            speedup=speedup,
            operator="bench",
            subscribers=[sampler],
        )
        print_table(outcome, out)
    wall = time.monotonic() - t0
    s = sampler.samples
    print(
        f"sweep: {outcome.status}, {len(s)} of {len(plan.points)} points in {wall:.0f} s at speed-up {speedup:g}"
        f"{f', drive watchdog {watchdog_s:g} s' if watchdog_s else ''} ({out})"
    )
    if len(s) <= FIRST_POINTS_LEFT_OUT + 3:
        print(f"  {outcome.message}: too few points for a growth figure")
        return False
    slope, err, per_block, rms = growth_fit(s)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print("  RSS sampled when each point is complete (after its heap trim), with the next point's blocks then held")
    print(
        f"  RSS start {start:.0f} MB, after point 10 {s[9].rss:.0f} MB, after the last point {s[-1].rss:.0f} MB, "
        f"after the closing table {rss_mb():.0f} MB, peak {peak:.0f} MB"
    )
    print(
        f"  growth after the first ten points: {slope:+.1f} +- {err:.1f} MB per 100 points (limit "
        f"{LIMIT_PER_100_POINTS_MB:g}); {per_block:.2f} MB per held block (0 to {max(x.held for x in s)} held), "
        f"residual {rms:.1f} MB rms"
    )
    return (outcome.status == "completed") & (slope <= LIMIT_PER_100_POINTS_MB) & logs_bounded(s, out)


def logs_bounded(s: list[Sample], out: Path) -> bool:
    """run.log within its quota between two completed points; the journal's growth per point."""
    quota = RUN_LOG_HEAD + RUN_LOG_TAIL + 1
    log_steps = [b.run_log_lines - a.run_log_lines for a, b in zip(s, s[1:])]
    journal_steps = [b.journal_bytes - a.journal_bytes for a, b in zip(s, s[1:])]
    end_lines, end_bytes = (
        _lines(out / "run.log") - s[-1].run_log_lines,
        _size(out / "journal.jsonl") - s[-1].journal_bytes,
    )
    print(
        f"  run.log: {_lines(out / 'run.log')} lines, at most {max(log_steps)} between two completed points "
        f"(quota {quota}), {end_lines} after the last; journal: {_size(out / 'journal.jsonl') / 1e6:.1f} MB, "
        f"{min(journal_steps) / 1e3:.0f} to {max(journal_steps) / 1e3:.0f} kB per point, "
        f"{end_bytes / 1e3:.0f} kB after the last"
    )
    return max(log_steps) <= quota and end_lines <= quota


def soak_serve(runs: int, speedup: float) -> bool:
    from tests.support.mqtt_helpers import ACCOUNTS, Broker, RigClient, Service, write_matrices

    work = Path(tempfile.mkdtemp(prefix="bench-soak-serve-"))
    broker = Broker(work / "broker")
    broker.start()
    pw = work / "service.pw"
    pw.write_text(ACCOUNTS["orbitrig-service"] + "\n")
    pw.chmod(0o600)
    args = [
        "--sim",
        "--broker",
        broker.url,
        "--rig-id",
        "soak",
        "--username",
        "orbitrig-service",
        "--password-file",
        str(pw),
        "--matrices",
        str(write_matrices(work / "matrices")),
        "--out",
        str(work / "runs"),
        "--speedup",
        str(speedup),
        "--verbose",
        "--log-file",
        str(work / "serve-rotating.log"),
        "--log-max-mb",
        "0.2",
        "--log-backups",
        "2",
    ]
    svc = Service(args, work)
    rig = RigClient(broker, "soak", svc)
    after: list[float] = []
    t0 = time.monotonic()
    try:
        rig.status(lambda s: True, timeout=60)
        for _ in range(runs):
            if not _one_run(rig):
                break
            after.append(rss_mb(svc.proc.pid))
    finally:
        rig.close()
        svc.stop()
        broker.stop()
    if not after:
        return False
    growth = after[-1] - after[0]
    print(
        f"serve: {len(after)} runs in {time.monotonic() - t0:.0f} s at speed-up {speedup:g}; RSS after each run "
        "(MB): " + " ".join(f"{m:.0f}" for m in after)
    )
    print(f"  growth from the first run to the last: {growth:+.1f} MB (limit {LIMIT_SERVE_MB:g})")
    logs = sorted(work.glob("serve-rotating.log*"))
    sizes = [f.stat().st_size for f in logs]
    print(
        f"  service log (--verbose, --log-max-mb 0.2, --log-backups 2): {len(logs)} files, largest "
        f"{max(sizes, default=0) / 1e3:.0f} kB, {sum(sizes) / 1e3:.0f} kB in all (quota 3 x 200 kB)"
    )
    logs_ok = len(logs) <= 3 and max(sizes, default=0) <= 200_000
    return len(after) == runs and growth <= LIMIT_SERVE_MB and logs_ok


def _one_run(rig) -> bool:
    """Start the quick matrix over MQTT, confirm its manual step, wait for its end (True: ended idle)."""
    mark = rig.watch.mark()
    reply = rig.command({"cmd": "start", "matrix": "quick"}, timeout=30)
    if reply.get("ok") is not True:
        print(f"serve: start refused: {reply}")
        return False
    run_id = rig.status("waiting", start=mark, timeout=60)["run_id"]
    assert rig.command({"cmd": "confirm", "step": "manual:0000"}, timeout=30)["ok"] is True
    end = rig.status(
        lambda s, r=run_id: s["state"] in ("idle", "faulted") and s["run_id"] == r, start=mark, timeout=180
    )
    if end["state"] == "faulted":  # e.g. the simulator starved on a loaded machine
        print(f"serve: run {run_id} faulted: {end['message']}")
        return False
    return True


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--points", type=int, default=None, help="about this many points of the paper matrix")
    ap.add_argument("--speedup", type=float, default=80.0)
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument(
        "--sim-watchdog",
        type=float,
        default=0.0,
        metavar="S",
        help="a loaded machine: the sweep's simulated drives trip on a link silent for S s "
        "(default: theirs, 1 s), acquisitions wait S s longer, Modbus requests 0.5 s, and the "
        "link is declared lost after 0.7 S s",
    )
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
