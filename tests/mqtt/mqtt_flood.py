"""A flooding operator client for the abort-under-flood test and bench.

Run as its own process (its own interpreter, so it competes with the rig
service for the machine, not for one GIL): publishes ``--count`` commands to
``<prefix>/cmd`` as fast as paho can send them, QoS 1 (``--qos 1``) or
alternating QoS 0 and 1 (``--qos mixed``), and counts the service's replies to
its own ids. Prints one line ``half`` as soon as the broker has taken half of
the flood (the moment the other operator aborts), then, once no reply came for
``--quiet`` s, one JSON line: published, seconds (to the last reply), out_s
(until the broker had taken the whole flood), and the replies by kind (``ok``,
``busy``, ``refused``).

    python mqtt_flood.py --port 1883 --prefix orbitrig/rig1 --count 5000 --qos 1
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import sys
import threading
import time

import paho.mqtt.client as mqtt

#: Ordinary commands an operator might repeat, none of which changes a run
#: (refused while a run is active or harmless); a start names no matrix there is.
FLOOD_CYCLE = (
    {"cmd": "start", "matrix": "no-such-matrix"},
    {"cmd": "status"},
    {"cmd": "confirm", "step": "manual:9999"},
    {"cmd": "resume"},
    {"cmd": "no-such-command"},
)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--prefix", required=True)
    ap.add_argument("--user", default="operator")
    ap.add_argument("--password", default="op-secret")
    ap.add_argument("--count", type=int, default=5000)
    ap.add_argument("--qos", choices=("1", "mixed"), default="1")
    ap.add_argument("--quiet", type=float, default=2.0)
    ap.add_argument("--wait", type=float, default=120.0, help="s at most after the start")
    args = ap.parse_args()

    replies = {"ok": 0, "busy": 0, "refused": 0}
    acked = 0
    out_at = [0.0]  # time.monotonic() when the broker had taken the whole flood
    half = threading.Event()
    last_reply = [time.monotonic()]
    lock = threading.Lock()

    def on_message(client, userdata, msg):
        obj = json.loads(msg.payload)
        if not str(obj.get("id", "")).startswith("flood-"):
            return
        kind = "ok" if obj.get("ok") else "busy" if str(obj.get("error", "")).startswith("busy") else "refused"
        with lock:
            replies[kind] += 1
            last_reply[0] = time.monotonic()

    def on_publish(client, userdata, mid, reason_code, properties):
        nonlocal acked
        acked += 1
        if acked == args.count // 2:
            half.set()
        if acked == args.count:
            out_at[0] = time.monotonic()

    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=f"mosq-flood-{os.getpid()}", protocol=mqtt.MQTTv5)
    client.username_pw_set(args.user, args.password)
    client.on_message = on_message
    client.on_publish = on_publish
    client.connect("127.0.0.1", args.port)
    client.subscribe(f"{args.prefix}/reply", qos=1)
    client.loop_start()
    time.sleep(0.3)  # subscribed
    t0 = time.monotonic()
    qos = itertools.cycle((0, 1)) if args.qos == "mixed" else itertools.repeat(1)
    for n, (body, q) in enumerate(zip(itertools.cycle(FLOOD_CYCLE), qos)):
        if n == args.count:
            break
        client.publish(f"{args.prefix}/cmd", json.dumps({**body, "id": f"flood-{n}"}), qos=q)
    half.wait(60)
    print("half", flush=True)
    while time.monotonic() - last_reply[0] < args.quiet or acked < args.count:
        if time.monotonic() - t0 > args.wait:
            break
        time.sleep(0.1)
    seconds = last_reply[0] - t0
    client.loop_stop()
    client.disconnect()
    with lock:
        print(
            json.dumps(
                {
                    "published": args.count,
                    "seconds": round(seconds, 3),
                    "out_s": round(out_at[0] - t0, 3) if out_at[0] else None,
                    **replies,
                }
            ),
            flush=True,
        )


if __name__ == "__main__":
    sys.exit(main())
