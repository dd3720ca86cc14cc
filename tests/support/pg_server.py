"""A real PostgreSQL server for the catalog tests, from Debian's packages, started in a
temporary directory under a system user (initdb refuses root), on a private socket."""

from __future__ import annotations

import glob
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest

from .ports import free_port

PG_USER = "orbitrig-pg"


def pg_bin(name: str) -> str:
    """Path of PostgreSQL's program `name` (initdb, pg_ctl, psql): Debian's newest version, else on PATH."""
    found = sorted(glob.glob(f"/usr/lib/postgresql/*/bin/{name}")) or [shutil.which(name)]
    if not found[-1]:
        raise RuntimeError(f"{name} not found: install Debian's postgresql (tools/run-tests does)")
    return found[-1]


def _as_user(*args: str) -> list[str]:
    return ["runuser", "-u", PG_USER, "--", *args] if os.geteuid() == 0 else list(args)


@pytest.fixture(scope="session")
def postgres_server():
    """URL of a fresh PostgreSQL server (trust authentication, Unix socket only)."""
    if os.geteuid() == 0 and subprocess.run(["id", PG_USER], capture_output=True).returncode != 0:
        subprocess.run(["useradd", "--system", "--no-create-home", PG_USER], check=True)
    base = Path(tempfile.mkdtemp(prefix="orbitrig-pg-"))
    base.chmod(0o755)
    data, sock = base / "data", base / "sock"
    sock.mkdir()
    if os.geteuid() == 0:
        shutil.chown(base, PG_USER)
        shutil.chown(sock, PG_USER)
    port = free_port()
    subprocess.run(
        _as_user(pg_bin("initdb"), "-D", str(data), "-A", "trust", "-U", "postgres"), check=True, capture_output=True
    )
    options = f"-k {sock} -p {port} -c listen_addresses='' -c fsync=off"
    subprocess.run(
        _as_user(pg_bin("pg_ctl"), "-D", str(data), "-o", options, "-w", "-l", str(base / "log"), "start"),
        check=True,
        capture_output=True,
    )
    try:
        yield f"postgresql://postgres@/postgres?host={sock}&port={port}"
    finally:
        subprocess.run(_as_user(pg_bin("pg_ctl"), "-D", str(data), "-m", "immediate", "stop"), capture_output=True)
        shutil.rmtree(base, ignore_errors=True)
