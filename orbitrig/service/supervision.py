"""The broker link as the run's supervision (docs/protocols/mqtt.md, "Loss of supervision").

Once the broker has been away longer than ``supervision_timeout`` nobody can answer
the run: the service marks its engine unattended (``RunEngine.unattended``), so a pause
or a confirmation, one under way included, stops the run after ``[interlocks]
unanswered_pause_s``, as `orbitrig sweep` does without a terminal; and it applies the
supervision policy once (``keep``, ``pause``, ``stop``). The mark is cleared when the
broker is back.
"""

from __future__ import annotations

import logging

from drives.waits import first_set
from orbitrig.run.states import RunState
from orbitrig.service.commands import CommandHandling, Request
from orbitrig.service.engine_port import Engine
from orbitrig.service.settings import ServiceSettings, SupervisionPolicy

log = logging.getLogger("orbitrig.service.rig_service")

LOST = "service (supervision lost)"
#: who asks the policy's pause (the commands log's sender)
PAUSED_BY = "service (supervision lost: no broker for {timeout:g} s, policy pause)"


class SupervisionHandling(CommandHandling):
    """The supervision side of :class:`orbitrig.service.rig_service.RigService`."""

    settings: ServiceSettings

    async def _supervision_loop(self) -> None:
        """Per outage longer than ``supervision_timeout``: the run unattended and the
        policy applied once; attended again when the broker is back."""
        while True:
            await self.link.offline.wait()
            if await first_set(self.link.online, timeout=self.settings.supervision_timeout) is not None:
                continue
            engine = self._engine if self.run_active else None
            if engine is None:
                await self.link.online.wait()
                continue
            try:
                await self._unsupervised(engine)
            finally:
                engine.unattended = False  # the broker is back (or the service ends)
            log.info("broker back: the run is supervised again")

    async def _unsupervised(self, engine: Engine) -> None:
        """From the loss of supervision until the broker is back."""
        s = self.settings
        log.warning(
            "no broker for %.0f s: supervision lost, policy %r; a pause or confirmation nobody "
            "can answer stops the run after %g s",
            s.supervision_timeout,
            s.supervision_policy,
            engine.rig.interlocks.unanswered_pause_s,
        )
        engine.unattended = True  # before the pause below; a wait under way counts its limit from now
        if s.supervision_policy is SupervisionPolicy.PAUSE and engine.state in (RunState.RUNNING, RunState.WAITING):
            self._request(Request.PAUSE, PAUSED_BY.format(timeout=s.supervision_timeout))
        elif s.supervision_policy is SupervisionPolicy.STOP:
            self._request(Request.STOP, LOST)
        await self.link.online.wait()
