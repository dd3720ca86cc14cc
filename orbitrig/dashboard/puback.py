"""The dashboard's MQTT 5 client: a QoS 1 publish that tells the broker's answer (the PUBACK's
reason code), so that a publish the broker's ACL refuses is known as refused.

Under MQTT 3.1.1 a broker acknowledges a refused publish like any other and drops it: the
sender cannot tell a refusal from a service that did not answer. Under MQTT 5 mosquitto
answers a refused publish with reason code 135 (not authorised). aiomqtt waits for the PUBACK
but drops its reason code; :class:`ReasonClient` keeps it (``publish_qos1``).

It also tells whether the broker kept the client's session (``session_present`` of the
CONNACK: the messages queued for it while it was away come next) and can end that session
with its connection (``end_session``).

A subscription asked without waiting (``subscribe_nowait``, ``unsubscribe_nowait``) goes past
aiomqtt, which knows only the message ids it awaits itself and logs any other acknowledgement as an
error with a traceback ("Unexpected message ID"): the client keeps the ids it asked for so and takes
their acknowledgements itself, as it does one whose wait was given up (the client's timeout,
orbitrig.service.broker_calls: a busy broker's late SUBACK or UNSUBACK), which the session has dealt
with already (orbitrig.dashboard.catchup).
"""

from __future__ import annotations

import asyncio
import logging
from typing import Any

import aiomqtt
import paho.mqtt.client as paho
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties

log = logging.getLogger("orbitrig.dashboard")


class PublishUnconfirmed(Exception):
    """No PUBACK came within the time given: the broker may or may not have the message."""


class ReasonClient(aiomqtt.Client):
    """aiomqtt's client (give it ``protocol=aiomqtt.ProtocolVersion.V5``) with :meth:`publish_qos1`."""

    def __init__(self, *args: Any, **kwargs: Any):
        super().__init__(*args, **kwargs)
        self._acks: dict[int, asyncio.Future] = {}
        self.session_present = False  # the broker's CONNACK: it had kept this client id's session
        self._unawaited: dict[int, str] = {}  # message id -> topic of a (un)subscribe nobody awaits

    def _on_connect(self, client: Any, userdata: Any, flags: Any, reason_code: Any, properties: Any = None) -> None:
        self.session_present = bool(getattr(flags, "session_present", False))
        super()._on_connect(client, userdata, flags, reason_code, properties)

    def end_session(self) -> None:
        """Disconnect, telling the broker to forget the session now (MQTT 5: session expiry 0 in the
        DISCONNECT): nothing is queued for it any more."""
        props = Properties(PacketTypes.DISCONNECT)
        props.SessionExpiryInterval = 0
        self._client.disconnect(properties=props)

    def subscribe_nowait(self, topic: str, qos: int) -> bool:
        """Ask the broker for a subscription without waiting for its SUBACK (False: it could not be asked).
        The broker reads a connection's packets in order: a publish sent next comes after it."""
        rc, mid = self._client.subscribe(topic, qos)
        if rc == paho.MQTT_ERR_SUCCESS and mid is not None:
            self._unawaited[mid] = topic  # the SUBACK is read on this event loop, after subscribe() returned
        return rc == paho.MQTT_ERR_SUCCESS

    def unsubscribe_nowait(self, topic: str) -> None:
        """End a subscription without waiting for the broker's UNSUBACK."""
        rc, mid = self._client.unsubscribe(topic)
        if rc == paho.MQTT_ERR_SUCCESS and mid is not None:
            self._unawaited[mid] = topic

    def _on_subscribe(self, client: Any, userdata: Any, mid: int, reason_codes: Any, properties: Any = None) -> None:
        topic = self._unawaited.pop(mid, None)
        if topic is None and mid not in self._pending_subscribes:  # its wait was given up (a busy broker)
            log.info("a subscription was acknowledged after its wait was given up (message id %d)", mid)
        elif topic is None:  # one aiomqtt awaits
            super()._on_subscribe(client, userdata, mid, reason_codes, properties)
        elif any(int(getattr(code, "value", code)) >= 0x80 for code in reason_codes):
            log.info("subscription to %s refused by the broker: %s", topic, [str(code) for code in reason_codes])

    def _on_unsubscribe(self, client: Any, userdata: Any, mid: int, reason_codes: Any, properties: Any = None) -> None:
        if self._unawaited.pop(mid, None) is not None:
            return
        if mid not in self._pending_unsubscribes:  # its wait was given up
            log.info("an unsubscription was acknowledged after its wait was given up (message id %d)", mid)
        else:
            super()._on_unsubscribe(client, userdata, mid, reason_codes, properties)

    def _on_publish(self, client: Any, userdata: Any, mid: int, reason_code: Any, properties: Any) -> None:
        fut = self._acks.pop(mid, None)  # called on the event loop (aiomqtt reads the socket there)
        if fut is not None and not fut.done():
            fut.set_result(int(getattr(reason_code, "value", reason_code or 0)))
        super()._on_publish(client, userdata, mid, reason_code, properties)

    async def publish_qos1(self, topic: str, payload: str, timeout: float, *, expiry: int | None = None) -> int:
        """Publish at QoS 1 and wait for the broker's PUBACK: its reason code (0 accepted, 16 accepted
        but nobody subscribes, 135 refused by the ACL). ``expiry`` (s, MQTT 5 message expiry interval):
        the broker drops the message instead of handing it on later (None: it never expires). Raises ``aiomqtt.MqttError`` when the message
        could not be handed over (no connection), :class:`PublishUnconfirmed` when no PUBACK came
        within ``timeout`` s (the message may have reached the broker)."""
        fut: asyncio.Future = asyncio.get_running_loop().create_future()
        props = None
        if expiry is not None:
            props = Properties(PacketTypes.PUBLISH)
            props.MessageExpiryInterval = max(1, int(expiry))
        info = self._client.publish(topic, payload, 1, properties=props)  # aiomqtt's paho client: no public handle
        if info.rc != paho.MQTT_ERR_SUCCESS:
            raise aiomqtt.MqttCodeError(info.rc, "could not publish")
        # the PUBACK is read on this event loop, after publish() returned: it cannot be missed here
        self._acks[info.mid] = fut
        try:
            async with asyncio.timeout(timeout):  # (3.11's wait_for can lose a cancellation)
                return await fut
        except (TimeoutError, asyncio.TimeoutError):
            raise PublishUnconfirmed(f"no acknowledgement from the broker within {timeout:g} s") from None
        finally:
            self._acks.pop(info.mid, None)
