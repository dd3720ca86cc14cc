"""An abort while the service's ramp stop with no run is under way: no ramp stop word follows the
abort's emergency stop.

A `stop` that no run carries out sends both drives the ramp stop (OFF1) over a link of the
service's own; an `abort` arriving meanwhile sends the emergency stop (OFF3) beside it, over a link
of its own. The ramp stop went on with its words regardless: an OFF1 still to go out reached the
drives after the abort's OFF3 and turned their emergency ramp back into their ten times slower
ramp stop, both replies ok (the abort's saying the emergency stop was sent). Now the abort makes
the ramp stop under way the emergency stop too: its words still to go out are OFF3, a drive that
took its OFF1 gets OFF3 next, and its reply says so; until it has ended (a drive's timed-out word
outlasts the abort's own stop), nothing that moves the drives is accepted (`start` refused).

Real parts: mosquitto with the shipped ACL and accounts, the service `orbitrig serve --sim` builds
(in process, on the simulator over Modbus TCP), the drives turned from their keypads with no run,
the simulator's own fault injection (its next request unanswered: the spin drive's ramp stop word
times out once, so the abort comes while that stop is under way). The one timed part: the fault is
armed once the ramp stop has read both drives (a moment a real part cannot be made to hit)."""

from __future__ import annotations

import time

from drives import registers as R
from orbitrig.config import load_rig
from orbitrig.service import idle_stop
from support.mqtt_helpers import wait
from support.polling import until
from test_mqtt_abort_always_sent import publish_abort, serving


async def test_an_abort_during_an_idle_ramp_stop_leaves_no_ramp_stop_word_after_it(broker, tmp_path, monkeypatch):
    rig = load_rig()
    rig = rig.model_copy(update={"drives": rig.drives.model_copy(update={"timeout_s": 3.0})})
    async with serving(broker, tmp_path, "ramp-then-abort-rig", rig=rig, speedup=2, decel=18000) as (
        svc,
        sim_rig,
        rc,
    ):
        for drive in sim_rig.drives.values():
            drive.write(R.COMM_LOSS_TIMEOUT, [0])  # nothing stops them but the service's words
        sim_rig.local_control(spin=100.0, orbit=-50.0, hand_back=True)  # someone at the drives, no run
        await until(lambda: min(abs(w) for w in sim_rig.speeds) > 10.0, 30, "both drives turning")
        real_read_first = idle_stop.read_first
        armed = []

        async def read_first(pair):
            found = await real_read_first(pair)
            sim_rig.modbus_servers[0].drop_next(1)  # the ramp stop's first word (the spin drive's) times out
            armed.append(found)
            return found

        monkeypatch.setattr(idle_stop, "read_first", read_first)
        t_stop = time.monotonic()
        mark = rc.watch.mark()
        await wait(rc.send, {"cmd": "stop", "id": "idle-stop"})
        await until(lambda: armed, 15, "the ramp stop's reads done")
        assert not armed[0].emergency and svc._idle_stop is not None and not svc._idle_stop.done()
        await wait(publish_abort, rc, "idle-abort")
        abort = await wait(rc.reply, "idle-abort", 30, mark)
        assert abort["ok"] is True and "emergency stop (OFF3) sent to both drives" in abort["detail"], abort
        assert svc._idle_stop.done()  # the abort's own stop is over, the ramp stop's tries go on
        start = await wait(rc.command, {"cmd": "start", "matrix": "quick", "id": "too-soon"})
        assert start["ok"] is False and "emergency stop is being sent to the drives" in start["error"], start
        stop = await wait(rc.reply, "idle-stop", 30, mark)
        for device, drive in sim_rig.drives.items():
            words = [cw for t, cw in drive.control_words if t >= t_stop]
            after = words[words.index(R.CW_EMERGENCY_STOP) :]
            assert R.CW_RAMP_STOP not in after, (device, [hex(w) for w in words])
            assert drive.read(R.CW, 1) == [R.CW_EMERGENCY_STOP], device
        assert stop["ok"] is True and "emergency stop (OFF3), by an abort during the ramp stop," in stop["detail"], stop


async def test_an_abort_during_an_idle_stop_a_read_made_the_emergency_stop_joins_it(broker, tmp_path, monkeypatch):
    """The stop with no run reads the spin drive turning in another program's emergency ramp, so the
    emergency stop (OFF3) goes out: the service records it as what it is, and an abort meanwhile is
    answered by that stop (no second stop sent beside it, as for an abort during an abort's stop),
    both replies saying what went out; no ramp stop word at all. (The spin drive's first word times
    out once, 1 s: the abort comes while the stop is under way.)"""
    from drives.link import ModbusLink

    rig = load_rig()
    rig = rig.model_copy(update={"drives": rig.drives.model_copy(update={"timeout_s": 1.0})})
    async with serving(broker, tmp_path, "read-off3-abort-rig", rig=rig, speedup=2, decel=18000) as (svc, sim_rig, rc):
        for drive in sim_rig.drives.values():
            drive.write(R.COMM_LOSS_TIMEOUT, [0])  # nothing stops them but the words sent
        sim_rig.local_control(spin=100.0, orbit=-50.0, hand_back=True)  # someone at the drives, no run
        async with ModbusLink(sim_rig.modbus_url, timeout=0.5) as other:
            await other.write(1, R.CW, [R.CW_EMERGENCY_STOP])  # another program's emergency stop
        await until(lambda: 10.0 < sim_rig.speeds[0] < 99.0, 30, "the spin drive in its emergency ramp")
        real_read_first, armed = idle_stop.read_first, []

        async def read_first(pair):
            found = await real_read_first(pair)
            sim_rig.modbus_servers[0].drop_next(1)  # the stop's first word (the spin drive's) times out
            armed.append(found)
            return found

        monkeypatch.setattr(idle_stop, "read_first", read_first)
        t_stop, mark = time.monotonic(), rc.watch.mark()
        await wait(rc.send, {"cmd": "stop", "id": "read-stop"})
        await until(lambda: armed, 15, "the stop's reads done")
        assert armed[0].emergency and svc._idle_stop is not None and not svc._idle_stop.done()
        await wait(publish_abort, rc, "abort-meanwhile")
        abort = await wait(rc.reply, "abort-meanwhile", 30, mark)
        stop = await wait(rc.reply, "read-stop", 30, mark)
        said = "emergency stop (OFF3, as spin (id 1) read turning in its emergency ramp) sent to both drives"
        assert stop["ok"] is True and said in stop["detail"], stop
        assert abort["ok"] is True and said in abort["detail"], abort
        for device, drive in sim_rig.drives.items():
            words = [cw for t, cw in drive.control_words if t >= t_stop]
            assert words == [R.CW_EMERGENCY_STOP], (device, [hex(w) for w in words])  # one stop, its word once
