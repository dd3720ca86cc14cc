"""Payloads with NaN or infinity on a real mosquitto (written as another publisher or an older service would:
`NaN`, `Infinity`, `1e999`, which JSON has not), read by a real `orbitrig dashboard` (orbitrig.dashboard.finite):
each such number reaches the page as null, the message naming the fields (`non_finite`), the log naming the topic;
the page's feed goes on with later statuses and a page (re)loaded gets the whole snapshot. The rig service itself
writes a non-finite number as null (orbitrig.service.protocol.dumps). And the rigs listed by a session: a status
larger than rigs.LATEST_KEPT listed, not kept, a rig whose retained status is cleared forgotten."""

from __future__ import annotations

import asyncio
import json
import math
import subprocess

import aiohttp
import pytest
from support.dash_helpers import RIG, Dashboard, fresh_page
from support.mqtt_helpers import ACCOUNTS, Broker

import orbitrig.service.protocol as proto
from orbitrig.dashboard.feed import Feed, FeedType
from orbitrig.dashboard.finite import NAMED, read_finite
from orbitrig.dashboard.rigs import LATEST_KEPT
from orbitrig.dashboard.session import DashboardSettings, Session

RUN = "r-nan"
STATUS_NAN = (
    '{"state": "running", "run_id": "r-nan", "since": "2026-12-07T21:00:00.000Z", "message": "measuring",'
    ' "progress": {"run_id": "r-nan", "point": 1, "points": 2, "eta_s": NaN, "fraction": Infinity}}'
)
RESULT_NAN = '{"run_id": "r-nan", "index": 0, "identification": [{"K": [1.5e7, NaN, -Infinity, 2.0]}], "rms_m": 1e999}'
LATER = {"state": "idle", "run_id": RUN, "since": "2026-12-07T21:05:00.000Z", "message": "run completed"}


def publish(broker: Broker, leaf: str, text: str, retain: bool = False) -> None:
    done = broker.pub(f"orbitrig/{RIG}/{leaf}", text, user="orbitrig-service", retain=retain)
    assert done.returncode == 0, done.stderr


async def read_until(ws: aiohttp.ClientWebSocketResponse, done, timeout: float = 15.0) -> list[dict]:
    """The page's messages (each parsed as a browser does: no NaN) until ``done(message)``."""
    got: list[dict] = []
    async with asyncio.timeout(timeout):
        while not got or not done(got[-1]):
            got.append(json.loads((await ws.receive()).data, parse_constant=lambda c: pytest.fail(f"{c} sent")))
    return got


def test_the_rig_service_publishes_no_nan():
    text = proto.dumps({"eta_s": math.nan, "k": [math.inf, -math.inf, 1.0]})
    assert json.loads(text, parse_constant=lambda c: pytest.fail(c)) == {"eta_s": None, "k": [None, None, 1.0]}


def test_the_page_says_the_fields_and_goes_on_after_a_reload(broker, driver, tmp_path):
    publish(broker, "status", STATUS_NAN, retain=True)
    dash = Dashboard(broker.url, RIG, tmp_path)
    try:
        page = fresh_page(driver, dash)
        page.sign_in("viewer", ACCOUNTS["viewer"])
        page.signed_in()
        page.wait_state("running", 20)
        said = "the status published came with NaN or infinity in progress.eta_s, progress.fraction: shown as not known"
        page.wait_text("events", lambda t: said in t, 20)
        publish(broker, "result", RESULT_NAN)
        page.wait_text("events", lambda t: "identification.0.K.1, identification.0.K.2, rms_m" in t, 20)
        publish(broker, "status", json.dumps(LATER), retain=True)
        page.wait_state("idle", 20)
        driver.refresh()  # a reload: its feed's snapshot has the result, its fields said again
        page.signed_in()
        page.wait_state("idle", 20)
        page.wait_text("events", lambda t: "the result published came with NaN or infinity in" in t, 20)
    finally:
        assert dash.stop() == 0, dash.text()[-3000:]


def test_a_payload_is_made_finite_naming_the_fields():
    text = '{"m": "NaN seen", "a": [1e308, 1e999, -1E+400], "b": {"c": NaN}, "d": [Infinity] }'
    assert read_finite(text) == (
        {"m": "NaN seen", "a": [1e308, None, None], "b": {"c": None}, "d": [None]},
        ["a.1", "a.2", "b.c", "d.0"],
    )
    plain = b'{"m": "NaN seen", "k": 1.5e+07}'
    for large in ("9" * 309 + ".0", "1" * 250 + "e60", "-1e0400"):  # each alone: nothing else marks it
        assert read_finite(f'{{"x": {large}}}') == ({"x": None}, ["x"]), large
    assert read_finite("[1e-999, " + "9" * 400 + "]") == ([0.0, int("9" * 400)], [])
    assert read_finite(plain) == ({"m": "NaN seen", "k": 1.5e7}, [])
    many = read_finite("[" + ",".join(["NaN"] * (NAMED + 5)) + "]")
    assert many[0] == [None] * (NAMED + 5) and many[1] == [str(i) for i in range(NAMED)] + ["... and 5 more"]


