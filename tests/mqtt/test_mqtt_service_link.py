"""The service's broker link, in process, against a real mosquitto: retained
status and last will, credentials, TLS with a CA file, reconnection, command
replies that need no run. (Runs themselves: test_mqtt_serve.py.)"""

from __future__ import annotations

import asyncio
import contextlib
import subprocess
from pathlib import Path

import pytest

from support.cli_helpers import orbitrig, orbitrig_here, reaped_async, started_async
from support.mqtt_helpers import ACCOUNTS, Broker, RigClient, Watcher, retained, wait
from orbitrig.service.rig_service import BrokerSettings, RigService, ServiceError, ServiceSettings


def _no_engine(name, matrix):
    raise AssertionError("no run is started in these tests")


def _service(
    broker: Broker, tmp_path: Path, rig_id: str, *, password: str = ACCOUNTS["orbitrig-service"], **kw
) -> RigService:
    matrices = tmp_path / "matrices"
    matrices.mkdir(exist_ok=True)
    (matrices / "quick.toml").write_text("name = 'quick'\n")
    (matrices / "broken.toml").write_text("name = \n")
    settings = ServiceSettings(rig_id=rig_id, matrices_dir=matrices, **kw)
    from orbitrig.config import load_matrix

    return RigService(
        settings,
        BrokerSettings.from_url(
            broker.url, username="orbitrig-service", password=password, tls_ca=getattr(broker, "ca", None)
        ),
        engine_factory=_no_engine,
        load_matrix=load_matrix,
    )


@contextlib.asynccontextmanager
async def running(service: RigService):
    stop = asyncio.Event()
    task = asyncio.create_task(service.serve(stop), name="service-under-test")
    try:
        yield task
    finally:
        stop.set()
        await asyncio.wait_for(task, 10)


@pytest.mark.parametrize(
    "url, host, port, tls",
    [
        ("mqtt://127.0.0.1:1884", "127.0.0.1", 1884, False),
        ("mqtt://broker.lab", "broker.lab", 1883, False),
        ("mqtts://broker.lab", "broker.lab", 8883, True),
    ],
)
def test_broker_url(url, host, port, tls):
    b = BrokerSettings.from_url(url)
    assert (b.host, b.port, b.tls) == (host, port, tls)


@pytest.mark.parametrize(
    "url, why",
    [
        ("tcp://h:1", "expected mqtt://"),
        ("mqtt://", "expected mqtt://"),
        ("mqtt://u:pw@h:1", "credentials do not belong in the URL"),
        ("mqtt://h:1/x", "no path"),
        ("mqtt://h:99999", "out of range"),
    ],
)
def test_bad_broker_url(url, why):
    with pytest.raises(ServiceError, match=why):
        BrokerSettings.from_url(url)


def test_password_not_in_repr():
    assert "s3cret" not in repr(BrokerSettings("h", username="u", password="s3cret"))


async def test_status_retained_and_offline_on_shutdown(broker, tmp_path):
    service = _service(broker, tmp_path, "link1")
    async with running(service):
        w = Watcher(broker, "orbitrig/link1/status")
        try:
            msg = await wait(w.wait_for, lambda m: True, 10)
        finally:
            w.close()
        assert msg.qos == 1 and msg.json()["state"] == "idle" and msg.json()["run_id"] is None
        late = await wait(retained, broker, "orbitrig/link1/status")  # a late subscriber gets it
        assert late.retain and late.payload == msg.payload
    # after a clean shutdown the retained status says offline
    msg = await wait(retained, broker, "orbitrig/link1/status")
    assert msg.retain and msg.json()["state"] == "offline"
    assert msg.json()["message"] == "service stopped"


async def test_refused_credentials_are_fatal(broker, tmp_path):
    service = _service(broker, tmp_path, "link2", password="wrong")
    with pytest.raises(ExceptionGroup) as info:
        await asyncio.wait_for(service.serve(asyncio.Event()), 10)
    err = info.value.exceptions[0]
    assert isinstance(err, ServiceError) and "refused the credentials of 'orbitrig-service'" in str(err)


