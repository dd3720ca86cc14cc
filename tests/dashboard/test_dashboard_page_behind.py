"""A page in a real chromium that falls behind its feed (orbitrig.dashboard.feed.Feed), on a real mosquitto and a
real `orbitrig dashboard`: its feed passes a relay that holds it (HeldFeeds, as on a stalled path) while the rig's
account publishes live values (a trend point a second) and then progress by the thousand; the dashboard server
leaves the oldest trend points and progress out for it and, the feed flowing again, sends a `gap` with their
counts first. The page lists it in its events (static/app.js showFeedBehind), with the counts the server sent:
what it did not show and what it showed add up to what was published; one of a kind in the singular."""

from __future__ import annotations

import asyncio
import base64
import json
import os
import re
import time

import aiohttp
import paho.mqtt.client as mqtt
import pytest
from support.dash_helpers import RIG, Dashboard, HeldFeeds, Page, publish_as_service
from support.mqtt_helpers import ACCOUNTS

from orbitrig.dashboard.feed import Feed, FeedType

RUN = "r-page-behind"
PROGRESS = 6000  # progress messages published while the feed is held (the page's queue holds 2,000)
FILL = 2000  # of them first: about 5 MB, what the socket buffers of the held feed take
SAID = re.compile(
    r"this page fell behind its feed from (\d\d:\d\d:\d\d) to (\d\d:\d\d:\d\d): not shown (\d+) progress updates?, "
    r"(\d+) trend points? \(every result, warning, alarm and status came\)$"
)


@pytest.fixture(scope="module")
def dashboard(broker, tmp_path_factory):
    """The dashboard alone on the broker (the test publishes what the rig service would); a tick of 30 s: the
    page gives its feed up only after 4 ticks of silence, not while it is held."""
    dash = Dashboard(broker.url, RIG, tmp_path_factory.mktemp("dashboard"), "--tick", "30")
    yield dash
    assert dash.stop() == 0, dash.text()[-3000:]


def publisher(broker) -> mqtt.Client:
    """The rig service's account, connected."""
    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=f"mosq-behind-{time.monotonic_ns()}")
    client.username_pw_set("orbitrig-service", ACCOUNTS["orbitrig-service"])
    client.connect("127.0.0.1", broker.port)
    client.loop_start()
    return client


def pad() -> str:
    """3 kB a progress carries besides its fields, new each time: the page's feed is deflated (permessage-deflate),
    and only bytes that do not compress fill the held socket's buffers."""
    return base64.b64encode(os.urandom(2300)).decode()


def flood(client: mqtt.Client, count: int) -> None:
    """``count`` progress messages of the run, handed to the broker."""
    for i in range(count):
        body = {"run_id": RUN, "point": i, "points": PROGRESS, "eta_s": 1.0, "pad": pad()}
        info = client.publish(f"orbitrig/{RIG}/progress", json.dumps(body), qos=1)
    info.wait_for_publish(20)


def session_heard(dashboard: Dashboard, page: Page, said: str, timeout: float = 60.0) -> None:
    """Wait until the page's session has read the warning ``said`` (and all before it): a feed of the session,
    straight to the dashboard, finds it among the kept warnings of its snapshot. The held page's queue is then
    as full as the flood makes it (a dashboard starved of CPU reads the broker later than the flood ends)."""
    cookie = page.d.get_cookie("orbitrig_session")["value"]

    async def heard() -> bool:
        async with aiohttp.ClientSession(dashboard.url, headers={"Cookie": f"orbitrig_session={cookie}"}) as http:
            async with http.ws_connect("/api/feed", compress=0) as ws:
                while (m := json.loads((await ws.receive(20)).data))["type"] != FeedType.ALARMS:
                    if m["type"] == FeedType.NOTE and m["data"].get("message") == said:
                        return True
        return False

    deadline = time.monotonic() + timeout
    while not asyncio.run(heard()):
        assert time.monotonic() < deadline, f"the session did not read {said!r} within {timeout:g} s"
        time.sleep(0.5)


COUNTING = """
window.fedKinds = {}; window.fedGaps = [];
const shown = handle;
window.handle = msg => {
  window.fedKinds[msg.type] = (window.fedKinds[msg.type] || 0) + 1;
  if (msg.type === "gap") window.fedGaps.push(msg.data);
  shown(msg);
};
"""


