"""An MQTT abort with no run holding the drives while someone at the rig has the spin drive at its
keypad (local control: it refuses the network's control words, docs/protocols/drive-modbus.md):
the orbit drive takes the emergency stop and stops; the reply is not ok and says which drive did
not take it and why, never that both were stopped (before: `Modbus exception 03`, no cause).

Real parts: mosquitto with the shipped ACL and accounts, the service `orbitrig serve --sim` builds
(in process, on the simulator over Modbus TCP), the simulator's keypads."""

from __future__ import annotations

import time

import pytest

from drives import registers as R
from support.mqtt_helpers import wait
from support.polling import until
from test_mqtt_abort_always_sent import publish_abort, serving

pytestmark = pytest.mark.timeout(120)


async def test_an_abort_with_one_drive_at_its_keypad_stops_the_other_and_names_it(broker, tmp_path):
    async with serving(broker, tmp_path, "local-rig") as (svc, sim_rig, rc):
        sim_rig.keypad(2, -30.0)  # turned from its keypad, then given back: the network may stop it
        sim_rig.keypad(2, None)
        sim_rig.keypad(1, 50.0)  # someone at the spin drive, and keeps it
        await until(lambda: min(abs(w) for w in sim_rig.speeds) > 10.0, 30, "both drives turning")
        t_abort = time.monotonic()
        mark = await wait(publish_abort, rc, "local-abort")
        reply = await wait(rc.reply, "local-abort", 15, mark)
        await until(lambda: abs(sim_rig.speeds[1]) < 1e-3, 30, "the orbit drive at standstill")
        spin = sim_rig.speeds[0]
        taken = {dev: [cw for t, cw in d.control_words if t >= t_abort] for dev, d in sim_rig.drives.items()}
        sim_rig.keypad(1, None)  # the operator gives it back
    assert reply["ok"] is False, reply
    said = (
        "emergency stop (OFF3) delivered to orbit (id 2) only: spin drive (id 1), register CW (0): did not take "
        "the emergency stop (OFF3, 0x047B): in local control (status word REMOTE = 0): the operator at its keypad has it"
    )
    assert said in reply["error"], reply
    assert "sent to both drives" not in str(reply), reply
    assert R.CW_EMERGENCY_STOP in taken[2] and not taken[1], taken  # the spin drive refused it: none taken
    assert spin == pytest.approx(50.0, abs=0.5)  # the keypad's speed: not stopped, not said stopped
