"""A page that stops reading its feed while the rig floods it (orbitrig.dashboard.feed.Feed): a real
`orbitrig dashboard` on a real mosquitto, a websocket client that reads its snapshot, then nothing while
the rig service's account publishes progress and live values by the thousand with results, warnings and
statuses among them. The page misses progress and trend points only, told by a `gap` (its `dropped`),
and every result, warning and status comes, in order; a page behind with only those waiting has its
connection cut and its next one starts with the session's snapshot."""

from __future__ import annotations

import asyncio
import json
import socket
import time

import aiohttp
import paho.mqtt.client as mqtt
from support.dash_helpers import RIG, Dashboard
from support.mqtt_helpers import ACCOUNTS

from orbitrig.dashboard.feed import FeedType

RUN = "r-behind"
PAD = "x" * 4000  # bytes a progress carries besides its fields: the page's socket buffers fill sooner
KEPT = (FeedType.RESULT, FeedType.NOTE, FeedType.STATUS)


def publisher(broker) -> mqtt.Client:
    """The rig service's account (a client id of the broker's `mosq-` prefix), connected."""
    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=f"mosq-flood-{time.monotonic_ns()}")
    client.username_pw_set("orbitrig-service", ACCOUNTS["orbitrig-service"])
    client.connect("127.0.0.1", broker.port)
    client.loop_start()
    return client


def flood(client: mqtt.Client, progress: int, every: int) -> list[tuple[str, int]]:
    """``progress`` progress and live messages, a result and a note after each ``every`` of them and a
    status after each 5 ``every``: what was published of the kinds a page must not miss, in order."""
    said: list[tuple[str, int]] = []
    topic = f"orbitrig/{RIG}/"
    for i in range(progress):
        body = {"run_id": RUN, "point": i, "points": progress, "eta_s": 1.0, "pad": PAD}
        client.publish(topic + "progress", json.dumps(body), qos=1)
        client.publish(topic + "live", json.dumps({"run_id": RUN, "drives": {"spin": {"actual_rpm": i}}}), qos=0)
        if i % every == every - 1:
            client.publish(topic + "result", json.dumps({"run_id": RUN, "index": i, "identification": []}), qos=1)
            client.publish(topic + "note", json.dumps({"run_id": RUN, "level": "warning", "message": f"w{i}"}), qos=1)
            said += [(FeedType.RESULT, i), (FeedType.NOTE, i)]
        if i % (5 * every) == 5 * every - 1:
            status = {"state": "running", "run_id": RUN, "message": f"s{i}"}
            client.publish(topic + "status", json.dumps(status), qos=1, retain=True).wait_for_publish(10)
            said.append((FeedType.STATUS, i))
    return said


def told(message: dict) -> tuple[str, int] | None:
    """(kind, i) of a result, note or status of the flood (None: another message)."""
    kind, data = message["type"], message.get("data") or {}
    if kind == FeedType.RESULT and data.get("run_id") == RUN:
        return kind, data["index"]
    if kind in (FeedType.NOTE, FeedType.STATUS) and str(data.get("message", "")).startswith(("w", "s")):
        return kind, int(data["message"][1:])
    return None


def in_order(got: list[dict]) -> list[tuple[str, int]]:
    """The results, notes and statuses of the flood that came, in their order."""
    return [t for message in got if (t := told(message))]


def small_socket(addr_info) -> socket.socket:
    """The page's socket with a small receive buffer: a page that stops reading is full sooner."""
    family, kind, proto, _, _ = addr_info
    sock = socket.socket(family, kind, proto)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8192)
    return sock


async def signed_in(dash: Dashboard) -> aiohttp.ClientSession:
    http = aiohttp.ClientSession(
        dash.url, cookie_jar=aiohttp.CookieJar(unsafe=True), connector=aiohttp.TCPConnector(socket_factory=small_socket)
    )
    r = await http.post("/api/login", json={"user": "operator", "password": ACCOUNTS["operator"]})
    assert r.status == 200, await r.text()
    return http


async def snapshot_read(ws: aiohttp.ClientWebSocketResponse) -> list[dict]:
    """The snapshot's messages, up to its alarms (a page that reads no more after them)."""
    got: list[dict] = []
    while not got or got[-1]["type"] != FeedType.ALARMS:
        got.append(json.loads((await ws.receive(10)).data))
    return got


