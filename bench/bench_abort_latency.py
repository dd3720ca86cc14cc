"""Abort latency: from publishing an MQTT `abort` to both drives commanded to stop.

Target: < 200 ms. Runs a real mosquitto (password file, the project's ACL),
the `orbitrig serve` service (the same RigService + RunEngine the CLI builds)
on the simulator, all in this process's event loop as with `serve --sim`.
For each trial a run is started and given time to spin both drives up; then
an operator client (paho, own thread, own connection through the broker)
publishes `abort`. Three instants on one clock (time.monotonic):

  t_pub     just before the operator's publish call;
  t_arrive  the service has the command (RigService.handle_command entered);
  t_stop    the simulated drive applied a control word that stops it (OFF1 or
            OFF3 or RUN cleared), as written over Modbus TCP by the executor:
            taken inside the drive's register write, for drive 1 and drive 2.

Latency = max(t_stop drive 1, t_stop drive 2) - t_pub.

    python3 -m bench.bench_abort_latency [--trials 7] [--speedup 20]
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

from tests.support.mqtt_helpers import ACCOUNTS, MATRIX, Broker

CW_STOPPING = 0b1101  # OFF1 (bit 0), OFF3 (bit 2), RUN (bit 3): any of them 0 = a stop command
TARGET_MS = 200.0  # abort -> both drives commanded to stop


def write_matrix(work: Path, revs: int = 200) -> None:
    """``work/matrices/bench.toml``: three forward orbit ratios of ``revs`` revolutions each
    (long blocks: the abort lands mid-acquisition)."""
    (work / "matrices").mkdir()
    (work / "matrices" / "bench.toml").write_text(
        MATRIX.format(name="bench", revs=revs, ratios="[0.5, 0.7, 0.9]", directions='["forward"]')
    )


def bench_service(sim_rig, work: Path, creds):
    """The rig service as `orbitrig serve --sim` builds it (rig id ``bench``, confirm auto) on
    ``sim_rig``, with the matrices of :func:`write_matrix` and its runs in ``work``."""
    from orbitrig.cli.serve import build_service
    from orbitrig.config import load_rig
    from orbitrig.service.rig_service import ServiceSettings

    settings = ServiceSettings(rig_id="bench", matrices_dir=work / "matrices")
    return build_service(load_rig(), settings, creds, out=work / "runs", sim_rig=sim_rig, confirm="auto")


def service_account(url: str):
    """The service's broker settings on ``url``: its account of the project's password file."""
    from orbitrig.service.rig_service import BrokerSettings

    return BrokerSettings.from_url(url, username="orbitrig-service", password=ACCOUNTS["orbitrig-service"])


@contextlib.asynccontextmanager
async def service_on_sim(prefix: str, speedup: float, stops: dict, words: dict, armed: threading.Event):
    """A work folder (``prefix``) with the bench matrix, a mosquitto, the simulator (its drives'
    stopping control words timed into ``stops`` and ``words`` once ``armed``) and the bench
    service on it, not yet serving: yields (work, broker, sim_rig, service)."""
    from sim.rig import SimRig

    logging.basicConfig(level=logging.WARNING)
    work = Path(tempfile.mkdtemp(prefix=prefix))
    write_matrix(work)
    broker = Broker(work / "broker")
    broker.start()
    try:
        async with SimRig(speedup=speedup, adc_pty=False) as sim_rig:
            watch_control_words(sim_rig, stops, words, armed)
            yield work, broker, sim_rig, bench_service(sim_rig, work, service_account(broker.url))
    finally:
        broker.stop()


def print_summary(title: str, start: str, latencies_ms: list[float]) -> int:
    """The latencies' median, min and max against the target; 0 when all are under it, else 1."""
    print(
        f"\n{title} over {len(latencies_ms)} trials ({start} -> both drives commanded to stop): "
        f"median {statistics.median(latencies_ms):.1f} ms, min {min(latencies_ms):.1f} ms, "
        f"max {max(latencies_ms):.1f} ms "
        f"(target < {TARGET_MS:.0f} ms: {'met' if max(latencies_ms) < TARGET_MS else 'NOT met'})"
    )
    return 0 if max(latencies_ms) < TARGET_MS else 1


