"""docs/protocols/dashboard-feed.md against what a real `orbitrig dashboard` sends a page on a real,
authenticated mosquitto: every message kind of the feed documented, and every field a message carries
(a path into it: `data.*.state`) documented for its kind, every field said `always` there. The two kinds
a broker outage or a late reply makes are checked from their one builder each."""

from __future__ import annotations

import asyncio
import json
import re
import time
from pathlib import Path
from typing import Any

import aiohttp
from support.dash_helpers import RIG, Dashboard, publish_as_service
from support.mqtt_helpers import ACCOUNTS

from orbitrig.dashboard.catchup import gap_message
from orbitrig.dashboard.commands import late_reply
from orbitrig.dashboard.feed import Feed, FeedType

DOC = Path(__file__).resolve().parents[2] / "docs" / "protocols" / "dashboard-feed.md"
_KIND = re.compile(r"^### `(\w+)`$", re.MULTILINE)
_ROW = re.compile(r"^\| `([\w.*]+)` \|[^|]*\|[^|]*\| ([^|]*) \|$", re.MULTILINE)
RUN = "r-feed"
LIVE = {"run_id": RUN, "drives": {"spin": {"actual_rpm": 1000.0, "reference_rpm": 1000.0}}, "aux": {"p_supply": 4.8e5}}


def documented() -> dict[str, dict[str, bool]]:
    """Kind -> {field path: always there} of the page."""
    text = DOC.read_text(encoding="utf-8")
    parts = _KIND.split(text)[1:]
    return {
        kind: {f: present.startswith("always") for f, present in _ROW.findall(body)}
        for kind, body in zip(parts[::2], parts[1::2])
    }


def paths(value: Any, doc: set[str], prefix: str = "") -> set[str]:
    """The field paths of ``value``, taken apart as deep as ``doc`` documents (``*``: each entry)."""
    out = {prefix} if prefix else set()
    if not any(p.startswith(prefix + ".") for p in doc) and prefix:
        return out
    items = value.items() if isinstance(value, dict) else [("*", v) for v in value] if isinstance(value, list) else []
    for key, v in items:
        name = f"{prefix}.{key}" if prefix else key
        if prefix and any(p == f"{prefix}.*" or p.startswith(f"{prefix}.*.") for p in doc):
            name = f"{prefix}.*"
        out |= paths(v, doc, name)
    return out


def undocumented(message: dict, doc: dict[str, dict[str, bool]]) -> list[str]:
    """What ``message`` carries that its kind's table does not say, and what it lacks that the table says always."""
    fields = doc.get(message["type"])
    if fields is None:
        return [f"kind {message['type']!r}"]
    have = paths(message, set(fields))
    said = {f.rsplit(".", n)[0] for f in fields for n in range(f.count(".") + 1)}  # and the entries on the way
    # an `always` field is missing when its parent is there (`data.*.state` of each entry a `data` has)
    missing = {f for f, always in fields.items() if always and ("." not in f or f.rsplit(".", 1)[0] in have)} - have
    return sorted(have - said) + [f"missing {f}" for f in sorted(missing)]


async def collect(ws: aiohttp.ClientWebSocketResponse, into: list[dict]) -> None:
    async for msg in ws:
        if msg.type == aiohttp.WSMsgType.TEXT:
            into.append(json.loads(msg.data))


