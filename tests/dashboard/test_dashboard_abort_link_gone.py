"""A stop or abort that the dashboard's client could not hand over (its broker link went away between the
session's last look and the publish: paho answers "not connected") says in capitals that it was not sent
and what to do, as when the session already knew the link was down. The client is a stand-in raising
what the real one (orbitrig.dashboard.puback.ReasonClient) raises then: no real broker makes that
moment on demand; the link known down, on a real mosquitto in a real browser, is
tests/dashboard/test_dashboard_command_safety.py."""

from __future__ import annotations

import aiomqtt
import paho.mqtt.client as paho
import pytest

from orbitrig.dashboard.commands import urgent_no_broker
from orbitrig.dashboard.session import DashboardSettings, Session
from orbitrig.service import protocol as proto

RIG = proto.topics("rig-a")


class LinkJustGone:
    """A client whose link dropped a moment ago: a publish cannot be handed over."""

    def subscribe_nowait(self, topic: str, qos: int) -> bool:
        return False

    async def publish_qos1(self, topic: str, payload: str, timeout: float, *, expiry=None) -> int:
        raise aiomqtt.MqttCodeError(paho.MQTT_ERR_NO_CONN, "could not publish")


@pytest.mark.parametrize("cmd", ["abort", "stop"])
async def test_a_stop_or_abort_not_handed_over_says_it_was_not_sent(cmd):
    session = Session(DashboardSettings(host="localhost", port=1883, topics=RIG, reply_timeout=0.5), "operator", "pw")
    session._client = LinkJustGone()
    outcome = await session.command({"cmd": cmd, "rig": RIG.prefix})
    assert outcome["ok"] is False
    assert outcome["error"].startswith(urgent_no_broker(cmd) + " ("), outcome
    assert (
        outcome["error"].startswith(f"{cmd.upper()} NOT SENT: ") and "use the rig's emergency stop" in outcome["error"]
    )


async def test_another_command_not_handed_over_says_not_sent():
    session = Session(DashboardSettings(host="localhost", port=1883, topics=RIG, reply_timeout=0.5), "operator", "pw")
    session._client = LinkJustGone()
    session.status = {"state": "running", "run_id": "r1"}
    outcome = await session.command({"cmd": "pause", "rig": RIG.prefix})
    assert outcome["ok"] is False and outcome["error"].startswith("not sent: "), outcome
