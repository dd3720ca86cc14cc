"""One page's queue (orbitrig.dashboard.feed.Feed) when the page stops reading while a batch is being
written to it: what waits for it, taken or not, stays within the queue's limit and one batch, and the
progress left out for it is told by a gap; every result comes, in order. On asyncio's own loop, the
feed as the server's writer takes from it."""

from __future__ import annotations

import json

from orbitrig.dashboard.feed import BATCH, LIMIT_BYTES, Feed, FeedType, text

LIMIT = 2000


def progress(i: int) -> dict:
    return {"type": FeedType.PROGRESS, "data": {"point": i}}


async def test_a_page_stalled_mid_write_holds_the_limit_and_one_batch_at_most():
    feed = Feed(LIMIT)
    for i in range(1990):  # a page reading slower than the rig says: its queue nearly full
        feed.put(progress(i))
    taken = await feed.take()  # the writer takes, then the page stops reading: these wait in the writer
    for i in range(1990, 6000):
        feed.put(progress(i))
        if i % 100 == 0:
            feed.put({"type": FeedType.RESULT, "data": {"index": i}})
    held = len(taken) + len(feed.queue)
    assert held <= LIMIT + BATCH, held  # 3,990 when the writer took the whole queue at once
    got = list(taken)
    while feed.queue:
        got += await feed.take()
    points = [m["data"]["point"] for m in got if m["type"] == FeedType.PROGRESS]
    dropped = sum(m["data"]["dropped"]["progress"] for m in got if m["type"] == FeedType.GAP)
    assert points == sorted(points) and len(points) + dropped == 6000, (len(points), dropped)
    assert len(points) <= LIMIT + BATCH - 40  # the 40 results waited among them
    results = [m["data"]["index"] for m in got if m["type"] == FeedType.RESULT]
    assert results == list(range(2000, 6000, 100))
    assert not feed.behind.is_set()


async def test_a_take_hands_on_a_batch_and_the_newest_live_and_the_rest_stay_queued():
    feed = Feed(LIMIT)
    for i in range(BATCH + 10):
        feed.put(progress(i))
    feed.put({"type": FeedType.LIVE, "data": {"n": 1}})
    feed.put({"type": FeedType.LIVE, "data": {"n": 2}})
    first = await feed.take()
    assert [m["data"].get("point") for m in first[:-1]] == list(range(BATCH))
    assert first[-1] == {"type": FeedType.LIVE, "data": {"n": 2}}
    assert feed.wake.is_set()  # the rest: taken next, without waiting for another message
    assert [m["data"]["point"] for m in await feed.take()] == list(range(BATCH, BATCH + 10))
    assert not feed.wake.is_set()


def rigs(n: int, state: str = "running") -> dict:
    """The rigs listed: rig-000 to rig-<n - 1>, each in ``state``."""
    listed = {f"rig-{i:03}": {"state": state, "message": "", "last_will": False, "link_lost": False} for i in range(n)}
    return {"type": FeedType.RIGS, "data": listed}


async def drain(feed: Feed) -> list[dict]:
    """Everything waiting, as the writer takes it."""
    got: list[dict] = []
    while feed.wake.is_set():
        got += await feed.take()
    return got


async def test_a_stalled_page_has_only_the_newest_of_each_kind_it_draws_wholly_from_the_newest():
    feed = Feed()
    for n in range(1, 501):  # 500 rigs coming on line while the page reads nothing: 500 listings
        feed.put(rigs(n))
        feed.put({"type": FeedType.LINK, "link": "online" if n % 2 else "broker unreachable"})
        feed.put({"type": FeedType.ALARMS, "data": [{"id": f"a{i}"} for i in range(n % 7)]})
        feed.put({"type": FeedType.STATUS, "data": {"state": "running", "message": f"s{n}"}})
    assert len(feed.queue) == 3 + 500  # a listing, a link, the alarms; every status
    assert feed.bytes == sum(len(text(w.message)) for w in feed.queue.values())
    got = await drain(feed)
    assert [m for m in got if m["type"] == FeedType.RIGS] == [rigs(500)]
    assert [m["link"] for m in got if m["type"] == FeedType.LINK] == ["broker unreachable"]
    assert [m["data"] for m in got if m["type"] == FeedType.ALARMS] == [[{"id": f"a{i}"} for i in range(500 % 7)]]
    assert [m["data"]["message"] for m in got if m["type"] == FeedType.STATUS] == [f"s{n}" for n in range(1, 501)]
    assert [m["type"] for m in got[-4:-1]] == [FeedType.RIGS, FeedType.LINK, FeedType.ALARMS]  # at the newest's place
    assert not any(m["type"] == FeedType.GAP for m in got)  # nothing the page draws is missing: no gap
    assert feed.bytes == 0 and not feed.behind.is_set()


async def test_a_trend_history_of_the_run_view_alone_leaves_a_whole_one_waiting():
    feed = Feed()

    def history(recent, n: int) -> dict:
        return {
            "type": FeedType.TREND_HISTORY,
            "data": {"run_id": "r", "run_step_s": 1.0, "recent": recent, "run": [n]},
        }

    feed.put(history([{"t": 1.0}], 0))  # a whole history (the snapshot's, or a rig chosen)
    for n in range(1, 6):
        feed.put(history(None, n))  # every 300 samples the run view again: recent unchanged (null)
    assert [m["data"]["run"] for m in await drain(feed)] == [[0], [5]]
    for n in range(3):
        feed.put(history(None, n))
    feed.put(history([], 9))  # a whole one replaces them all
    assert [m["data"]["run"] for m in await drain(feed)] == [[9]]


