"""`orbitrig serve` whose terminal stops reading (the operator's Ctrl-S: XOFF, the output held
by the terminal's line discipline) carries out an abort at once: its log is written by a thread
of its own (orbitrig.cli.service_log). Before, the first record logged then (the command's own)
held the event loop: the abort was neither carried out nor answered until Ctrl-Q. Real parts: a
pseudo-terminal and the keystrokes, mosquitto, `orbitrig serve --sim`."""

from __future__ import annotations

import time

from support.cli_helpers import orbitrig_started, reaped
from support.mqtt_helpers import ACCOUNTS, RigClient, interrupt, sim_service_args
from support.pseudo_terminal import CTRL_Q, CTRL_S, Terminal

RIG = "tty-rig"


def test_an_abort_is_carried_out_while_the_terminal_does_not_read(broker, tmp_path):
    terminal = Terminal()
    env = {"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]}
    args = sim_service_args(broker.url, RIG, tmp_path, "--confirm", "auto")
    tty = terminal.tty
    try:
        with reaped(
            orbitrig_started("serve", *args, stdin=None, stdout=tty, stderr=tty, env=env, cwd=tmp_path)
        ) as proc:
            terminal.started()
            rc = RigClient(broker, RIG)
            try:
                rc.ready()
                assert rc.command({"cmd": "start", "matrix": "long"})["ok"] is True
                run_id = rc.status("running")["run_id"]
                rc.watch.wait_for(lambda m: m.topic.endswith("/progress") and m.json()["revolutions"] > 0, 30)
                terminal.press(CTRL_S)
                time.sleep(1.0)
                mark = rc.watch.mark()
                cid = rc.send({"cmd": "abort"})
                assert rc.reply(cid, 5, start=mark)["ok"] is True  # before: no reply until Ctrl-Q
                ended = rc.status(lambda s: s["state"] == "idle" and s["run_id"] == run_id, 60, mark)
                assert "aborted" in ended["message"], ended
                terminal.press(CTRL_Q)
                terminal.shows("command abort", 10)  # logged all the same, once the terminal reads
                assert interrupt(proc) == 0
            finally:
                rc.close()
    finally:
        terminal.close()
