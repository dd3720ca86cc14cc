"""An abort whose executor raises on a bug (RunEngine.request_abort: a fault no real part can
produce, injected) still reaches the drives: the service cancels the run, whose closing stop is
then the emergency stop, and sends both drives the emergency stop (OFF3) over a link of its own at
once; the reply says so (the run that held them cancelled, its abort's failure named: not "no run
held them"), the run ends cancelled with both drives confirmed at standstill, its end message naming
the failure (type and text), and the service serves on.

Real parts: mosquitto with the shipped ACL, the service `orbitrig serve --sim` builds (in process,
on the simulator), the abort published on the abort topic as the dashboard sends it."""

import time

import pytest

from drives import registers as R
from orbitrig.run.requests import OperatorRequests
from support.polling import until
from support.mqtt_helpers import wait
from test_mqtt_abort_always_sent import publish_abort, serving

pytestmark = pytest.mark.timeout(180)

#: wall s from the abort's message to each drive's emergency stop word (9 ms measured), for a loaded machine
WORD_WITHIN_S = 1.0
BUG = "'NoneType' object has no attribute 'abort_by'"
#: the failure as the reply and the run's end message name it: its type and text
FAILED = f"AttributeError: {BUG}"


async def test_an_abort_whose_executor_raises_still_stops_both_drives(broker, tmp_path, monkeypatch):
    def buggy(self, by=None, why=""):
        raise AttributeError(BUG)

    async with serving(broker, tmp_path, "buggy-abort-rig", speedup=4) as (svc, sim_rig, rc):
        assert (await wait(rc.command, {"cmd": "start", "matrix": "long"}))["ok"] is True
        await wait(rc.status, "running")
        await until(lambda: min(abs(w) for w in sim_rig.speeds) > 1.0, 60, "both drives turning")
        monkeypatch.setattr(OperatorRequests, "request_abort", buggy)
        t_abort = time.monotonic()
        mark = await wait(publish_abort, rc, "a1")
        reply = await wait(rc.reply, "a1", 30, mark)
        assert reply["ok"] is True and "emergency stop (OFF3) sent to both drives" in reply["detail"], reply
        # a run held them: cancelled for its abort that failed (it said "no run held them")
        held = f"(the run holding them cancelled, its stop or abort failed ({FAILED}))"
        assert reply["detail"].endswith(held) and "no run held" not in reply["detail"], reply
        for device, drive in sim_rig.drives.items():
            first = min(
                (t for t, cw in drive.control_words if t >= t_abort and cw == R.CW_EMERGENCY_STOP), default=None
            )
            assert first is not None and first - t_abort < WORD_WITHIN_S, (device, drive.control_words[-4:])
        ended = await wait(rc.status, "idle", 60, mark)
        assert "cancelled" in ended["message"] and "standstill confirmed" in ended["message"], ended
        assert f"cancelled (its stop or abort failed ({FAILED})); its drives' closing stop" in ended["message"], ended
        await until(lambda: all(abs(w) < 1e-3 for w in sim_rig.speeds), 30, "both drives at rest")
        assert (await wait(rc.command, {"cmd": "status"}))["ok"] is True  # the service serves on
