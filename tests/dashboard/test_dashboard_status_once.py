"""Each status of the rig watched reaches the page once, on a real mosquitto and a real `orbitrig dashboard`:
the session subscribes to the rig's status and, to list the rigs, to every rig's (`orbitrig/+/status`), and
mosquitto hands a message on once per matching subscription, each copy with its subscription identifier
(orbitrig.dashboard.catchup.Via). Counted at the page's websocket: each status once, the progress a status
names once, the rigs listed once per change."""

from __future__ import annotations

import asyncio
import json

import aiohttp
from support.dash_helpers import RIG, Dashboard, publish_as_service
from support.mqtt_helpers import ACCOUNTS

from orbitrig.dashboard.feed import FeedType

RUN = "r-once"


async def feed_until_note(dash: Dashboard, broker, statuses: list[dict]) -> list[dict]:
    """What a signed-in page's feed brings after its snapshot while ``statuses`` are published, up to a
    warning published after them."""
    async with aiohttp.ClientSession(dash.url, cookie_jar=aiohttp.CookieJar(unsafe=True)) as http:
        r = await http.post("/api/login", json={"user": "viewer", "password": ACCOUNTS["viewer"]})
        assert r.status == 200, await r.text()
        async with http.ws_connect("/api/feed") as ws:
            while json.loads((await ws.receive(10)).data)["type"] != FeedType.ALARMS:  # the snapshot
                pass
            for status in statuses:
                await asyncio.to_thread(publish_as_service, broker, "status", status, retain=True)
            await asyncio.to_thread(publish_as_service, broker, "note", {"run_id": RUN, "message": "the end"})
            got: list[dict] = []
            while not got or got[-1]["type"] != FeedType.NOTE:
                got.append(json.loads((await ws.receive(10)).data))
    return got


async def test_each_status_reaches_the_page_once(broker, tmp_path):
    progress = {"run_id": RUN, "point": 1, "points": 3, "fraction": 0.25}
    statuses = [
        {"state": "running", "run_id": RUN, "since": "2026-12-07T20:00:00.000Z", "message": "measuring 1"},
        {
            "state": "paused",
            "run_id": RUN,
            "since": "2026-12-07T20:01:00.000Z",
            "message": "paused",
            "progress": progress,
        },
        {"state": "idle", "run_id": RUN, "since": "2026-12-07T20:02:00.000Z", "message": "run stopped"},
    ]
    dash = await asyncio.to_thread(Dashboard, broker.url, RIG, tmp_path)
    try:
        got = await feed_until_note(dash, broker, statuses)
    finally:
        assert await asyncio.to_thread(dash.stop) == 0, dash.text()[-3000:]
    assert [m["data"] for m in got if m["type"] == FeedType.STATUS] == statuses, [m["type"] for m in got]
    assert [m["data"] for m in got if m["type"] == FeedType.PROGRESS] == [progress]
    listed = [m["data"][RIG]["state"] for m in got if m["type"] == FeedType.RIGS]
    assert listed == ["running", "paused", "idle"], listed