async def test_nan_from_the_broker_reaches_the_page_as_null_and_the_feed_goes_on(broker, tmp_path):
    await asyncio.to_thread(publish, broker, "status", STATUS_NAN, True)  # retained: every snapshot has it
    dash = await asyncio.to_thread(Dashboard, broker.url, RIG, tmp_path, "--tick", "0.5")
    try:
        async with aiohttp.ClientSession(dash.url, cookie_jar=aiohttp.CookieJar(unsafe=True)) as http:
            r = await http.post("/api/login", json={"user": "viewer", "password": ACCOUNTS["viewer"]})
            assert r.status == 200, await r.text()
            async with http.ws_connect("/api/feed") as ws:
                snapshot = await read_until(ws, lambda m: m["type"] == FeedType.ALARMS)
                statuses = [m for m in snapshot if m["type"] == FeedType.STATUS]
                if not statuses:  # the retained status came after the snapshot
                    statuses = [(await read_until(ws, lambda m: m["type"] == FeedType.STATUS))[-1]]
                progress = {"run_id": RUN, "point": 1, "points": 2, "eta_s": None, "fraction": None}
                assert statuses[-1]["data"]["progress"] == progress
                assert statuses[-1]["non_finite"] == ["progress.eta_s", "progress.fraction"]
                await asyncio.to_thread(publish, broker, "result", RESULT_NAN)
                await asyncio.to_thread(publish, broker, "live", '{"run_id": "r-nan", "aux": {"p_supply": NaN}}')
                await asyncio.to_thread(publish, broker, "status", json.dumps(LATER), True)
                got = await read_until(ws, lambda m: m["type"] == FeedType.STATUS and m["data"] == LATER)
            result = next(m for m in got if m["type"] == FeedType.RESULT)
            assert result["data"]["identification"] == [{"K": [1.5e7, None, None, 2.0]}]
            assert result["data"]["rms_m"] is None
            assert result["non_finite"] == ["identification.0.K.1", "identification.0.K.2", "rms_m"]
            live = next(m for m in got if m["type"] == FeedType.LIVE)
            assert live["data"]["aux"] == {"p_supply": None} and live["non_finite"] == ["aux.p_supply"]
            assert "non_finite" not in got[-1]
            async with http.ws_connect("/api/feed") as ws:  # a reload: the whole snapshot, the result kept in it
                again = await read_until(ws, lambda m: m["type"] == FeedType.ALARMS)
            body = f'{{"cmd": "start", "rig": "orbitrig/{RIG}", "plan": "p.toml", "speed": -Infinity}}'
            r = await http.post("/api/cmd", data=body, headers={"Content-Type": "application/json"})
            assert r.status == 400 and "-Infinity is not JSON" in (await r.json())["error"], await r.text()
        kinds = [m["type"] for m in again]
        assert kinds[0] == FeedType.HELLO and FeedType.STATUS in kinds, kinds
        assert [m["data"] for m in again if m["type"] == FeedType.STATUS] == [LATER]
        assert [m for m in again if m["type"] == FeedType.RESULT] == [result]
    finally:
        assert await asyncio.to_thread(dash.stop) == 0, dash.text()[-3000:]
    said = [line for line in dash.text().splitlines() if "NaN or infinity" in line]
    assert any(f"orbitrig/{RIG}/result" in line and "identification.0.K.1" in line for line in said), said
    assert any(f"orbitrig/{RIG}/status" in line and "progress.eta_s" in line for line in said), said


async def test_a_message_that_cannot_be_written_is_dropped_and_the_feed_goes_on(caplog):
    """A message the server made with a NaN (none of the broker's payloads: those are made finite) is not sent,
    the log says its kind and topic; the message after it is sent."""
    feed = Feed()
    feed.put({"type": FeedType.TREND, "run_id": RUN, "sample": {"t": math.inf}})
    feed.put({"type": FeedType.NOTE, "data": {"message": "after"}})
    taken = await asyncio.wait_for(feed.take_written(), 1.0)
    assert [(m["type"], json.loads(t)) for m, t in taken] == [
        (FeedType.NOTE, {"type": "note", "data": {"message": "after"}})
    ]
    assert feed.bytes == 0 and feed.counted == 0
    assert any("a trend message cannot be written" in r.getMessage() for r in caplog.records), caplog.text


def clear(broker: Broker, topic: str) -> None:
    """The retained message of ``topic`` cleared (an empty retained payload, mosquitto_pub -n)."""
    args = ["mosquitto_pub", *broker.client_args("orbitrig-service"), "-q", "1", "-t", topic, "-r", "-n"]
    done = subprocess.run(args, capture_output=True, timeout=10, check=False)
    assert done.returncode == 0, done.stderr


async def signed_in(broker: Broker) -> tuple[Session, Feed]:
    session = Session(
        DashboardSettings(host="127.0.0.1", port=broker.port, topics=proto.topics(RIG)), "viewer", ACCOUNTS["viewer"]
    )
    await session.open()
    feed = Feed()
    session.feeds.add(feed)
    return session, feed


