"""The broker README of a lab folder, done as written: mosquitto started as root with the
lab's mosquitto.conf (no `user root`: it drops to the `mosquitto` user, as on a rig) keeps a
retained status across a restart once the README's commands have run, and loses it when the
persistence folder's `chown` is left out (what the README said before it named the folder); its
"Trying it out" command (passwd.example's accounts) does the same, also for a lab made with
`--broker-dir` once its files are copied there as that section says.

Real parts: `orbitrig init`'s files, mosquitto_passwd, chown, mosquitto 2, mosquitto_pub/sub.
Only the listener ports are changed (free ones, beside the other tests' brokers).
"""

from __future__ import annotations

import os
import pwd
import re
import shlex
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest

from support.mqtt_helpers import ACCOUNTS, end_process, launch_mosquitto, on_free_ports

from orbitrig.config.lab import write_lab

pytestmark = [
    pytest.mark.timeout(60),
    pytest.mark.skipif(os.geteuid() != 0, reason="mosquitto drops to its own user only when started as root"),
]


@pytest.fixture
def lab():
    """A lab folder the `mosquitto` user can reach (pytest's tmp_path is root's alone)."""
    base = Path(tempfile.mkdtemp(prefix="orbitrig-broker-"))
    base.chmod(0o755)
    write_lab(base / "lab")
    yield base / "lab"
    shutil.rmtree(base, ignore_errors=True)


def _setup(lab: Path, *, chown_data: bool) -> tuple[Path, int, int]:
    """The README's commands (passwords given with -b instead of typed), the conf on free
    ports; (conf, service port, people's port)."""
    readme = (lab / "mosquitto" / "README.md").read_text()
    lines = [ln.strip() for ln in readme.splitlines()]
    for line in (ln for ln in lines if ln.startswith("mosquitto_passwd ")):
        args = shlex.split(line)
        subprocess.run([*args[:-2], "-b", *args[-2:], ACCOUNTS[args[-1]]], check=True, capture_output=True)
    chowns = [ln for ln in lines if ln.startswith("chown ")]
    assert len(chowns) == 2 and "data/" in chowns[1]
    for line in chowns[: 2 if chown_data else 1]:
        subprocess.run(line, shell=True, check=True)
    conf = lab / "mosquitto" / "mosquitto.conf"
    text, svc, people = on_free_ports(conf.read_text())
    conf.write_text(text)
    return conf, svc, people


def _retained_status_survives_a_restart(conf: Path, svc: int, people: int) -> tuple[str | None, str]:
    """(the retained status read after a restart, or None; the broker's output of both starts)."""
    log = conf.with_name("broker.log")
    broker = launch_mosquitto(conf, log, svc)
    pub = ["mosquitto_pub", "-p", str(svc), "-u", "orbitrig-service", "-P", ACCOUNTS["orbitrig-service"]]
    subprocess.run([*pub, "-q", "1", "-r", "-t", "orbitrig/rig1/status", "-m", "idle"], check=True, timeout=10)
    end_process(broker)
    broker = launch_mosquitto(conf, log, svc)
    try:
        sub = [
            "mosquitto_sub",
            "-p",
            str(people),
            "-u",
            "viewer",
            "-P",
            ACCOUNTS["viewer"],
            "-t",
            "orbitrig/rig1/status",
        ]
        got = subprocess.run([*sub, "-C", "1", "-W", "3"], capture_output=True, text=True, timeout=10)
    finally:
        end_process(broker)
    return (got.stdout.strip() or None), log.read_text(errors="replace")


def test_the_readme_as_written_keeps_the_retained_status_across_a_restart(lab):
    conf, svc, people = _setup(lab, chown_data=True)
    data = lab / "mosquitto" / "data"
    got, log = _retained_status_survives_a_restart(conf, svc, people)
    assert got == "idle", log
    assert (data / "mosquitto.db").stat().st_uid == pwd.getpwnam("mosquitto").pw_uid


def test_without_the_data_folders_chown_the_broker_loses_it(lab):
    conf, svc, people = _setup(lab, chown_data=False)
    got, log = _retained_status_survives_a_restart(conf, svc, people)
    assert got is None
    assert "Permission denied" in log or "Error saving" in log, log


def test_trying_it_out_as_written_gives_the_example_accounts_a_broker(lab):
    readme = (lab / "mosquitto" / "README.md").read_text()
    [line] = [ln.strip() for ln in readme.splitlines() if ln.strip().startswith("cp passwd.example ")]
    subprocess.run(line, shell=True, check=True, cwd=lab / "mosquitto")
    conf = lab / "mosquitto" / "mosquitto.conf"
    text, svc, people = on_free_ports(conf.read_text())
    conf.write_text(text)
    got, log = _retained_status_survives_a_restart(conf, svc, people)  # the service's and viewer's accounts
    assert got == "idle", log


def test_trying_it_out_with_a_broker_dir_as_written():
    """init --broker-dir B writes the broker's files into DIR/mosquitto and names B in their
    mosquitto.conf: run in DIR/mosquitto the broker finds no password file; the README's copy
    into B, then its commands in B, give the example accounts a broker."""
    base = Path(tempfile.mkdtemp(prefix="orbitrig-broker-"))
    try:
        base.chmod(0o755)
        lab, broker = base / "lab", base / "broker"
        write_lab(lab, broker_dir=broker)
        assert not broker.exists()
        readme = (lab / "mosquitto" / "README.md").read_text()
        [copy] = re.findall(r"`(mkdir -p B/data && cp [^`\n]*)`", readme)
        [line] = [ln.strip() for ln in readme.splitlines() if ln.strip().startswith("cp passwd.example ")]
        subprocess.run(re.sub(r"\bB/", f"{broker}/", copy), shell=True, check=True, cwd=lab / "mosquitto")
        subprocess.run(line, shell=True, check=True, cwd=broker)
        conf = broker / "mosquitto.conf"
        text, svc, people = on_free_ports(conf.read_text())
        conf.write_text(text)
        got, log = _retained_status_survives_a_restart(conf, svc, people)
        assert got == "idle", log
        assert (broker / "data" / "mosquitto.db").is_file()
    finally:
        shutil.rmtree(base, ignore_errors=True)
