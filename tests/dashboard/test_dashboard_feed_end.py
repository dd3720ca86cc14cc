"""A browser's feed (dashboard/server.py `_send_loop`) ends when its connection's handler cancels
it, also when the cancel arrives as a message for the browser is taken or any few loop turns after:
the sender never runs on (waiting a tick, sending) with its handler's end waiting on it. Over a real
websocket (aiohttp, a local socket). (asyncio.wait_for of Python 3.11 took such a cancel.)"""

from __future__ import annotations

import asyncio
import json

import aiohttp
from aiohttp import web

from orbitrig.dashboard.feed import Feed, FeedType
from orbitrig.dashboard.server import _send_loop

TICK_S = 30.0  # no tick comes during the test: only the messages put


async def test_the_feed_ends_on_a_cancel_arriving_as_a_message_is_taken():
    ended: list[tuple[int, bool, bool]] = []  # (turns, the sender took the cancel, it ended within 2 s)

    async def handler(request: web.Request) -> web.WebSocketResponse:
        ws = web.WebSocketResponse()
        await ws.prepare(request)
        for turns in range(8):
            queue = Feed()
            sender = asyncio.create_task(_send_loop(ws, queue, TICK_S))
            await asyncio.sleep(0.01)  # waiting for a message
            queue.put({"type": FeedType.NOTE, "turns": turns})
            for _ in range(turns):
                await asyncio.sleep(0)
            took = sender.cancel()
            done, _ = await asyncio.wait([sender], timeout=2.0)
            ended.append((turns, took, bool(done)))
        await ws.close()
        return ws

    app = web.Application()
    app.router.add_get("/ws", handler)
    runner = web.AppRunner(app)
    await runner.setup()
    site = web.TCPSite(runner, "127.0.0.1", 0)
    await site.start()
    port = site._server.sockets[0].getsockname()[1]  # type: ignore[union-attr]
    try:
        async with aiohttp.ClientSession() as http, http.ws_connect(f"http://127.0.0.1:{port}/ws") as ws:
            got = [json.loads(m.data)["turns"] async for m in ws if m.type == aiohttp.WSMsgType.TEXT]
    finally:
        await runner.cleanup()
    assert [t for t, _, _ in ended] == list(range(8))
    assert all(took for _, took, _ in ended)  # each sender was waiting or sending: it took the cancel
    assert all(done for _, _, done in ended), f"a sender ran on after its cancel: {ended}"
    assert set(got) <= set(range(8))