def watch_control_words(sim_rig, stops: dict[int, float], words: dict[int, int], armed: threading.Event) -> None:
    """Time stamp (and keep) the first stopping control word each drive applies once armed."""
    for device, drive in sim_rig.drives.items():
        original = drive.write

        def write(address, values, _orig=original, _dev=device):
            _orig(address, values)
            if armed.is_set() and _dev not in stops and address <= 0 < address + len(values):
                if int(values[-address]) & CW_STOPPING != CW_STOPPING:
                    stops[_dev] = time.monotonic()
                    words[_dev] = int(values[-address])

        drive.write = write


class Operator:
    """An independent MQTT client (paho, its own network thread)."""

    def __init__(self, port: int, prefix: str, topics: tuple[str, ...] = ("#",)):
        import paho.mqtt.client as mqtt

        self.prefix = prefix
        self.status: dict = {}
        self.progress_revs = 0
        self._got = threading.Condition()
        self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="mosq-bench-operator")
        self.client.username_pw_set("operator", ACCOUNTS["operator"])
        self.client.on_message = self._on_message
        self.client.connect("127.0.0.1", port)
        self.client.subscribe([(f"{prefix}/{t}", 1) for t in topics])
        self.client.loop_start()

    def _on_message(self, client, userdata, msg):
        import json

        obj = json.loads(msg.payload)
        with self._got:
            if msg.topic.endswith("/status"):
                self.status = obj
            elif msg.topic.endswith("/progress"):
                self.progress_revs = obj["revolutions"] if obj["point"] else 0
            self._got.notify_all()

    def wait(self, pred, timeout: float) -> None:
        with self._got:
            if not self._got.wait_for(pred, timeout):
                raise TimeoutError(f"timed out; last status {self.status}")

    def send(self, cmd: str, **fields) -> float:
        import json

        payload = json.dumps({"cmd": cmd, "id": f"bench-{cmd}-{time.monotonic_ns()}", **fields})
        t = time.monotonic()
        self.client.publish(f"{self.prefix}/cmd", payload, qos=1)
        return t

    def close(self) -> None:
        self.client.loop_stop()
        self.client.disconnect()


async def main(trials: int, speedup: float) -> int:
    """Run the trials; 0 when every one is under the target, else 1."""
    stops: dict[int, float] = {}
    words: dict[int, int] = {}
    armed = threading.Event()
    arrivals: list[float] = []
    async with service_on_sim("bench-abort-", speedup, stops, words, armed) as (_, broker, sim_rig, service):
        handle = service.handle_command

        def timed_handle(payload: bytes, *, retained: bool = False) -> None:
            arrivals.append(time.monotonic())
            handle(payload, retained=retained)

        service.handle_command = timed_handle
        shutdown = asyncio.Event()
        serving = asyncio.create_task(service.serve(shutdown), name="bench-service")
        op = await asyncio.to_thread(Operator, broker.port, "orbitrig/bench")
        rows = []
        try:
            await asyncio.to_thread(op.wait, lambda: op.status.get("state") == "idle", 30)
            for trial in range(trials):
                op.progress_revs = 0
                op.send("start", matrix="bench")
                # both drives at speed and the orbit being acquired
                await asyncio.to_thread(op.wait, lambda: op.progress_revs >= 20, 60)
                spin, orbit = (abs(sim_rig.drives[d].actual_rpm) for d in (1, 2))
                stops.clear()
                arrivals.clear()
                armed.set()
                t_pub = op.send("abort")
                await asyncio.to_thread(op.wait, lambda: op.status.get("state") == "idle", 60)
                armed.clear()
                if len(stops) != 2:
                    raise RuntimeError(f"trial {trial}: stop commands seen for drives {sorted(stops)} only")
                t_arr = arrivals[0]
                rows.append(
                    (
                        (t_arr - t_pub) * 1e3,
                        (max(stops.values()) - t_arr) * 1e3,
                        (max(stops.values()) - t_pub) * 1e3,
                    )
                )
                print(
                    f"trial {trial + 1}: spin {spin:6.0f} rpm, orbit {orbit:+6.0f} rpm | "
                    f"broker {rows[-1][0]:6.1f} ms + service/executor/Modbus {rows[-1][1]:6.1f} ms "
                    f"= abort -> both drives stopping {rows[-1][2]:6.1f} ms "
                    f"(CW {words[1]:#06x}, {words[2]:#06x})",
                    flush=True,
                )
        finally:
            op.close()
            shutdown.set()
            await serving
    return print_summary("abort latency", "publish", [r[2] for r in rows])


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=7)
    ap.add_argument("--speedup", type=float, default=20.0)
    args = ap.parse_args()
    sys.exit(asyncio.run(main(args.trials, args.speedup)))