async def read_until(ws: aiohttp.ClientWebSocketResponse, done, timeout: float = 20.0) -> list[dict]:
    got: list[dict] = []
    deadline = time.monotonic() + timeout
    while not got or not done(got[-1]):
        msg = await ws.receive(max(0.1, deadline - time.monotonic()))
        if msg.type != aiohttp.WSMsgType.TEXT:
            got.append({"type": f"closed: {msg.type.name}"})
            break
        got.append(json.loads(msg.data))
    return got


async def test_a_page_behind_misses_progress_and_trend_only_and_is_told(broker, tmp_path):
    client = publisher(broker)
    client.publish(f"orbitrig/{RIG}/status", json.dumps({"state": "running", "run_id": RUN, "message": "run"}), 1, True)
    dash = await asyncio.to_thread(Dashboard, broker.url, RIG, tmp_path, "--tick", "30")
    try:
        async with await signed_in(dash) as http:
            ws = await http.ws_connect("/api/feed", compress=0)
            await snapshot_read(ws)
            watcher = await http.ws_connect("/api/feed", compress=0)  # a page that reads on
            await snapshot_read(watcher)
            said = await asyncio.to_thread(flood, client, 6000, 100)  # the first page reads nothing meanwhile
            client.publish(f"orbitrig/{RIG}/note", json.dumps({"run_id": RUN, "message": "w-1"}), qos=1)
            await read_until(watcher, lambda m: told(m) == (FeedType.NOTE, -1))  # the session has it all
            got = await read_until(ws, lambda m: told(m) == (FeedType.NOTE, -1))
    finally:
        client.disconnect()
        assert await asyncio.to_thread(dash.stop) == 0, dash.text()[-3000:]
    assert in_order(got) == [*said, (FeedType.NOTE, -1)]  # every one, in order
    gaps = [m["data"] for m in got if m["type"] == FeedType.GAP]
    assert gaps and all(g["caught_up"] and set(g["dropped"]) <= {"progress", "trend"} for g in gaps), gaps
    dropped = sum(g["dropped"].get("progress", 0) for g in gaps)
    came = sum(m["type"] == FeedType.PROGRESS for m in got)
    assert dropped > 1000 and came + dropped <= 6000, (dropped, came)
    assert sum(m["type"] == FeedType.LIVE for m in got) < 6000 - dropped  # only the newest live waited


async def test_a_page_behind_with_only_results_waiting_is_cut_and_gets_the_snapshot_again(broker, tmp_path):
    client = publisher(broker)
    dash = await asyncio.to_thread(Dashboard, broker.url, RIG, tmp_path, "--tick", "30")
    try:
        async with await signed_in(dash) as http:
            ws = await http.ws_connect("/api/feed", compress=0)
            await snapshot_read(ws)
            watcher = await http.ws_connect("/api/feed", compress=0)  # a page that reads on
            await snapshot_read(watcher)
            for i in range(4000):  # results only: none the page may miss
                body = {"run_id": RUN, "index": i, "identification": [], "pad": PAD}
                client.publish(f"orbitrig/{RIG}/result", json.dumps(body), qos=1)
            client.publish(f"orbitrig/{RIG}/result", json.dumps({"run_id": RUN, "index": 4000}), 1).wait_for_publish(10)
            await read_until(watcher, lambda m: told(m) == (FeedType.RESULT, 4000))  # the session has it all
            got = await read_until(ws, lambda m: told(m) == (FeedType.RESULT, 4000))
            again = await http.ws_connect("/api/feed", compress=0)
            fresh = await snapshot_read(again)
    finally:
        client.disconnect()
        assert await asyncio.to_thread(dash.stop) == 0, dash.text()[-3000:]
    assert got[-1]["type"].startswith("closed"), [m["type"] for m in got[-3:]]
    indices = [i for kind, i in in_order(got) if kind == FeedType.RESULT]
    assert indices == list(range(len(indices)))  # those that came, in order, none left out between
    assert fresh[0]["type"] == FeedType.HELLO
    last_500 = list(range(3501, 4001))  # the session's results kept for a snapshot
    assert [m["data"]["index"] for m in fresh if m["type"] == FeedType.RESULT] == last_500
    assert "its feed is closed" in dash.text()
