"""The broker README's "TLS for the network", done as written in a lab folder: its openssl and
chown lines make a CA and a broker key the broker (started as root, dropping to the `mosquitto`
user) loads, the TLS listener uncommented takes the README's mosquitto_pub and mosquitto_sub with
`--cafile` and the example accounts; without the chown the broker stops at start naming the key.

Real parts: `orbitrig init`'s files, openssl, chown, mosquitto 2, mosquitto_pub/sub. Changed
only: the host name (the certificate names 127.0.0.1, where the test's clients connect), free
ports, the passwords typed in place of '...'."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest

from support.mqtt_helpers import ACCOUNTS, end_process, launch_mosquitto, on_free_ports
from support.ports import free_port

from orbitrig.config.lab import write_lab

pytestmark = [
    pytest.mark.timeout(60),
    pytest.mark.skipif(os.geteuid() != 0, reason="mosquitto drops to its own user only when started as root"),
]

TLS_LINES = r"(?m)^#((?:listener 8883|cafile|certfile|keyfile|tls_version)\b.*)$"


@pytest.fixture
def broker_dir():
    """A lab's broker folder the `mosquitto` user can reach, its example password file in place."""
    base = Path(tempfile.mkdtemp(prefix="orbitrig-tls-"))
    base.chmod(0o755)
    write_lab(base / "lab")
    folder = base / "lab" / "mosquitto"
    readme = (folder / "README.md").read_text()
    [line] = [ln.strip() for ln in readme.splitlines() if ln.strip().startswith("cp passwd.example ")]
    subprocess.run(line, shell=True, check=True, cwd=folder)
    yield folder
    shutil.rmtree(base, ignore_errors=True)


def _tls_section(folder: Path) -> list[str]:
    """The section's command lines, continuations joined, for 127.0.0.1."""
    text = (folder / "README.md").read_text().split("## TLS for the network", 1)[1].split("\n## ", 1)[0]
    text = text.replace("\\\n", "").replace("DNS:rig-broker", "IP:127.0.0.1").replace("-h rig-broker", "-h 127.0.0.1")
    return [ln.strip() for ln in text.splitlines() if ln.startswith("    ")]


def _conf_with_tls(folder: Path) -> tuple[Path, int]:
    conf = folder / "mosquitto.conf"
    text, _, _ = on_free_ports(conf.read_text())
    text, n = re.subn(TLS_LINES, r"\1", text)
    assert n == 5, "mosquitto.conf no longer has the five commented TLS lines the README uncomments"
    port = free_port()
    text = text.replace("\nlistener 8883\n", f"\nlistener {port} 127.0.0.1\n")
    conf.write_text(text)
    return conf, port


def _as_typed(line: str, port: int) -> list[str]:
    for user, password in ACCOUNTS.items():
        line = line.replace(f"-u {user} -P '...'", f"-u {user} -P '{password}'")
    return ["bash", "-c", line.replace("-p 8883", f"-p {port}")]


def test_the_tls_section_as_written_carries_a_supervisors_command(broker_dir):
    lines = _tls_section(broker_dir)
    for line in (ln for ln in lines if ln.startswith(("openssl ", "printf ", "chmod "))):
        subprocess.run(line, shell=True, check=True, cwd=broker_dir, capture_output=True)
    conf, port = _conf_with_tls(broker_dir)
    log = broker_dir / "broker.log"
    broker = launch_mosquitto(conf, log, port)
    try:
        [sub_line] = [ln for ln in lines if ln.startswith("mosquitto_sub ")]
        [start, _stop] = [ln for ln in lines if ln.startswith("mosquitto_pub ")]
        sub = subprocess.Popen(
            [*_as_typed(sub_line, port)[:-1], _as_typed(sub_line, port)[-1] + " -C 1 -W 10"],
            cwd=broker_dir,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        got = ""
        for _ in range(20):  # until the subscription is in place (the viewer sees the operator's command)
            subprocess.run(_as_typed(start, port), cwd=broker_dir, check=True, timeout=10)
            try:
                got, _err = sub.communicate(timeout=0.5)
                break
            except subprocess.TimeoutExpired:
                continue
        assert got.startswith('orbitrig/rig1/cmd {"cmd": "start", "id": "a1"'), (got, log.read_text())
        without_ca = subprocess.run(
            _as_typed(start.replace("--cafile ca.crt ", ""), port), cwd=broker_dir, capture_output=True, text=True
        )
        assert without_ca.returncode != 0, without_ca.stderr
        wrong = subprocess.run(
            _as_typed(start, port)[:2] + [_as_typed(start, port)[2].replace("'op-secret'", "'op-wrong'")],
            cwd=broker_dir,
            capture_output=True,
            text=True,
        )
        assert wrong.returncode != 0 and "Connection Refused: not authorised." in wrong.stderr
    finally:
        end_process(broker)


def test_a_key_only_root_reads_stops_the_broker(broker_dir):
    lines = _tls_section(broker_dir)
    for line in (ln for ln in lines if ln.startswith(("openssl ", "printf "))):  # no chown
        subprocess.run(line, shell=True, check=True, cwd=broker_dir, capture_output=True)
    (broker_dir / "broker.key").chmod(0o600)
    conf, port = _conf_with_tls(broker_dir)
    done = subprocess.run(["mosquitto", "-c", str(conf)], capture_output=True, text=True, timeout=20)
    assert done.returncode != 0
    out = done.stdout + done.stderr
    assert f'Error: Unable to load server key file "{broker_dir / "broker.key"}". Check keyfile.' in out, out
    assert "Permission denied" in out, out
