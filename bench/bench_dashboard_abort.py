"""Abort latency from the browser: click on the page -> both drives commanded to stop.

Target: < 200 ms. A real mosquitto (password file, the project's ACL), the rig
service (RigService + RunEngine as `orbitrig serve --sim` builds them, in this
process so the simulated drives' register writes can be time stamped), the
`orbitrig dashboard` process, and a headless chromium driven by selenium,
signed in as the operator. For each trial a run is started and given time to
spin both drives up; then the bench clicks ABORT and the confirmation's
"Abort now". On one clock (time.monotonic):

  t_click   just before selenium clicks "Abort now" (the click that commits;
            the first ABORT click only opens the confirmation);
  t_stop    the simulated drive applied a control word that stops it (as in
            bench_abort_latency.py), for drive 1 and drive 2.

Latency = max(t_stop drive 1, t_stop drive 2) - t_click. It includes
chromedriver's round trip for the click, the page's fetch to the dashboard
server, its MQTT publish as the operator, the broker, the service, the executor
and the Modbus write.

    python3 -m bench.bench_dashboard_abort [--trials 5] [--speedup 20]
"""

from __future__ import annotations

import argparse
import asyncio
import sys
import threading
import time

from bench.bench_abort_latency import Operator, print_summary, service_on_sim
from tests.support.dash_helpers import Dashboard, Page, chromium
from tests.support.mqtt_helpers import ACCOUNTS


def click_abort(page: Page) -> float:
    """Open the confirmation, then commit; returns the time just before the committing click."""
    page.el("btn-abort").click()
    page.wait(lambda: page.el("abort-confirm").is_displayed(), 10, "the abort confirmation")
    button = page.el("abort-confirm")
    t = time.monotonic()
    button.click()
    return t


async def trials_loop(
    page, watcher, sim_rig, stops: dict, words: dict, armed: threading.Event, trials: int
) -> list[float]:
    """Start a run, let both drives spin up, abort from the page; click -> stop latency (ms) per trial."""
    rows: list[float] = []
    for trial in range(trials):
        watcher.progress_revs = 0
        await asyncio.to_thread(page.command, "btn-start", "start: accepted")
        await asyncio.to_thread(watcher.wait, lambda: watcher.progress_revs >= 20, 60)
        spin, orbit = (abs(sim_rig.drives[d].actual_rpm) for d in (1, 2))
        stops.clear()
        armed.set()
        t_click = await asyncio.to_thread(click_abort, page)
        await asyncio.to_thread(watcher.wait, lambda: watcher.status.get("state") == "idle", 60)
        armed.clear()
        if len(stops) != 2:
            raise RuntimeError(f"trial {trial}: stop commands seen for drives {sorted(stops)} only")
        rows.append((max(stops.values()) - t_click) * 1e3)
        print(
            f"trial {trial + 1}: spin {spin:6.0f} rpm, orbit {orbit:+6.0f} rpm | click 'Abort now' -> "
            f"both drives stopping {rows[-1]:6.1f} ms (CW {words[1]:#06x}, {words[2]:#06x})",
            flush=True,
        )
    return rows


async def main(trials: int, speedup: float) -> int:
    """Run the trials; 0 when every one is under the target, else 1."""
    stops: dict[int, float] = {}
    words: dict[int, int] = {}
    armed = threading.Event()
    rows: list[float] = []
    dash = driver = None
    async with service_on_sim("bench-dash-abort-", speedup, stops, words, armed) as (work, broker, sim_rig, service):
        shutdown = asyncio.Event()
        serving = asyncio.create_task(service.serve(shutdown), name="bench-service")
        watcher = await asyncio.to_thread(Operator, broker.port, "orbitrig/bench")
        try:
            dash = await asyncio.to_thread(Dashboard, broker.url, "bench", work)
            driver = await asyncio.to_thread(chromium, work)
            page = await asyncio.to_thread(Page, driver, dash.url, dash)
            await asyncio.to_thread(page.sign_in, "operator", ACCOUNTS["operator"])
            await asyncio.to_thread(page.signed_in)
            await asyncio.to_thread(page.wait_state, "idle")
            await asyncio.to_thread(page.el("matrix").clear)
            await asyncio.to_thread(page.el("matrix").send_keys, "bench")
            rows = await trials_loop(page, watcher, sim_rig, stops, words, armed, trials)
        finally:
            watcher.close()
            if driver is not None:
                await asyncio.to_thread(driver.quit)
            if dash is not None:
                await asyncio.to_thread(dash.stop)
            shutdown.set()
            await serving
    return print_summary("dashboard abort latency", "click", rows)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=5)
    ap.add_argument("--speedup", type=float, default=20.0)
    args = ap.parse_args()
    sys.exit(asyncio.run(main(args.trials, args.speedup)))
