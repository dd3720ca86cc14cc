"""A further abort says truthfully whether the run still holds the drives. Once the run's cleanup
has closed the drives' link (also when it could not confirm them stopped), an abort must not be
reported as carried out by the run: the service then sends the emergency stop over a link of its
own. While the link is open, the further abort sends the emergency stop again.

The engine's request handling (orbitrig.run.requests) on the real drives client against the
simulator's drives behind a real Modbus server."""

from __future__ import annotations

from orbitrig.run.control import RunControl
from orbitrig.run.requests import OperatorRequests
from orbitrig.run.states import RUNNING
from support.drives_testkit import CW_EMERGENCY, RPM, SimDrives, make_models, open_rig, serve

from drives.limits import DriveLimits


class _IO:
    def __init__(self, drives):
        self.drives = drives


class _Run(OperatorRequests):
    """The engine's requests, with the run's rig links (`_io`) as given and nothing stored."""

    console_user, _store, _held, _body = "ada", None, None, None

    def __init__(self, io):
        self._control = RunControl(lambda state, message: None, lambda message: None)
        self._control.state = RUNNING
        self._io = io

    def _log_event(self, *args, **kw) -> None:
        pass


async def test_a_further_abort_after_the_cleanup_closed_the_drives_link_is_not_claimed_by_the_run():
    models = make_models()
    endpoint = await serve("tcp", models)
    sim = SimDrives("tcp", models, endpoint)
    try:
        rig = open_rig(sim, DriveLimits(max_spin=2400 * RPM, max_orbit=2400 * RPM))
        async with rig:
            await rig.set_speeds(600 * RPM, 300 * RPM)
            await rig.wait_settled(hold=0.1, timeout=20)
            run = _Run(_IO(rig))
            assert run.request_abort("ada") is True  # the first: the stop words go out now
            await sim.wait_for(lambda: sim.regs(1)["CW"] == CW_EMERGENCY, 5, "the emergency stop")
            models[1].write(0, [0x047F])  # the drive told to run again (as from its keypad) ...
            assert run.request_abort("bob") is True  # ... a further abort while the link is open: sent again
            await sim.wait_for(lambda: sim.regs(1)["CW"] == CW_EMERGENCY, 5, "the emergency stop again")
        # the cleanup closed the drives' link; the run's links object is still there
        assert run._io is not None and run.request_abort("bob") is False
    finally:
        await endpoint.aclose()
