"""One page's queue (orbitrig.dashboard.feed.Feed) when the page stops reading while a batch is being
written to it: what waits for it, taken or not, stays within the queue's limit and one batch, and the
progress left out for it is told by a gap; every result comes, in order. On asyncio's own loop, the
feed as the server's writer takes from it."""

from __future__ import annotations

from orbitrig.dashboard.feed import BATCH, Feed, FeedType

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