async def until(got: list[dict], kind: str, timeout: float = 10.0, after: int = 0) -> dict:
    """The first message of ``kind`` in ``got`` from index ``after`` on, once it came."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = [m for m in got[after:] if m["type"] == kind]
        if found:
            return found[0]
        await asyncio.sleep(0.05)
    raise AssertionError(f"no {kind} within {timeout} s: {[m['type'] for m in got]}")


def test_the_page_documents_every_kind_of_the_feed():
    assert set(documented()) == {k.value for k in FeedType}
    assert all(fields.get("type") for fields in documented().values())


def test_a_gap_and_a_late_outcome_are_as_documented():
    doc = documented()
    assert undocumented(gap_message("2026-12-05T01:00:00.000Z", True), doc) == []
    assert undocumented({"type": "gap", "data": {"from": "2026-12-05T01:00:00.000Z"}}, doc) == [
        "missing data.caught_up",
        "missing data.to",
    ]
    behind = Feed(limit=2)  # a page behind: progress left out for it, told by a gap
    for i in range(3):
        behind.put({"type": FeedType.PROGRESS, "data": {"point": i}})
    taken = asyncio.run(behind.take())
    assert [m["type"] for m in taken] == ["gap", "progress", "progress"]
    assert undocumented(json.loads(json.dumps(taken[0])), doc) == []
    for reply, rig in (({"ok": True, "detail": "stopped"}, "orbitrig/rig-b"), ({"ok": False, "error": "no run"}, None)):
        outcome = {"type": FeedType.OUTCOME, "data": late_reply("abort", reply, 4.2, rig)}
        assert undocumented(json.loads(json.dumps(outcome)), doc) == []


async def test_what_a_real_dashboard_sends_is_as_documented(broker, tmp_path):
    pub = asyncio.to_thread
    await pub(publish_as_service, broker, "status", {"state": "running", "run_id": RUN, "message": "run"}, retain=True)
    dash = await asyncio.to_thread(Dashboard, broker.url, RIG, tmp_path, "--tick", "0.5", "--reply-timeout", "0.5")
    first: list[dict] = []
    again: list[dict] = []
    try:
        async with aiohttp.ClientSession(dash.url, cookie_jar=aiohttp.CookieJar(unsafe=True)) as http:
            r = await http.post("/api/login", json={"user": "operator", "password": ACCOUNTS["operator"]})
            assert r.status == 200, await r.text()
            ws = await http.ws_connect("/api/feed")
            reader = asyncio.create_task(collect(ws, first))
            await until(first, "status")
            await pub(publish_as_service, broker, "progress", {"run_id": RUN, "point": 1, "points": 2, "eta_s": 60.0})
            await pub(publish_as_service, broker, "live", LIVE, qos=0)
            await pub(
                publish_as_service, broker, "note", {"run_id": RUN, "level": "warning", "message": "journal gone"}
            )
            fit = {"coefficients": {"Kxx": 1.5e7}, "warnings": ["u_Kxx large"]}
            await pub(publish_as_service, broker, "result", {"run_id": RUN, "index": 0, "identification": [fit]})
            await until(first, "trend")
            n = len(first)
            await pub(
                publish_as_service,
                broker,
                "status",
                {"state": "paused", "run_id": RUN, "message": "suspended by interlock: supply pressure low"},
                retain=True,
            )
            await until(first, "alarms", after=n)
            await pub(
                publish_as_service,
                broker,
                "status",
                {"state": "idle", "run_id": RUN, "message": "run completed"},
                retain=True,
            )
            stop = await http.post("/api/cmd", json={"cmd": "stop", "rig": f"orbitrig/{RIG}"})
            assert stop.status == 200 and not (await stop.json())["ok"]
            done = broker.pub(
                "orbitrig/rig-b/status",
                json.dumps({"state": "idle", "message": "ready"}),
                user="orbitrig-service",
                retain=True,
            )
            assert done.returncode == 0, done.stderr
            await until(first, "tick", after=len(first))
            running = {"state": "running", "run_id": RUN + "-2", "message": "run"}
            n = len(first)
            await pub(publish_as_service, broker, "status", running, retain=True)
            await pub(publish_as_service, broker, "live", {**LIVE, "run_id": RUN + "-2"}, qos=0)
            await until(first, "live", after=n)

            ws2 = await http.ws_connect("/api/feed")  # a page (re)loaded: the session's snapshot
            reader2 = asyncio.create_task(collect(ws2, again))
            await until(again, "tick")
            r = await http.post("/api/rig", json={"rig": "rig-b"})
            assert (await r.json())["ok"], await r.text()
            await until(first, "rig")
            await http.post("/api/logout")
            await until(first, "signed_out")
            await asyncio.wait_for(asyncio.gather(reader, reader2), 5)
    finally:
        assert await asyncio.to_thread(dash.stop) == 0, dash.text()[-3000:]
        await pub(
            publish_as_service, broker, "status", {"state": "idle", "run_id": None, "message": "ready"}, retain=True
        )
    doc = documented()
    wrong = {json.dumps(m)[:300]: undocumented(m, doc) for m in first + again if undocumented(m, doc)}
    assert wrong == {}
    seen = {m["type"] for m in first + again}
    assert seen == {k.value for k in FeedType} - {FeedType.GAP, FeedType.OUTCOME}  # those two: from their builders
    snapshot = [m["type"] for m in again]
    assert snapshot[:3] == ["hello", "link", "rigs"] and {"ending", "outcomes", "live"} <= set(snapshot)
    assert [m for m in again if m["type"] == "live"][0]["age_s"] >= 0
