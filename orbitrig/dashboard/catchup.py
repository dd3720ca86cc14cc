"""What a dashboard session reads of a rig, and how it catches up after its broker link dropped.

A session's MQTT session outlives a dropped link for ``catch_up_s`` s (MQTT 5 session expiry;
the same client id on every reconnection, a new one at each sign-in; never a clean start, which mosquitto 2.0 would
not save to its persistence): the broker queues for it what it subscribed
to at QoS 1 (statuses, results, the run's warnings, replies, acknowledgements; mosquitto keeps up to its
``max_queued_messages`` per client, 10000 in config/mosquitto/mosquitto.conf) and hands them
over when the link is back. Progress and live payloads (QoS 0) are stale by then: not kept.
Commands are not read at all, so no flood of them fills the queue.

When the broker had not kept the session (the link was down longer than ``catch_up_s``, or the
broker restarted without its persistence), the CONNACK says so (``session_present`` false) and
the pages get a ``gap`` message: results published between ``from`` and ``to`` may be missing.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from enum import IntEnum
from typing import Any

import orbitrig.service.protocol as proto
import orbitrig.service.broker_calls as broker_calls
from daq.backoff import Backoff
from orbitrig.dashboard.feed import FeedType

log = logging.getLogger(__name__)


class Via(IntEnum):
    """The MQTT 5 subscription identifier of each of a session's subscriptions. The status of the rig watched
    matches two, its own topic and the rigs' pattern (orbitrig.dashboard.rigs), and mosquitto hands it on once
    per subscription, each copy with its own identifier (a broker handing on one copy names both): the rig's
    copy is read as the rig's status, the rigs' copy only lists it (orbitrig.dashboard.incoming), so that a
    page gets each status once; but while the broker has not confirmed the subscription to a rig chosen, the rigs'
    copy is read as its status (keep_subscribing)."""

    WATCHED = 1  # the rig watched (subscriptions)
    RIGS = 2  # every rig's status (RigDirectory.pattern)


def tagged(via: Via) -> Any:
    """MQTT 5 SUBSCRIBE properties naming the subscription ``via``."""
    from paho.mqtt.packettypes import PacketTypes
    from paho.mqtt.properties import Properties

    props = Properties(PacketTypes.SUBSCRIBE)
    props.SubscriptionIdentifier = int(via)
    return props


def via_of(properties: Any) -> frozenset[int]:
    """The subscription identifiers a message came with (a PUBLISH's properties; empty: none)."""
    ids = getattr(properties, "SubscriptionIdentifier", None) if properties is not None else None
    return frozenset(ids if isinstance(ids, list) else [ids] if isinstance(ids, int) else [])


def subscriptions(topics: proto.Topics) -> list[tuple[str, int]]:
    """The topics a session reads of a rig with their QoS: 1 for what the broker keeps for the session
    while its link is down, 0 for what is stale by then."""
    t = topics
    return [(t.status, 1), (t.result, 1), (t.note, 1), (t.reply, 1), (t.ack, 1), (t.progress, 0), (t.live, 0)]


def topic_names(topics: proto.Topics) -> list[str]:
    """The topics of :func:`subscriptions` alone (to unsubscribe)."""
    return [topic for topic, _ in subscriptions(topics)]


async def move_subscriptions(
    client: Any, old: proto.Topics, new: proto.Topics, user: str, keep: frozenset[str] = frozenset()
) -> bool:
    """Subscribe ``client`` to rig ``new`` (its retained status comes), then unsubscribe from ``old``
    but ``keep`` (a reply topic whose stop's or abort's reply is awaited); True when the new
    subscriptions were confirmed. In this order a late acknowledgement of either (the wait raises
    aiomqtt.MqttError although the broker carries it out) never leaves the session reading nothing;
    the old rig's messages that still come are ignored (the session reads the rig it watches)."""
    subscribed = True
    try:
        await broker_calls.subscribe(client, subscriptions(new), properties=tagged(Via.WATCHED))
    except Exception as err:  # noqa: BLE001 - aiomqtt errors: the connection loop subscribes again
        log.info("session of %r: subscription to %s deferred: %s", user, new.prefix, err)
        subscribed = False
    try:
        await broker_calls.unsubscribe(client, [topic for topic in topic_names(old) if topic not in keep])
    except Exception as err:  # noqa: BLE001 - as above; the broker's session may keep old until it ends
        log.info("session of %r: unsubscribe from %s not confirmed: %s", user, old.prefix, err)
    return subscribed


#: s before the first and at most between two attempts to subscribe to a rig chosen whose subscription the broker
#: did not confirm (jittered, doubling: orbitrig.dashboard.session.Session keeps trying)
RESUBSCRIBE_S = (0.5, 5.0)


async def keep_subscribing(
    client: Any, topics: proto.Topics, user: str, given_up: Callable[[], bool], attempt: Callable[[], None]
) -> bool:
    """Subscribe ``client`` to rig ``topics`` again and again, a growing delay apart (RESUBSCRIBE_S), until the
    broker confirms it (True) or ``given_up()`` (False: another rig chosen, the session closed, the link gone: a
    reconnection subscribes anew). ``attempt()`` is called just before each SUBSCRIBE goes."""
    backoff = Backoff(*RESUBSCRIBE_S)
    while True:
        await asyncio.sleep(backoff.next_delay())
        if given_up():
            return False
        attempt()
        try:
            await broker_calls.subscribe(client, subscriptions(topics), properties=tagged(Via.WATCHED))
        except Exception as err:  # noqa: BLE001 - aiomqtt errors: tried again, or given up above
            log.info("session of %r: subscription to %s not confirmed again: %s", user, topics.prefix, err)
            continue
        log.info("session of %r: subscribed to %s after %d attempts", user, topics.prefix, backoff.attempts)
        return True


def connect_properties(catch_up_s: int) -> Any:
    """MQTT 5 CONNECT properties: the broker keeps the session ``catch_up_s`` s after the link drops."""
    from paho.mqtt.packettypes import PacketTypes
    from paho.mqtt.properties import Properties

    props = Properties(PacketTypes.CONNECT)
    props.SessionExpiryInterval = int(catch_up_s)
    return props


def gap_message(down_since: str, caught_up: bool) -> dict:
    """The feed message of a broker link back after a drop since ``down_since`` (ISO-8601): whether the
    messages published meanwhile came (``caught_up``) or results may be missing between the times."""
    return {"type": FeedType.GAP, "data": {"from": down_since, "to": proto.iso8601(), "caught_up": caught_up}}
