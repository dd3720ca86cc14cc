"""The reply of a stop or abort sent to a rig the session does not watch (orbitrig.dashboard.elsewhere):
the session reads that rig's reply topic from before the command goes until its reply came, and never
drops a subscription of the rig it watches. The client is a stand-in recording what the session asks
of it; the whole path on a real mosquitto with two real rig services is
tests/dashboard/test_dashboard_other_rig_abort.py."""

from __future__ import annotations

import asyncio
import json

from orbitrig.dashboard.catchup import subscriptions
from orbitrig.dashboard.session import DashboardSettings, Session
from orbitrig.service import protocol as proto

A, B = proto.topics("rig-a"), proto.topics("rig-b")


class Broker:
    """A connected client whose publishes the broker takes, and whose stop and abort the rig answers."""

    timeout = 10.0  # s (aiomqtt's client: the bound broker_calls puts on each wait)

    def __init__(self, session: Session, answer: bool = True) -> None:
        self.session, self.answer = session, answer
        self.calls: list[tuple[str, object]] = []

    async def subscribe(self, topic, qos: int = 0, properties=None, *, timeout: float):
        self.calls.append(("subscribe", topic))

    async def unsubscribe(self, topic, *, timeout: float):
        self.calls.append(("unsubscribe", topic))

    def subscribe_nowait(self, topic: str, qos: int) -> bool:
        self.calls.append(("subscribe_nowait", topic))
        return True

    def unsubscribe_nowait(self, topic: str) -> None:
        self.calls.append(("unsubscribe_nowait", topic))

    async def publish_qos1(self, topic: str, payload: str, timeout: float, *, expiry=None) -> int:
        self.calls.append(("publish", topic))
        if self.answer:
            reply = json.dumps({"id": json.loads(payload)["id"], "ok": True, "detail": "stopped"})
            rig = topic.rpartition("/")[0]
            asyncio.get_running_loop().call_soon(self.session._on_message, f"{rig}/reply", reply.encode())
        return 0


async def _session_on_b(answer: bool = True) -> tuple[Session, Broker]:
    settings = DashboardSettings(host="localhost", port=1883, topics=A, reply_timeout=0.5)
    session = Session(settings, "operator", "secret")
    session._client = client = Broker(session, answer)
    session.rigs.on_status("rig-a", {"state": "idle"})
    session.rigs.on_status("rig-b", {"state": "idle"})
    assert (await session.select_rig("rig-b"))["ok"]
    client.calls.clear()
    return session, client


async def test_the_reply_of_another_rig_is_read_from_before_the_abort_until_it_came():
    session, client = await _session_on_b()
    outcome = await session.command({"cmd": "abort", "rig": A.prefix})
    assert outcome["ok"] and outcome["rig"] == A.prefix and outcome["detail"] == "stopped", outcome
    assert client.calls == [("subscribe_nowait", A.reply), ("publish", A.abort), ("unsubscribe_nowait", A.reply)]
    assert session.outcomes[-1]["rig"] == A.prefix


async def test_a_reply_topic_the_session_reads_for_its_own_rig_stays():
    session, client = await _session_on_b(answer=False)
    outcome = await session.command({"cmd": "stop", "rig": A.prefix})  # no reply in time: awaited late
    assert "the outcome is unknown" in outcome["error"] and outcome["rig"] == A.prefix, outcome
    assert (await session.select_rig("rig-a"))["ok"]  # the session watches rig-a again
    session._on_message(A.reply, json.dumps({"id": next(iter(session._late)), "ok": True}).encode())
    assert session.outcomes[-1]["late"] and session.outcomes[-1]["rig"] == A.prefix
    assert ("unsubscribe_nowait", A.reply) not in client.calls  # rig-a's own subscription is not dropped


async def test_a_late_reply_awaited_on_another_rig_is_read_on_after_the_session_went_there_and_left():
    session, client = await _session_on_b(answer=False)
    await session.command({"cmd": "abort", "rig": A.prefix})
    assert (await session.select_rig("rig-a"))["ok"]
    assert (await session.select_rig("rig-b"))["ok"]  # leaving rig-a unsubscribes its topics but the reply
    left = [t for t, _ in subscriptions(A) if t != A.reply]
    assert ("unsubscribe", left) in client.calls  # the awaited reply is read on, with no gap
    session._on_message(A.reply, json.dumps({"id": next(iter(session._late)), "ok": True}).encode())
    assert session.outcomes[-1]["late"] and session.outcomes[-1]["rig"] == A.prefix
    assert client.calls[-1] == ("unsubscribe_nowait", A.reply)  # then no longer


async def test_a_start_of_a_page_of_another_rig_is_refused_and_goes_nowhere():
    session, client = await _session_on_b()
    outcome = await session.command({"cmd": "start", "matrix": "demo", "rig": A.prefix})
    assert outcome == {
        "ok": False,
        "error": f"not sent: this page shows rig {A.prefix} but the session now watches {B.prefix}: reload the page",
    }
    assert client.calls == []


async def test_the_reply_awaited_on_the_watched_rig_is_read_on_after_the_session_leaves_it():
    """An abort to the rig watched (rig-b) whose reply is late; another tab chooses rig-a: rig-b's
    reply topic is kept (not unsubscribed with the rest of rig-b's), the late reply still becomes
    its outcome, and only then is the topic read no more. It read "unknown" for good before."""
    session, client = await _session_on_b(answer=False)
    outcome = await session.command({"cmd": "abort", "rig": B.prefix})
    assert "the outcome is unknown" in outcome["error"] and "rig" not in outcome, outcome
    assert (await session.select_rig("rig-a"))["ok"]
    (left,) = [topics for call, topics in client.calls if call == "unsubscribe"]
    assert B.reply not in left and B.status in left  # the rest of rig-b goes
    session._on_message(B.reply, json.dumps({"id": next(iter(session._late)), "ok": True}).encode())
    assert session.outcomes[-1]["late"] and session.outcomes[-1]["ok"], session.outcomes[-1]
    assert client.calls[-1] == ("unsubscribe_nowait", B.reply)  # then no longer