async def test_commands_without_a_run(broker, tmp_path):
    service = _service(broker, tmp_path, "link3")
    async with running(service):
        rc = RigClient(broker, "link3")
        try:
            await wait(rc.status, "idle")
            cases = [
                ({"cmd": "pause"}, "no run is active: nothing to pause"),
                ({"cmd": "resume"}, "no run is active: nothing to resume"),
                ({"cmd": "confirm", "step": "orbit_radius"}, "no run is active: nothing to confirm"),
                (
                    {"cmd": "start", "matrix": "nope"},
                    "no matrix 'nope' in the matrix folder (available: broken, quick)",
                ),
                ({"cmd": "start", "matrix": "broken"}, "matrix 'broken' is invalid: not valid TOML"),
                (
                    {"cmd": "start", "matrix": "quick"},
                    "matrix 'quick' is invalid: key 'operating': required key is missing",
                ),
                (
                    {"cmd": "start", "matrix": "quick"},
                    f"(file {tmp_path / 'matrices' / 'quick.toml'})",
                ),  # which file to mend
                ({"cmd": "start", "matrix": "/etc/passwd"}, "not a path"),
            ]
            for cmd, why in cases:
                reply = await wait(rc.command, cmd)
                assert reply["ok"] is False and why in reply["error"], (cmd, reply)
            reply = await wait(rc.command, {"cmd": "stop"})  # always accepted: no run, no drive link: said so
            assert reply["ok"] is False and reply["error"].startswith("not sent: no run holds the drives"), reply
            reply = await wait(rc.command, {"cmd": "abort"})  # no run since the start: no drive link known
            assert reply["ok"] is False and reply["error"].startswith("not sent: no run holds the drives"), reply
            mark = rc.watch.mark()
            assert (await wait(rc.command, {"cmd": "status"}))["ok"] is True
            await wait(rc.status, "idle", start=mark)  # published again
            assert service.state == "idle" and not service.run_active
        finally:
            rc.close()


async def test_tls_with_ca_file(tmp_path):
    with Broker(tmp_path / "tls-broker", tls=True) as b:
        service = _service(b, tmp_path, "tls1")
        assert service.broker.tls and service.broker.tls_ca == b.ca
        async with running(service):
            w = Watcher(b, "orbitrig/tls1/status")  # mosquitto_sub over TLS, same CA
            try:
                msg = await wait(w.wait_for, lambda m: True, 10)
            finally:
                w.close()
            assert msg.json()["state"] == "idle"


async def test_reconnects_and_republishes_status(tmp_path):
    with Broker(tmp_path / "flaky-broker") as b:
        service = _service(b, tmp_path, "re1", supervision_timeout=30)
        async with running(service):
            w = Watcher(b, "orbitrig/re1/status")
            try:
                await wait(w.wait_for, lambda m: True, 10)
            finally:
                w.close()
            assert service.connections == 1
            b.stop()  # persistence is off: the retained status is gone with the broker
            await asyncio.sleep(0.5)
            b.start()
            w = Watcher(b, "orbitrig/re1/status")
            try:
                msg = await wait(w.wait_for, lambda m: True, 15)
            finally:
                w.close()
            assert msg.json()["state"] == "idle"
            assert service.connections == 2
            assert (await wait(retained, b, "orbitrig/re1/status")).payload == msg.payload