async def test_the_rigs_listed_keep_no_large_status_and_forget_one_cleared(broker):
    small, large = "nan-rig-small", "nan-rig-large"
    status = {"state": "idle", "run_id": "r1", "since": "2026-12-07T21:00:00.000Z", "message": "ready"}
    big = {**status, "settings": {"note": "x" * LATEST_KEPT}}
    for rig, body in ((small, status), (large, big)):
        done = await asyncio.to_thread(
            broker.pub, f"orbitrig/{rig}/status", json.dumps(body), user="orbitrig-service", retain=True
        )
        assert done.returncode == 0, done.stderr
    session, feed = await signed_in(broker)
    try:
        async with asyncio.timeout(10):
            while not {small, large} <= set(session.rigs.statuses):
                await asyncio.sleep(0.02)
        assert session.rigs.latest[small] == status  # whole: read as the status of a rig chosen
        assert large not in session.rigs.latest  # too large: not read as its status, its own copy is waited for
        assert session.rigs.listing()[large] == {"state": "idle", "message": "ready", "last_will": False}
        await asyncio.to_thread(clear, broker, f"orbitrig/{small}/status")
        got: list[dict] = []
        async with asyncio.timeout(10):
            while not any(m["type"] == FeedType.RIGS and small not in m["data"] for m in got):
                got += await feed.take()
        listed = [m["data"] for m in got if m["type"] == FeedType.RIGS][-1]
        assert large in listed and small not in listed
        assert small not in session.rigs.latest and small not in session.rigs.heard_at
    finally:
        await session.close("test over")
        await asyncio.to_thread(clear, broker, f"orbitrig/{large}/status")


async def test_the_watched_rig_whose_status_is_cleared_is_shown_with_no_status(broker):
    status = {"state": "idle", "run_id": "r1", "since": "2026-12-07T21:00:00.000Z", "message": "ready"}
    again = {**status, "since": "2026-12-07T21:10:00.000Z", "message": "back"}
    await asyncio.to_thread(publish, broker, "status", json.dumps(status), True)
    session, feed = await signed_in(broker)
    try:
        async with asyncio.timeout(10):
            while session.status != status:
                await asyncio.sleep(0.02)
        await asyncio.to_thread(clear, broker, f"orbitrig/{RIG}/status")
        got: list[dict] = []
        async with asyncio.timeout(10):
            while not any(m["type"] == FeedType.RIG for m in got):
                got += await feed.take()
        assert session.status is None and RIG not in session.rigs.listing()
        assert FeedType.STATUS not in [m["type"] for m in session.snapshot()]  # a page loaded now: no status either
        await asyncio.to_thread(publish, broker, "status", json.dumps(again), True)  # the rig's next status shown
        async with asyncio.timeout(10):
            while not any(m["type"] == FeedType.STATUS for m in got[after_rig(got) :]):
                got += await feed.take()
        rig = [m for m in got if m["type"] == FeedType.RIG]
        assert rig == [{"type": FeedType.RIG, "prefix": f"orbitrig/{RIG}"}], got  # once: the clear comes twice
        assert [m["data"] for m in got if m["type"] == FeedType.STATUS] == [status, again], got
        assert session.status == again
    finally:
        await session.close("test over")
        await asyncio.to_thread(clear, broker, f"orbitrig/{RIG}/status")


def after_rig(got: list[dict]) -> int:
    """The index after the first ``rig`` message of ``got``."""
    return next(i for i, m in enumerate(got) if m["type"] == FeedType.RIG) + 1


async def test_a_rig_chosen_is_shown_with_the_fields_its_listed_status_had_as_nan(broker):
    """A rig chosen is shown at once with its status as the rigs listed it (before the broker confirms the
    subscription to it; the retained copy that then comes is not sent again): its NaN fields are named too."""
    other = "nan-rig-chosen"
    done = await asyncio.to_thread(
        broker.pub, f"orbitrig/{other}/status", STATUS_NAN, user="orbitrig-service", retain=True
    )
    assert done.returncode == 0, done.stderr
    session, feed = await signed_in(broker)
    try:
        async with asyncio.timeout(10):
            while other not in session.rigs.latest:
                await asyncio.sleep(0.02)
        assert (await session.select_rig(other))["ok"]
        assert session.status_non_finite == ["progress.eta_s", "progress.fraction"]
        got: list[dict] = []
        async with asyncio.timeout(10):
            while not any(m["type"] == FeedType.STATUS and m["data"]["run_id"] == RUN for m in got):
                got += await feed.take()
        status = next(m for m in got if m["type"] == FeedType.STATUS and m["data"]["run_id"] == RUN)
        assert status["non_finite"] == ["progress.eta_s", "progress.fraction"]
        snapshot = [m for m in session.snapshot() if m["type"] == FeedType.STATUS]
        assert [m["non_finite"] for m in snapshot] == [["progress.eta_s", "progress.fraction"]]
    finally:
        await session.close("test over")
        await asyncio.to_thread(clear, broker, f"orbitrig/{other}/status")
