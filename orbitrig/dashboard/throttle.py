"""Sign-in throttling: per broker user name and per client address.

Every refused sign-in counts against both keys. After `n` failures of a user name the
next attempt is accepted only `delay * 2**(n-1)` s after the last one (a growing
delay); at `lock_after` failures the user name is locked out for `lockout` s. A client
address has `lock_after` free failures, then the same growing delay, and a lockout at
four times `lock_after`. While a key waits or is locked, an attempt is refused before
the password is tried (so the right password does not end a lockout early). A
successful sign-in clears its user name's count; counts are forgotten `lockout` s after
their last failure.
"""

from __future__ import annotations

import dataclasses
import math
import time

from orbitrig.dashboard.defaults import LOCK_AFTER, LOCKOUT_S, SIGNIN_DELAY_S

ADDRESS_FACTOR = 4  # an address locks out after this many times a user name's failures
MAX_KEYS = 10_000  # counts kept before the expired ones are dropped


@dataclasses.dataclass(frozen=True)
class ThrottlePolicy:
    """First delay (s), failures that lock a user name out, and the lockout (s)."""

    delay: float = SIGNIN_DELAY_S
    lock_after: int = LOCK_AFTER
    lockout: float = LOCKOUT_S


@dataclasses.dataclass
class _Count:
    failures: int = 0
    last: float = 0.0


class SignInThrottle:
    """The failures per ("user", name) and ("address", ip); `wait` says how long an attempt must wait."""

    def __init__(self, policy: ThrottlePolicy, clock=time.monotonic):
        self.policy, self.clock = policy, clock
        self.counts: dict[tuple[str, str], _Count] = {}

    def _limits(self, kind: str) -> tuple[int, int]:
        """(free failures, failures that lock out) of a key kind."""
        n = self.policy.lock_after
        return (0, n) if kind == "user" else (n, ADDRESS_FACTOR * n)

    def _wait_of(self, key: tuple[str, str], now: float) -> tuple[float, bool]:
        count = self.counts.get(key)
        if count is None:
            return 0.0, False
        if now - count.last > self.policy.lockout:
            del self.counts[key]
            return 0.0, False
        free, lock = self._limits(key[0])
        if count.failures >= lock:
            return count.last + self.policy.lockout - now, True
        if count.failures <= free:
            return 0.0, False
        delay = min(self.policy.delay * 2 ** (count.failures - free - 1), self.policy.lockout)
        return max(0.0, count.last + delay - now), False

    def refusal(self, user: str, address: str) -> str | None:
        """Why an attempt of `user` from `address` is refused now (None: try the password)."""
        now = self.clock()
        for key in (("user", user), ("address", address)):
            wait, locked = self._wait_of(key, now)
            if locked:
                return (
                    f"too many refused sign-ins for {'this user' if key[0] == 'user' else 'this address'}: "
                    f"locked for {math.ceil(wait)} s more (lockout {self.policy.lockout:g} s)"
                )
            if wait > 0:
                return f"too many refused sign-ins: try again in {wait:.1f} s"
        return None

    def failed(self, user: str, address: str) -> None:
        now = self.clock()
        if len(self.counts) > MAX_KEYS:  # a flood of made-up names: forget the expired counts
            self.counts = {k: c for k, c in self.counts.items() if now - c.last <= self.policy.lockout}
        for key in (("user", user), ("address", address)):
            count = self.counts.setdefault(key, _Count())
            count.failures += 1
            count.last = now

    def succeeded(self, user: str) -> None:
        self.counts.pop(("user", user), None)