def _serve_cli(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    """`orbitrig serve ARGS...` in this process (typer's runner): for the checks of its options,
    made before it connects; no ORBITRIG_MQTT_PASSWORD unless `env` is given."""
    return orbitrig_here("serve", *args, env={"ORBITRIG_MQTT_PASSWORD": None} if env is None else env)


def test_cli_needs_a_password_from_file_or_environment(broker):
    done = _serve_cli("--broker", broker.url, "--username", "orbitrig-service")
    assert done.returncode == 2
    assert "no password: give --password-file or set ORBITRIG_MQTT_PASSWORD" in done.stderr
    assert "--password" not in _serve_cli("--help").stdout.replace("--password-file", "")


def test_cli_refused_credentials_exit_1(broker, tmp_path):
    pw = tmp_path / "pw"
    pw.write_text("wrong\n")
    pw.chmod(0o600)
    done = orbitrig(  # a real process: its exit status once the broker refused it
        *("serve", "--broker", broker.url, "--username", "orbitrig-service", "--password-file", str(pw)),
        timeout=60,
        columns=None,
        env={"ORBITRIG_MQTT_PASSWORD": None},
    )
    assert done.returncode == 1, done.stderr
    assert "refused the credentials of 'orbitrig-service'" in done.stderr


@pytest.mark.parametrize(
    "args, why",
    [
        (["--no-abort-connection", "--abort-username", "x"], "--no-abort-connection: no --abort-username"),
        (["--abort-password-file", "{open}"], "--abort-password-file: {open} is accessible by other users"),
        (["--abort-username", "x", "--abort-password-file", "{empty}"], "--abort-password-file: {empty} is empty"),
    ],
)
def test_cli_checks_the_abort_account_options(broker, tmp_path, args, why):
    files = {"open": tmp_path / "open", "empty": tmp_path / "empty"}
    files["open"].write_text("pw\n")
    files["open"].chmod(0o644)
    files["empty"].write_text("")
    files["empty"].chmod(0o600)
    names = {k: str(v) for k, v in files.items()}
    env = {"ORBITRIG_MQTT_PASSWORD": ACCOUNTS["orbitrig-service"]}
    args = [a.format(**names) for a in args]
    done = _serve_cli("--broker", broker.url, "--username", "orbitrig-service", *args, env=env)
    assert done.returncode == 2, done.stderr
    assert why.format(**names) in done.stderr and "Traceback" not in done.stderr


@pytest.mark.parametrize("mode", [0o644, 0o640, 0o604, 0o606, 0o620])
def test_cli_refuses_a_password_file_others_can_access(broker, tmp_path, mode):
    pw = tmp_path / "pw"
    pw.write_text(ACCOUNTS["orbitrig-service"] + "\n")
    pw.chmod(mode)
    done = _serve_cli("--broker", broker.url, "--username", "orbitrig-service", "--password-file", str(pw))
    assert done.returncode == 2, done.stderr
    assert f"{pw} is accessible by other users (mode {mode:04o}): chmod 600" in done.stderr
    assert "Traceback" not in done.stderr


@pytest.mark.parametrize("mode", [0o755, 0o700])
def test_cli_says_a_password_file_that_is_a_folder_is_one(broker, tmp_path, mode):
    """Its mode was blamed (0755: "accessible by other users"), or chmod 600 suggested, of a folder."""
    folder = tmp_path / "secrets"
    folder.mkdir()
    folder.chmod(mode)
    done = _serve_cli("--broker", broker.url, "--username", "orbitrig-service", "--password-file", str(folder))
    assert done.returncode == 2, done.stderr
    assert f"--password-file: {folder} is a folder: give the file holding the password" in done.stderr
    assert "chmod" not in done.stderr and "Traceback" not in done.stderr


def test_cli_refuses_a_password_file_that_is_not_utf8(broker, tmp_path):
    pw = tmp_path / "pw"
    pw.write_bytes(b"caf\xe9\n")
    pw.chmod(0o600)
    done = _serve_cli("--broker", broker.url, "--username", "orbitrig-service", "--password-file", str(pw))
    assert done.returncode == 2 and "is not UTF-8 text" in done.stderr and "Traceback" not in done.stderr


@pytest.mark.parametrize("value", ["nan", "inf", "-1", "0"])
def test_cli_supervision_timeout_must_be_finite_and_positive(broker, value):
    done = _serve_cli(
        "--broker",
        broker.url,
        "--supervision-timeout",
        value,
        env={"ORBITRIG_MQTT_PASSWORD": "x", "ORBITRIG_MQTT_USERNAME": "orbitrig-service"},
    )
    assert done.returncode == 2 and "supervision timeout must be a finite number" in done.stderr, done.stderr


@pytest.mark.parametrize("value", ["nan", "inf", "0"])
def test_cli_speedup_must_be_finite_and_positive(broker, value):
    done = _serve_cli(
        "--broker",
        broker.url,
        "--sim",
        "--speedup",
        value,
        env={"ORBITRIG_MQTT_PASSWORD": "x", "ORBITRIG_MQTT_USERNAME": "orbitrig-service"},
    )
    assert done.returncode == 2 and "--speedup" in done.stderr and "Traceback" not in done.stderr


@pytest.mark.parametrize(
    "given, says",
    [
        (("--sim-config", "paper"), "--sim-config needs --sim"),
        (("--sim", "--sim-config", "nope"), "nope: no such file; unknown simulator scenario 'nope'; known: paper,"),
        (("--sim", "--sim-config", "pyproject.toml"), "pyproject.toml: "),  # not a scenario's TOML
    ],
)
def test_cli_checks_the_sim_config_as_the_sweep_does(given, says):
    """The option and its checks are sweep's: refused (exit 2) before anything starts, with sweep's words."""
    done = _serve_cli("--broker", "mqtt://127.0.0.1:1", *given)
    assert done.returncode == 2 and f"Invalid value for --sim-config: {says}" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr
    sweep = orbitrig_here("sweep", "--dry-run", *given)
    assert sweep.returncode == 2 and f"Invalid value for --sim-config: {says}" in sweep.stderr, sweep.stderr


async def test_a_flood_is_answered_busy_or_counted_and_a_stop_amid_it_is_carried_out(broker, tmp_path):
    """5000 mixed QoS 0/1 commands from another operator: those that find the queue full
    are answered busy or dropped from their raw bytes (orbitrig/service/flood_read.py),
    every one counted; a stop sent in the middle is still read, carried out and answered,
    even though the service's loop stalls 2 s just then (a host busy with other work):
    the broker's queue for the service (max_queued_messages, the shipped config) holds
    the rest of the flood and the stop meanwhile instead of dropping them."""
    import json
    import sys
    import time

    service = _service(broker, tmp_path, "flood1")
    async with running(service):
        # the observer watches only status and replies: watching the 5000 commands too, its own
        # broker queue (1000, the shipped limit) overflowed under load and lost the stop's reply
        rc = RigClient(broker, "flood1", watch=("status", "reply"))
        try:
            await wait(rc.status, "idle")
            flooder = [sys.executable, str(Path(__file__).with_name("mqtt_flood.py")), "--port", str(broker.port)]
            flood = await started_async(
                [*flooder, "--prefix", "orbitrig/flood1", "--count", "5000", "--qos", "mixed"]
                + ["--quiet", "3"]  # s without a reply before the flood's client sums up: longer than the stall below
                + ["--password", ACCOUNTS["operator"]],
                stderr=None,
            )
            async with reaped_async(flood):
                assert (await asyncio.wait_for(flood.stdout.readline(), 60)).strip() == b"half"
                asyncio.get_running_loop().call_soon(time.sleep, 2.0)  # the stall; the stop goes out in it,
                # once the flood has had 0.5 s to fill the broker's queue for the service (1000 did not hold it)
                stopped = await wait(lambda: time.sleep(0.5) or rc.command({"cmd": "stop"}, 20))
                assert stopped["error"].startswith("not sent: no run holds the drives"), (
                    stopped
                )  # (no drive link known)
                summary = json.loads((await asyncio.wait_for(flood.stdout.read(), 120)).decode().splitlines()[-1])
                await flood.wait()
        finally:
            rc.close()
    counts = service.triage.counts
    assert counts["at once"] == 1
    assert 0 < counts["received"] <= 5001 and counts["busy"] + counts["dropped"] > 0, counts
    # each reply the flood got was sent by the service (busy ones counted), none twice
    assert summary["busy"] <= counts["busy"], (summary, counts)
    assert summary["ok"] + summary["refused"] + counts["busy"] + counts["dropped"] <= counts["received"] - 1
    assert summary["seconds"] - summary["out_s"] < 10, summary  # no backlog long after the flood


@pytest.mark.parametrize(
    "option, says",
    [("--tls-ca", "--tls-ca: a folder, not a file: {folder}"), ("--matrices", "matrix folder: a file, not a folder")],
)
def test_a_folder_for_a_file_or_a_file_for_a_folder_is_said_so(tmp_path, option, says):
    """They said "no such file" of a folder and "no such folder" of a file."""
    a_file = tmp_path / "quick.toml"
    a_file.write_text("")
    given = tmp_path if option == "--tls-ca" else a_file
    p = _serve_cli("--broker", "mqtts://127.0.0.1:1", option, str(given))
    assert p.returncode == 2, p.stderr
    assert f"orbitrig serve: error: {says.format(folder=tmp_path)}" in p.stderr and "Traceback" not in p.stderr