def test_a_page_behind_lists_what_it_did_not_show(broker, dashboard, browsers):
    publish_as_service(broker, "status", {"state": "running", "run_id": RUN, "message": "measuring"}, retain=True)
    relay = HeldFeeds(dashboard.port)
    client = publisher(broker)
    try:
        page = Page(browsers(), relay.url, dashboard)
        page.sign_in("viewer", ACCOUNTS["viewer"])
        page.signed_in()
        page.wait_state("running", 10)
        page.d.execute_script(COUNTING)  # what the page's feed hands it, by kind (the page's own handler after)
        relay.hold()
        flood(client, FILL)  # the held socket's buffers full: what comes next waits on the page's queue
        live = {"run_id": RUN, "drives": {"spin": {"actual_rpm": 1000.0}}}
        for _ in range(16):  # 3 s of live values: 3 or 4 trend points wait among progress
            client.publish(f"orbitrig/{RIG}/live", json.dumps(live), qos=0)
            time.sleep(0.2)
        flood(client, PROGRESS - FILL)  # the queue overflows: the oldest progress and trend points go
        publish_as_service(broker, "note", {"run_id": RUN, "level": "warning", "message": "after the flood"})
        session_heard(dashboard, page, "after the flood")  # the dashboard has read it all (its queue for the page full)
        relay.release()
        page.wait(lambda: "after the flood" in " ".join(events(page)), 30, "the warning after the flood")
        listed = [m for e in events(page) if (m := SAID.search(e))]
        fed = page.d.execute_script("return [window.fedKinds, window.fedGaps]")
        page.d.execute_script("handle(arguments[0])", one_of_each())
        one = "not shown 1 progress update, 1 trend point (every result, warning, alarm and status came)"
        page.wait(lambda: sum(e.endswith(one) for e in events(page)) == 1, 5, "one of each, in the singular")
    finally:
        client.disconnect()
        relay.release()
        relay.close()
    kinds, gaps = fed
    assert gaps and all(set(g["dropped"]) == {"progress", "trend"} for g in gaps), gaps
    assert len(listed) == len(gaps), (listed, gaps)  # each gap one event
    for said, gap in zip(sorted(listed, key=lambda m: m[1]), sorted(gaps, key=lambda g: g["from"])):
        assert (int(said[3]), int(said[4])) == (gap["dropped"]["progress"], gap["dropped"]["trend"]), (said, gap)
    dropped = sum(g["dropped"]["progress"] for g in gaps)
    assert dropped > 1000 and dropped + kinds.get("progress", 0) == PROGRESS, (dropped, kinds)
    trend_dropped = sum(g["dropped"]["trend"] for g in gaps)
    assert trend_dropped >= 1 and trend_dropped + kinds.get("trend", 0) <= 4, (trend_dropped, kinds)  # 1 a second


def one_of_each() -> dict:
    """The gap the server's Feed (a queue of 2) sends after leaving out one progress and one trend point."""
    queue = Feed(limit=2)
    for message in ({"type": FeedType.TREND}, {"type": FeedType.PROGRESS}, *[{"type": FeedType.NOTE}] * 2):
        queue.put(message)
    gap = asyncio.run(queue.take())[0]
    assert gap["data"]["dropped"] == {"trend": 1, "progress": 1}, gap
    return json.loads(json.dumps(gap))


def events(page: Page) -> list[str]:
    return page.d.execute_script("return [...document.querySelectorAll('#events li')].map(li => li.textContent)")


RIGS = 200  # rigs coming on line, then going idle, while the page's feed is held: 400 listings of up to 200 rigs
LISTED = re.compile(r"^pb-(\d{3}) \((\w+)\)$")


def rigs_on_line(client: mqtt.Client, state: str) -> None:
    """Each of the RIGS rigs' statuses in ``state``, retained, as a rig service's (``state`` "": cleared)."""
    for i in range(RIGS):
        body = json.dumps({"state": state, "run_id": None, "message": f"rig {i}"}) if state else b""
        info = client.publish(f"orbitrig/pb-{i:03}/status", body, qos=1, retain=True)
    info.wait_for_publish(20)


def test_a_page_behind_ends_with_the_newest_rigs_listed(broker, dashboard, browsers):
    """Of the rigs listed only the newest listing waits for a page behind (orbitrig.dashboard.feed.SUPERSEDED): 400
    listings, about 6 MB of JSON, beyond the 4 MB a page's queue holds, would cut the page's feed; one waits, and
    the page, its feed flowing again, lists every rig in its newest state without reconnecting."""
    publish_as_service(broker, "status", {"state": "running", "run_id": RUN, "message": "measuring"}, retain=True)
    relay = HeldFeeds(dashboard.port)
    client = publisher(broker)
    try:
        page = Page(browsers(), relay.url, dashboard)
        page.sign_in("viewer", ACCOUNTS["viewer"])
        page.signed_in()
        page.wait_state("running", 10)
        page.d.execute_script(COUNTING)
        relay.hold()
        flood(client, 2 * FILL)  # the held socket's buffers full, progress waiting: the listings wait behind
        rigs_on_line(client, "running")
        rigs_on_line(client, "idle")
        publish_as_service(broker, "note", {"run_id": RUN, "level": "warning", "message": "after the rigs"})
        session_heard(dashboard, page, "after the rigs")
        relay.release()
        page.wait(lambda: "after the rigs" in " ".join(events(page)), 30, "the warning after the rigs")
        kinds = page.d.execute_script("return window.fedKinds")
        listed = page.d.execute_script(
            "return [...document.querySelectorAll('#rig-select option')].map(o => o.textContent)"
        )
    finally:
        client.disconnect()
        relay.release()
        relay.close()
        rigs_on_line(cleared := publisher(broker), "")  # the retained statuses go
        cleared.disconnect()
    assert 0 < kinds.get("rigs", 0) < 100, kinds  # 400 listings were sent to the session: those waiting merged
    assert "hello" not in kinds, kinds  # the feed was not cut: no new snapshot
    states = {m[1]: m[2] for o in listed if (m := LISTED.match(o))}
    assert states == {f"{i:03}": "idle" for i in range(RIGS)}, listed
