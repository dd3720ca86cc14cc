"""A subscription's acknowledgement that comes after aiomqtt gave up waiting for it (its timeout: a broker
busy with a flood) is no error: the session carried on already (orbitrig.dashboard.catchup subscribes to the
new rig before it unsubscribes from the old, the connection loop subscribes again). The dashboard's client
takes it itself and says it in its log, where aiomqtt logged an error with a traceback ("Unexpected message
ID"). A late acknowledgement is the fault a real mosquitto does not produce on demand: the test hands the
client's callbacks one for a message id nobody awaits. The acknowledgements of the subscriptions the client
asks without waiting, with a real mosquitto: tests/dashboard/test_dashboard_other_rig_abort.py."""

from __future__ import annotations

import logging

from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.reasoncodes import ReasonCode

from orbitrig.dashboard.puback import ReasonClient


async def test_an_acknowledgement_after_the_wait_was_given_up_is_no_error(caplog):
    client = ReasonClient("127.0.0.1", 1883)
    caplog.set_level(logging.INFO)
    client._on_subscribe(None, None, 41, [ReasonCode(PacketTypes.SUBACK, identifier=1)], None)
    client._on_unsubscribe(None, None, 42, [ReasonCode(PacketTypes.UNSUBACK, identifier=0)], None)
    assert [r.levelname for r in caplog.records] == ["INFO", "INFO"], caplog.text
    assert "a subscription was acknowledged after its wait was given up (message id 41)" in caplog.text
    assert "an unsubscription was acknowledged after its wait was given up (message id 42)" in caplog.text
