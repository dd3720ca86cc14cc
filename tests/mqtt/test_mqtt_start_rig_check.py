"""A start of `orbitrig serve` asks the rig's transports first, as `orbitrig sweep` does.

The drives' Modbus port refused: the start is answered ok: false in the words of the sweep's check
(orbitrig.run.rig_answers: the drives' line naming the URL, what to run instead), no run folder is
made or named, and the service stays ready; the drives' address corrected in rig.toml (loaded again
at each start), the next start begins its run
(its folder made and named) and is stopped.

Real parts: mosquitto with the shipped ACL and accounts, the service `orbitrig serve` builds (in
process, no --sim: its rig configuration names the simulator's endpoints), a simulator serving
Modbus TCP, the A/D board over TCP and CAN on a virtual bus; a port nothing listens on."""

from __future__ import annotations

import asyncio
import contextlib
import functools
import time
import pytest

from orbitrig.config import load_rig
from support.mqtt_helpers import (
    RigClient,
    Service,
    endpoint_lines,
    run_dirs,
    service_in_process,
    service_password_file,
    wait,
    write_matrices,
)
from support.ports import free_port
from support.rig_configs import lab_record_config, rig_without_answer

pytestmark = pytest.mark.timeout(240)


async def mute_drives(heard: list, closed: list, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
    """A drive port that takes a connection and never answers: each Modbus TCP request read is put
    in `heard` as (monotonic s, function code); `closed` gets the time its peer closed the link."""
    try:
        while header := await reader.readexactly(7):  # MBAP header: its length field counts the rest
            body = await reader.readexactly(int.from_bytes(header[4:6], "big") - 1)
            heard.append((time.monotonic(), body[0]))
    except (asyncio.IncompleteReadError, ConnectionError):
        closed.append(time.monotonic())
    finally:
        writer.close()


async def test_a_start_with_the_drives_refused_is_answered_and_the_next_one_runs(broker, tmp_path):
    from sim.rig import SimRig

    async with SimRig(speedup=20.0, adc_pty=False, can_channel="rig-check") as sim_rig:
        refused = f"tcp://127.0.0.1:{free_port()}"  # nothing listens there
        edits = {**endpoint_lines(sim_rig), "modbus_url": f'modbus_url = "{refused}"'}
        config = lab_record_config(tmp_path / "lab", edits=edits)
        svc = service_in_process(
            broker.url, tmp_path, "checked-rig", rig=load_rig(config), abort=False, reload=config, reconnect_initial=0.2
        )
        shutdown = asyncio.Event()
        task = asyncio.create_task(svc.serve(shutdown))
        rc = RigClient(broker, "checked-rig")
        try:
            await wait(rc.status, "idle")
            mark = rc.watch.mark()
            reply = await wait(rc.command, {"cmd": "start", "matrix": "quick"}, 30)
            assert reply["ok"] is False, reply
            error = reply["error"]
            assert error.startswith("start of 'quick' refused: the rig does not answer"), error
            assert f"([transports] and [drives] in {config}):" in error
            assert f"drives (modbus_url, [drives] spin_id, orbit_id): cannot connect to {refused}" in error
            assert "Nothing was started and no run folder was made" in error and "orbitrig serve --sim" in error
            assert "A/D board" not in error and "CAN sensor node" not in error  # those answered
            statuses = [m.json() for m in rc.watch.on("status", mark)]
            assert all("folder" not in s and s["state"] == "idle" for s in statuses), statuses
            assert not (tmp_path / "runs").exists() or run_dirs(tmp_path / "runs") == []
            assert svc.state == "idle" and not svc.run_active

            config.write_text(lab_record_config(tmp_path / "lab2", edits=endpoint_lines(sim_rig)).read_text())
            mark = rc.watch.mark()
            assert (await wait(rc.command, {"cmd": "start", "matrix": "quick"}, 30))["ok"] is True
            begun = await wait(rc.status, lambda s: s["run_id"] is not None and "folder" in s, 60, mark)
            (run,) = run_dirs(tmp_path / "runs")
            assert begun["folder"] == str(run.resolve()) and run.is_dir(), begun
            assert (await wait(rc.command, {"cmd": "stop"}))["ok"] is True
            await wait(rc.status, lambda s: s["state"] in ("idle", "faulted") and s["run_id"], 120, mark)
        finally:
            rc.close()
            shutdown.set()
            await asyncio.wait_for(asyncio.gather(task, return_exceptions=True), 120)


def test_serve_on_a_rig_that_does_not_answer_says_so_at_start_up_and_serves(broker, tmp_path):
    """`orbitrig serve` (no --sim) with no transport answering: ready all the same (the rig may be
    powered later), its log naming each transport that does not answer; a start is refused saying so."""
    config, subs = rig_without_answer(tmp_path)
    args = [
        *("--broker", broker.url, "--rig-id", "silent-rig", "--username", "orbitrig-service"),
        *("--password-file", str(service_password_file(tmp_path)), "--config", str(config)),
        *("--matrices", str(write_matrices(tmp_path / "matrices")), "--out", str(tmp_path / "runs")),
    ]
    svc = Service(args, tmp_path)
    try:
        rc = RigClient(broker, "silent-rig", svc)
        try:
            rc.ready()
            deadline = time.monotonic() + 30  # the start-up's words: each link refused at once
            while "the rig does not answer yet" not in svc.text() and time.monotonic() < deadline:
                time.sleep(0.05)
            refused = rc.command({"cmd": "start", "matrix": "quick"}, 30)
        finally:
            rc.close()
    finally:
        ended = svc.stop()  # Ctrl-C with no run: its emergency stop cannot reach the drives, exit 1
    said = svc.text()
    assert ended == 1 and "emergency stop NOT sent" in said, said[-3000:]
    assert f"the rig does not answer yet ([transports] and [drives] in {config}); each start asks again:" in said
    for what, url in (("A/D board", "adc_url"), ("drives", "modbus_url"), ("CAN sensor node", "can_channel")):
        assert f"  {what} (" in said and subs[url] in said, what
    assert refused["ok"] is False and "the rig does not answer" in refused["error"], refused
    assert not (tmp_path / "runs").exists() or run_dirs(tmp_path / "runs") == []


async def _service_on_mute_drives(broker, tmp_path, rig_id: str, heard: list, closed: list):
    """A drives' port that takes connections and never answers (``mute_drives`` records each request in
    ``heard`` and each closed link in ``closed``), and a service in this process whose rig.toml names it."""
    server = await asyncio.start_server(functools.partial(mute_drives, heard, closed), "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    config, subs = rig_without_answer(tmp_path)
    config.write_text(config.read_text().replace(subs["modbus_url"], f"tcp://127.0.0.1:{port}"))
    svc = service_in_process(
        broker.url, tmp_path, rig_id, rig=load_rig(config), abort=False, reload=config, reconnect_initial=0.2
    )
    return server, svc


async def test_an_abort_while_a_start_waits_on_mute_drives_goes_out_at_once(broker, tmp_path):
    """The worst case of a start's check: a drive port that takes the connection and never answers
    (the check waits out its timeout). An abort sent meanwhile opens its own link at once: its stop
    word reaches the drives' port while the check still waits (before the start's reply), never behind
    it; the start is refused naming the drives, no run folder is made."""
    from orbitrig.run.rig_answers import TIMEOUT_S

    heard: list[tuple[float, int]] = []  # (monotonic s, Modbus function code) of each request
    server, svc = await _service_on_mute_drives(broker, tmp_path, "mute-rig", heard, [])
    shutdown = asyncio.Event()
    task = asyncio.create_task(svc.serve(shutdown))
    rc = RigClient(broker, "mute-rig")
    try:
        await wait(rc.status, "idle")
        mark = rc.watch.mark()
        start = rc.send({"cmd": "start", "matrix": "quick"})
        deadline = time.monotonic() + 30
        while not heard and time.monotonic() < deadline:  # the check's first read, left unanswered
            await asyncio.sleep(0.01)
        assert heard and heard[0][1] == 3, heard  # read holding registers: nothing written
        sent = time.monotonic()
        abort = rc.send({"cmd": "abort"})
        while not any(fc in (6, 16) for _, fc in heard) and time.monotonic() < deadline:
            await asyncio.sleep(0.01)
        written = next(t for t, fc in heard if fc in (6, 16))  # the abort's emergency stop word
        refused = await wait(rc.reply, start, 30, mark)
        replied = time.monotonic()
        print(
            f"abort's stop word at the drives' port {1e3 * (written - sent):.0f} ms after the abort was sent; "
            f"the start's reply {1e3 * (replied - sent):.0f} ms after it"
        )
        assert written < replied and written - sent < TIMEOUT_S, (written - sent, replied - sent)
        assert refused["ok"] is False and "drives (modbus_url" in refused["error"], refused
        assert "Nothing was started" in refused["error"], refused
        assert (await wait(rc.reply, abort, 30, mark))["ok"] is False  # mute drives: not confirmed sent
        assert all(fc in (3, 6, 16) for _, fc in heard), heard
        assert not (tmp_path / "runs").exists() or run_dirs(tmp_path / "runs") == []
    finally:
        rc.close()
        shutdown.set()
        await asyncio.wait_for(asyncio.gather(task, return_exceptions=True), 120)
        server.close()


async def test_a_shutdown_during_a_start_check_waits_for_it_and_refuses_the_start(broker, tmp_path):
    """SIGTERM while a start's check waits on mute drives: the shutdown waits for the check (its
    thread closes its link: the service leaves no check running behind it), the start's refusal (here
    the check's: the drives do not answer) is sent before offline, and no run folder is made."""
    heard: list[tuple[float, int]] = []
    closed: list[float] = []
    server, svc = await _service_on_mute_drives(broker, tmp_path, "leaving-rig", heard, closed)
    shutdown = asyncio.Event()
    task = asyncio.create_task(svc.serve(shutdown))
    rc = RigClient(broker, "leaving-rig")
    try:
        await wait(rc.status, "idle")
        mark = rc.watch.mark()
        start = rc.send({"cmd": "start", "matrix": "quick"})
        deadline = time.monotonic() + 30
        while not heard and time.monotonic() < deadline:  # the check waits on the drives
            await asyncio.sleep(0.01)
        assert heard and not closed, (heard, closed)
        shutdown.set()
        await asyncio.wait_for(asyncio.gather(task, return_exceptions=True), 60)
        assert closed, "the check's link was left open after serve returned"
        refused = await wait(rc.reply, start, 10, mark)
        assert refused["ok"] is False and "refused: the rig does not answer" in refused["error"], refused  # mute drives
        (answer,) = [m for m in rc.watch.on("reply", mark) if m.json().get("id") == start]
        offline = await wait(rc.status, "offline", 10, mark)
        (gone,) = [m for m in rc.watch.on("status", mark) if m.json() == offline]
        assert answer.t <= gone.t, (answer, gone)  # the refusal before offline
        assert not (tmp_path / "runs").exists() or run_dirs(tmp_path / "runs") == []
    finally:
        rc.close()
        shutdown.set()
        await asyncio.wait_for(asyncio.gather(task, return_exceptions=True), 120)
        server.close()


@pytest.mark.parametrize("asker", ["start", "start-up"])
async def test_an_abort_while_a_check_holds_the_drives_serial_port_waits_for_it_to_let_go(broker, tmp_path, asker):
    """Drives on RS-485 (RTU): a start's check (or the service's look at the rig as `orbitrig serve`
    starts) opens their serial port exclusively and waits on mute drives. An abort meanwhile cannot
    open the port at once: it retries until the check lets go (not 'NOT sent' at the first refusal)
    and its stop words then go down the cable."""
    import os
    import threading

    from orbitrig.run.rig_answers import say_what_answers

    from support.serial_cable import serial_cable

    config, subs = rig_without_answer(tmp_path)
    with serial_cable(tmp_path) as (near, far):
        wire: list[tuple[float, bytes]] = []  # what reaches the drives' end, with when (monotonic s)
        over = threading.Event()

        def listen() -> None:
            os.set_blocking(far, False)
            while not over.wait(0.005):
                with contextlib.suppress(BlockingIOError, OSError):
                    if data := os.read(far, 4096):
                        wire.append((time.monotonic(), data))

        reader = threading.Thread(target=listen, daemon=True)
        reader.start()
        config.write_text(config.read_text().replace(subs["modbus_url"], f"rtu://{near}?baud=19200"))
        svc = service_in_process(
            broker.url, tmp_path, "rtu-rig", rig=load_rig(config), abort=False, reload=config, reconnect_initial=0.2
        )
        shutdown = asyncio.Event()
        task = asyncio.create_task(svc.serve(shutdown))
        rc = RigClient(broker, "rtu-rig")
        try:
            await wait(rc.status, "idle")
            mark = rc.watch.mark()
            if asker == "start":
                start = rc.send({"cmd": "start", "matrix": "quick"})
            else:  # as orbitrig serve on the rig does as it starts
                asked = asyncio.create_task(say_what_answers(load_rig(config), "orbitrig.cli.serve"))
                svc.port_asked_by(asked)
            deadline = time.monotonic() + 30
            while not wire and time.monotonic() < deadline:  # the check's read, on the port it holds
                await asyncio.sleep(0.01)
            assert wire, "the check sent nothing"
            sent = time.monotonic()
            abort = await wait(rc.reply, rc.send({"cmd": "abort"}), 60, mark)
            assert "cannot open their link" not in abort.get("error", ""), abort
            if asker == "start":
                assert (await wait(rc.reply, start, 30, mark))["ok"] is False
            after = b"".join(data for t, data in wire if t > sent)
            stop_words = [bytes([dev, fc]) in after for dev in (1, 2) for fc in (6, 16)]
            assert any(stop_words), after.hex()
        finally:
            rc.close()
            shutdown.set()
            await asyncio.wait_for(asyncio.gather(task, return_exceptions=True), 120)
            over.set()
            reader.join(5)
