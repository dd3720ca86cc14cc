"""How the rig service reads its broker connection, so that a flood of commands
costs it little and holds back neither a stop nor the drives' poll.

aiomqtt runs paho's ``loop_read`` from the event loop each time the socket is
readable; paho then reads one packet and decodes it whole (properties, a message
object, the subscription match) before the service sees it. Three adjustments of
that paho client (aiomqtt gives no public handle on it):

- :func:`read_in_bursts`: one turn of the loop reads up to ``burst`` packets
  while the socket has more (one per turn would let a flood pile up in the
  socket, an abort behind it), but at most ``budget_s`` s of reading, and it ends
  right after a message carried out at once (a stop or an abort), so the drives'
  stop goes out before anything more is read;
- :func:`hold_reading`: the socket left unread for a moment (after a stop or an
  abort while the abort connection is up to take the next one, and after an abort
  in any case: nothing the connection brings outranks it), until the drives' stop
  words are out (at most STOP_HOLD_MAX_S), so that they get the processor rather
  than the flood, however busy the host;
- :func:`shed_before_decoding`: a PUBLISH on the command topic is first offered,
  as raw bytes, to ``shed(payload, retained)``; a command the service has no room
  for is answered busy or dropped there (and acknowledged to the broker) without
  paho decoding it (no properties, message object or subscription match for
  a command that is not going to be carried out).
"""

from __future__ import annotations

import asyncio
import select
import time
from collections.abc import Callable
from typing import Any

#: packets read off the socket in one turn of the event loop, at most
READ_BURST = 64
#: s of reading in one turn of the event loop, at most (then the loop's other work goes on)
READ_BUDGET_S = 0.005
#: s the main connection is left unread after a stop or an abort whose stop words the
#: service cannot follow (a ramp stop at the next safe point, no run holding the drives)
STOP_HOLD_S = 0.15
#: s at most the main connection is left unread until an abort's stop words are out (with
#: both cores busy at load 15 they took up to 1.5 s while the flood was read meanwhile)
STOP_HOLD_MAX_S = 2.0


def read_in_bursts(
    paho_client: Any,
    burst: int = READ_BURST,
    *,
    taken_at_once: Callable[[], int] = lambda: 0,
    budget_s: float = READ_BUDGET_S,
) -> None:
    """Make ``paho_client.loop_read`` read up to ``burst`` packets while the socket has
    more, for at most ``budget_s`` s, and stop right after a message carried out at once
    (``taken_at_once()``, a count, changed)."""
    from paho.mqtt.client import MQTTErrorCode

    one = paho_client.loop_read

    def loop_read(max_packets: int = 1) -> Any:
        t0, urgent = time.monotonic(), taken_at_once()
        rc = one()
        for _ in range(burst - 1):
            if taken_at_once() != urgent or time.monotonic() - t0 > budget_s:
                break
            sock = paho_client.socket()
            if rc != MQTTErrorCode.MQTT_ERR_SUCCESS or sock is None or not select.select([sock], [], [], 0)[0]:
                break
            rc = one()
        return rc

    paho_client.loop_read = loop_read


class _Held:
    """A socket left unread: its reader (aiomqtt's callback) and the holds not ended yet."""

    def __init__(self, sock: Any, callback: Callable[..., Any], args: tuple[Any, ...]) -> None:
        self.sock, self.callback, self.args = sock, callback, args
        self.holds = 0


#: the sockets left unread, by event loop and file descriptor
_HELD: dict[tuple[asyncio.AbstractEventLoop, int], _Held] = {}


def hold_reading(paho_client: Any, seconds: float, until: asyncio.Future[Any] | None = None) -> bool:
    """Leave ``paho_client``'s socket unread for ``seconds`` s, or until ``until`` is done if that
    is sooner: the event loop stops watching it and watches it again afterwards with the same
    callback (aiomqtt's reader), unless the socket was closed meanwhile. A hold asked while
    another is under way (an abort on the abort connection within a stop's hold) adds to it:
    the socket is read again once every hold has ended. False if there was nothing to hold
    (no socket, not watched, or a loop without a selector to ask for the callback)."""
    sock = paho_client.socket()
    loop = asyncio.get_running_loop()
    selector = getattr(loop, "_selector", None)
    if sock is None or selector is None:
        return False
    fd = sock.fileno()
    key = (loop, fd)
    held = _HELD.get(key)
    if held is None or held.sock is not sock:
        try:
            reader = selector.get_key(fd).data[0]
        except (KeyError, ValueError):
            return False
        if reader is None:
            return False
        callback, args = reader._callback, reader._args  # (remove_reader clears them)
        if not loop.remove_reader(fd):
            return False
        held = _HELD[key] = _Held(sock, callback, tuple(args or ()))
    held.holds += 1
    ended = [False]

    def read_again(*_: Any) -> None:
        if ended[0]:  # (the other of the timer and `until` came first)
            return
        ended[0] = True
        timer.cancel()
        held.holds -= 1
        if held.holds > 0:
            return
        if _HELD.get(key) is held:
            del _HELD[key]
        if paho_client.socket() is sock and sock.fileno() == fd:
            loop.add_reader(fd, held.callback, *held.args)

    timer = loop.call_later(seconds, read_again)
    if until is not None:
        until.add_done_callback(read_again)
    return True


def shed_before_decoding(paho_client: Any, topic: str, shed: Callable[[bytes, bool], bool]) -> None:
    """Offer every QoS 0 or 1 PUBLISH on ``topic`` (MQTT 5) to ``shed(payload, retained)``
    before paho decodes it; True: dealt with (paho only acknowledges a QoS 1 one)."""
    from paho.mqtt.client import MQTTv5, MQTTErrorCode

    decode = paho_client._handle_publish
    wanted = topic.encode()

    def handle_publish() -> Any:
        fixed, raw = paho_client._in_packet["command"], paho_client._in_packet["packet"]
        qos = (fixed & 0x06) >> 1
        if qos > 1 or paho_client._protocol != MQTTv5:
            return decode()
        end = 2 + int.from_bytes(raw[:2], "big")
        if raw[2:end] != wanted:
            return decode()
        mid = int.from_bytes(raw[end : end + 2], "big") if qos else 0
        start = _after_properties(raw, end + (2 if qos else 0))
        if start is None or not shed(bytes(raw[start:]), bool(fixed & 0x01)):
            return decode()
        return paho_client._send_puback(mid) if qos else MQTTErrorCode.MQTT_ERR_SUCCESS

    paho_client._handle_publish = handle_publish


def _after_properties(raw: bytes, at: int) -> int | None:
    """Where the payload starts: after the properties' length (a variable byte integer,
    at most 4 bytes) and the properties; None if the packet is too short (paho decides)."""
    length, shift = 0, 0
    for i in range(at, min(at + 4, len(raw))):
        length |= (raw[i] & 0x7F) << shift
        shift += 7
        if not raw[i] & 0x80:
            start = i + 1 + length
            return start if start <= len(raw) else None
    return None
