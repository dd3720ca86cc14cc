"""Turns on one shared Modbus link: one request at a time, a stop before anything else waiting.

The poll, the run and a stop share one link, and a request holds it until its
answer (at most the request timeout). An abort must not wait behind the poll's
reads or the run's writes that queued up before it: `Turns` is an asyncio lock
whose urgent waiters (the stop words, `drives.stop.send_stop`) are served
before the others, each kind in its order of arrival; a stop reserves the link
for its words, so no poll slips in between the two drives' stop words.

    async with turns.turn(urgent=True):
        ...  # one exchange on the link
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
from collections.abc import AsyncIterator, Iterator


class Turns:
    """An asyncio lock with two queues of waiters: urgent ones first. While `reserved()`,
    only urgent requests get the link (a stop's words back to back, no poll between)."""

    def __init__(self) -> None:
        self._held = False
        self._reserved = 0
        self._waiting: dict[bool, collections.deque[asyncio.Future[None]]] = {
            True: collections.deque(),
            False: collections.deque(),
        }

    def locked(self) -> bool:
        return self._held

    def waiting(self, urgent: bool) -> int:
        """Requests of that kind waiting for their turn."""
        return len(self._waiting[urgent])

    async def acquire(self, urgent: bool = False) -> None:
        if not self._held and not self._waiting[True] and (urgent or not (self._reserved or self._waiting[False])):
            self._held = True
            return
        turn = asyncio.get_running_loop().create_future()
        queue = self._waiting[urgent]
        queue.append(turn)
        try:
            await turn
        except asyncio.CancelledError:
            if turn.done() and not turn.cancelled():
                self.release()  # handed over just as the waiter was cancelled: pass it on
            elif turn in queue:
                queue.remove(turn)
            raise

    def release(self) -> None:
        """Hand the link to the next waiter (urgent ones first), or free it."""
        self._held = False
        self._hand_over()

    @contextlib.contextmanager
    def reserved(self) -> Iterator[None]:
        """While open, the link goes to urgent requests only."""
        self._reserved += 1
        try:
            yield
        finally:
            self._reserved -= 1
            if not self._held:
                self._hand_over()

    def _hand_over(self) -> None:
        for urgent in (True,) if self._reserved else (True, False):
            queue = self._waiting[urgent]
            while queue:
                turn = queue.popleft()
                if not turn.done():
                    self._held = True
                    turn.set_result(None)  # held on by the next waiter
                    return

    @contextlib.asynccontextmanager
    async def turn(self, urgent: bool = False) -> AsyncIterator[None]:
        await self.acquire(urgent)
        try:
            yield
        finally:
            self.release()

    async def __aenter__(self) -> None:
        await self.acquire()

    async def __aexit__(self, *exc: object) -> None:
        self.release()