async def test_the_waiting_bytes_are_bounded_progress_going_first_results_never():
    feed = Feed(limit=2000, limit_bytes=LIMIT_BYTES)
    live = {"type": FeedType.LIVE, "data": {"run_id": "r", "waveforms": {"fx": "0.125, " * 43_000}}}  # 0.3 MB each
    result = {"type": FeedType.RESULT, "data": {"index": 0, "pad": "r" * 100_000}}
    for i in range(1000):
        feed.put({"type": FeedType.PROGRESS, "data": {"point": i, "pad": "p" * 20_000}})
        feed.put(live)
        if i % 100 == 0:
            feed.put({**result, "data": {**result["data"], "index": i}})
        assert feed.bytes <= LIMIT_BYTES
    assert feed.bytes == sum(len(text(w.message)) for w in feed.queue.values()) > LIMIT_BYTES - 25_000  # not live
    got = await drain(feed)
    gap = got[0]["data"]["dropped"]
    came = [m["data"]["point"] for m in got if m["type"] == FeedType.PROGRESS]
    assert gap["progress"] + len(came) == 1000 and came == list(range(1000 - len(came), 1000))
    assert 146 < len(came) < 152, len(came)  # (4 MB - 10 results of 0.1 MB) / 20 kB: 149 (the live one not counted)
    assert [m["data"]["index"] for m in got if m["type"] == FeedType.RESULT] == list(range(0, 1000, 100))
    assert [m for m in got if m["type"] == FeedType.LIVE] == [live]
    assert not feed.behind.is_set()


async def test_beyond_the_byte_bound_with_results_only_the_page_is_behind():
    feed = Feed(limit=2000, limit_bytes=LIMIT_BYTES)
    for i in range(39):
        feed.put({"type": FeedType.RESULT, "data": {"index": i, "pad": "r" * 100_000}})
    assert not feed.behind.is_set()  # 3.9 MB
    feed.put({"type": FeedType.RESULT, "data": {"index": 39, "pad": "r" * 100_000}})
    assert feed.behind.is_set() and len(feed.queue) == 40  # cut: the next connection starts with the snapshot


async def test_a_live_payload_never_cuts_a_page():
    feed = Feed(limit=2000, limit_bytes=LIMIT_BYTES)
    for i in range(39):
        feed.put({"type": FeedType.RESULT, "data": {"index": i, "pad": "r" * 100_000}})
    live = {"type": FeedType.LIVE, "data": {"run_id": "r", "waveforms": {"fx": "0.125, " * 43_000}}}  # 0.3 MB
    for _ in range(3):
        feed.put(live)
    assert not feed.behind.is_set() and feed.bytes < LIMIT_BYTES  # 3.9 MB of results and the newest live
    got = await drain(feed)
    assert [m["data"]["index"] for m in got if m["type"] == FeedType.RESULT] == list(range(39))
    assert [m for m in got if m["type"] == FeedType.LIVE] == [live]


def note(name: str) -> dict:
    return {"type": FeedType.NOTE, "data": {"message": name, "pad": "n" * 12_000}}  # 12 kB


async def test_a_snapshot_larger_than_the_bound_waits_beside_it_and_the_bound_is_the_same_once_it_is_taken():
    results = [{"type": FeedType.RESULT, "data": {"index": i, "pad": "r" * 12_000}} for i in range(500)]
    snapshot = [{"type": FeedType.HELLO}, rigs(200), *results]  # 6 MB: a long run's last 500 results
    assert sum(len(json.dumps(m)) for m in snapshot) > LIMIT_BYTES
    feed = Feed()
    feed.start(snapshot)
    assert not feed.behind.is_set() and feed.bytes == feed.counted == 0  # the snapshot counts toward neither bound
    for i in range(330):
        feed.put(note(f"w{i}"))
    assert not feed.behind.is_set() and feed.counted == 330  # 3.97 MB besides the snapshot's 6 MB
    assert await feed.take(len(snapshot)) == snapshot  # the page reads its snapshot, then stalls again
    feed.put(rigs(3))  # a rigs listing: one more
    for i in range(3):
        feed.put(note(f"x{i}"))
    assert feed.behind.is_set()  # beyond 4 MB: the snapshot taken left no room of its own behind
    assert feed.bytes == sum(len(text(w.message)) for w in feed.queue.values()) > LIMIT_BYTES


async def test_a_snapshot_listing_superseded_leaves_the_bounds_as_they_were():
    feed = Feed()
    feed.start([{"type": FeedType.HELLO}, rigs(200), {"type": FeedType.LINK, "link": "online"}])
    feed.put(rigs(3))  # the snapshot's listing goes: the newest waits, at its place, counted
    assert feed.counted == 1 and feed.bytes == len(text(rigs(3)))
    got = await drain(feed)
    assert [m["type"] for m in got] == [FeedType.HELLO, FeedType.LINK, FeedType.RIGS] and got[-1] == rigs(3)
    assert feed.bytes == feed.counted == 0
