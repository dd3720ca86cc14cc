"""Abort latency while another operator floods the rig service with commands.

Target: < 200 ms from the abort's publish to both drives commanded to stop,
while a second operator client publishes 5000 commands at full speed. A real
mosquitto (password file, the project's ACL and the shipped config's queue and
in-flight limits), the rig service as `orbitrig serve --sim` builds it (in this
process, so the simulated drives' register writes can be time stamped, as in
bench_abort_latency.py). Per trial: a run is started and both drives spun up;
the flooding client (tests/mqtt/mqtt_flood.py, its own process) publishes its
commands (QoS 1, or alternating QoS 0 and 1); when the broker has taken half of
them, the operator (paho, own connection) publishes `abort`. On one clock:

  t_pub       just before the operator's publish call;
  t_stop      both simulated drives applied a stopping control word;
  t_stopping  the operator saw status `stopping`.

Printed per trial: t_stop - t_pub (the figure held to 200 ms), t_stopping -
t_pub, the run's outcome, the flood's replies (ok / busy / refused) and what
the service counted (commands received, answered busy, dropped).
Exit status 1 when any trial misses 200 ms or does not end aborted.

    python3 bench/bench_abort_flood.py [--trials 3] [--count 5000] [--qos 1 mixed]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import logging
import sys
import tempfile
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO), str(REPO / "tests" / "mqtt"), str(REPO / "bench")]

from bench_abort_latency import Operator, watch_control_words  # noqa: E402
from mqtt_helpers import ACCOUNTS, MATRIX, Broker  # noqa: E402  (the tests' broker set-up)

FLOODER = REPO / "tests" / "mqtt" / "mqtt_flood.py"
TARGET_MS = 200.0


class TimedOperator(Operator):
    """The aborting operator; also notes when it first sees each status state."""

    def __init__(self, port: int, prefix: str):
        self.seen: dict[str, float] = {}
        super().__init__(port, prefix)

    def _on_message(self, client, userdata, msg):
        if msg.topic.endswith("/status"):
            self.seen.setdefault(json.loads(msg.payload).get("state"), time.monotonic())
        super()._on_message(client, userdata, msg)


async def flood(port: int, prefix: str, count: int, qos: str) -> asyncio.subprocess.Process:
    """Start the flooding client; returns it once half the flood is out."""
    proc = await asyncio.create_subprocess_exec(
        sys.executable, str(FLOODER), "--port", str(port), "--prefix", prefix, "--count", str(count),
        "--qos", qos, "--password", ACCOUNTS["operator"], stdout=asyncio.subprocess.PIPE)
    line = await asyncio.wait_for(proc.stdout.readline(), 120)
    if line.strip() != b"half":
        raise RuntimeError(f"flooder: {line!r}")
    return proc


async def one_trial(op: TimedOperator, sim_rig, service, broker: Broker, qos: str, count: int,
                    stops: dict, armed: threading.Event) -> dict:
    op.progress_revs = 0
    op.send("start", matrix="bench")
    await asyncio.to_thread(op.wait, lambda: op.progress_revs >= 20, 60)  # both drives at speed
    before = dict(getattr(service, "flood_counts", dict)())
    proc = await flood(broker.port, op.prefix, count, qos)
    stops.clear()
    op.seen.clear()
    armed.set()
    t_pub = op.send("abort")
    await asyncio.to_thread(op.wait, lambda: op.status.get("state") == "idle", 120)
    armed.clear()
    summary = json.loads((await asyncio.wait_for(proc.stdout.read(), 180)).decode().strip().splitlines()[-1])
    await proc.wait()
    after = dict(getattr(service, "flood_counts", dict)())
    counted = {k: after.get(k, 0) - before.get(k, 0) for k in after}
    stop_ms = (max(stops.values()) - t_pub) * 1e3 if len(stops) == 2 else float("inf")
    stopping_ms = (op.seen["stopping"] - t_pub) * 1e3 if "stopping" in op.seen else float("inf")
    return {"stop_ms": stop_ms, "stopping_ms": stopping_ms, "outcome": op.status.get("message", ""),
            "flood": summary, "service": counted}


async def main(trials: int, speedup: float, count: int, modes: list[str]) -> int:
    from orbitrig.cli.serve import build_service
    from orbitrig.config import load_rig
    from orbitrig.service.rig_service import BrokerSettings, ServiceSettings
    from sim.rig import SimRig

    logging.basicConfig(level=logging.WARNING)
    work = Path(tempfile.mkdtemp(prefix="bench-abort-flood-"))
    (work / "matrices").mkdir()
    (work / "matrices" / "bench.toml").write_text(  # long blocks: abort lands mid-acquisition
        MATRIX.format(name="bench", revs=400, ratios="[0.5, 0.7, 0.9]", directions='["forward"]'))
    broker = Broker(work / "broker", bind_ids=True)
    broker.start()
    stops: dict[int, float] = {}
    armed = threading.Event()
    failures = 0
    try:
        async with SimRig(speedup=speedup, adc_pty=False) as sim_rig:
            watch_control_words(sim_rig, stops, {}, armed)
            settings = ServiceSettings(rig_id="bench", matrices_dir=work / "matrices")
            creds = BrokerSettings.from_url(broker.service_url, username="orbitrig-service",
                                            password=ACCOUNTS["orbitrig-service"])
            service = build_service(load_rig(), settings, creds, out=work / "runs", sim_rig=sim_rig,
                                    confirm="auto")
            shutdown = asyncio.Event()
            serving = asyncio.create_task(service.serve(shutdown), name="bench-service")
            op = await asyncio.to_thread(TimedOperator, broker.port, "orbitrig/bench")
            try:
                await asyncio.to_thread(op.wait, lambda: op.status.get("state") == "idle", 30)
                for qos in modes:
                    for trial in range(trials):
                        r = await one_trial(op, sim_rig, service, broker, qos, count, stops, armed)
                        ok = r["stop_ms"] < TARGET_MS and "aborted" in r["outcome"]
                        failures += not ok
                        print(f"QoS {qos:>5} trial {trial + 1}: abort -> both drives stopping "
                              f"{r['stop_ms']:7.1f} ms, status stopping {r['stopping_ms']:7.1f} ms, "
                              f"{r['outcome']!r} | flood {r['flood']} | service {r['service']}"
                              f"{'' if ok else '  <-- MISS'}", flush=True)
            finally:
                op.close()
                shutdown.set()
                await serving
    finally:
        broker.stop()
    dropped = broker.log.read_text().count("Outgoing messages are being dropped")
    print(f"\nbroker dropped outgoing messages {dropped} times; "
          f"target < {TARGET_MS:.0f} ms and run aborted: {'met' if not failures else f'{failures} trial(s) missed'}")
    return 1 if failures or dropped else 0


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=3)
    ap.add_argument("--speedup", type=float, default=20.0)
    ap.add_argument("--count", type=int, default=5000)
    ap.add_argument("--qos", nargs="+", default=["1", "mixed"], choices=("1", "mixed"))
    args = ap.parse_args()
    sys.exit(asyncio.run(main(args.trials, args.speedup, args.count, args.qos)))
