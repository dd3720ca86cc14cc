"""A dashboard session never ends up subscribed to nothing while its link is up.

An UNSUBSCRIBE or SUBSCRIBE whose acknowledgement comes late (a broker busy with a flood) makes
aiomqtt raise although the broker carries it out. A session that unsubscribed first and gave up
on the subscribe after such a timeout would sit on a live link reading nothing of its rig. So:

- reading the retained status again is a SUBSCRIBE alone (it replaces the subscription and the
  broker sends the retained status again), never an UNSUBSCRIBE first;
- watching another rig subscribes to the new rig before it unsubscribes from the old one; an
  unsubscribe that times out leaves the new rig watched.

The broker's timeout is the fault a real mosquitto does not produce on demand: the client here
is a stand-in recording what the session asks of it. The re-read against a real mosquitto is
tests/dashboard/test_dashboard_command_safety.py::test_an_unknown_outcome_reads_the_status_again.
"""

from __future__ import annotations

import math

import aiomqtt

from orbitrig.dashboard.catchup import subscriptions
from orbitrig.dashboard.session import DashboardSettings, Session
from orbitrig.service import protocol as proto


class SlowBroker:
    """A connected client whose unsubscribe acknowledgements time out (what a flooded broker does)."""

    timeout = 10.0  # s (aiomqtt's client: the bound broker_calls puts on each wait)

    def __init__(self) -> None:
        self.calls: list[tuple[str, object]] = []

    async def subscribe(self, topic, qos: int = 0, properties=None, *, timeout: float):
        assert timeout == math.inf  # aiomqtt waits unbounded: broker_calls bounds the wait
        self.calls.append(("subscribe", topic))

    async def unsubscribe(self, topic, *, timeout: float):
        assert timeout == math.inf
        self.calls.append(("unsubscribe", topic))
        raise aiomqtt.MqttError("Operation timed out")


def _session() -> tuple[Session, SlowBroker]:
    settings = DashboardSettings(host="localhost", port=1883, topics=proto.topics("rig-a"))
    session, client = Session(settings, "operator", "secret"), SlowBroker()
    session._client = client
    return session, client


async def test_reading_the_status_again_subscribes_without_unsubscribing_first():
    session, client = _session()
    await session._reread_status(client, session.topics)
    assert client.calls == [("subscribe", session.topics.status)]


async def test_another_rig_is_watched_although_the_old_rigs_unsubscribe_times_out():
    session, client = _session()
    old = session.topics
    reply = await session.select_rig("rig-b")
    new = proto.topics("rig-b")
    assert reply == {"ok": True, "prefix": new.prefix}
    assert client.calls[0] == ("subscribe", subscriptions(new))  # the new rig first
    assert ("unsubscribe", [t for t, _ in subscriptions(old)]) in client.calls[1:]
    assert session._subscribed == new  # a reconnection's catch-up counts the new rig as subscribed
