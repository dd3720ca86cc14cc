"""docs/catalog.md's "On one machine, as root": its server of one's own in a folder, made as the
page writes it (initdb and pg_ctl as the `postgres` system user, since both refuse root), takes a
`catalog add` from root over the folder's socket, and that socket's `peer` rule refuses a role that
is not named as the system user asking, with the message the page quotes.

Real parts: Debian's PostgreSQL binaries, runuser, `orbitrig catalog add` and `list`. Only the
folder and the port are changed (a temporary folder, a free port)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from support.cli_helpers import child_env, orbitrig
from support.paths import ROOT
from support.pg_server import pg_bin
from support.ports import free_port

pytestmark = [
    pytest.mark.timeout(90),
    pytest.mark.skipif(os.geteuid() != 0, reason="the page's commands are root's (runuser)"),
    pytest.mark.skipif(
        subprocess.run(["id", "postgres"], capture_output=True).returncode != 0, reason="no postgres user"
    ),
]


def _folder_block() -> str:
    page = (ROOT / "docs" / "catalog.md").read_text()
    section = page.split("#### On one machine, as root", 1)[1].split("\n## ", 1)[0]
    [block] = [b for b in re.findall(r"```\n(.*?)```", section, re.S) if "initdb" in b]
    return block


def test_the_folder_server_as_written_takes_roots_add(catalog_run):
    block = _folder_block()
    assert "/usr/lib/postgresql/15/bin/" in block and "/srv/catalog" in block and "5433" in block
    base = Path(tempfile.mkdtemp(prefix="orbitrig-pgdoc-"))
    base.chmod(0o755)
    folder, port = base / "catalog", free_port()
    script = (
        block.replace("/usr/lib/postgresql/15/bin/", str(Path(pg_bin("initdb")).parent) + "/")
        .replace("/srv/catalog", str(folder))
        .replace("5433", str(port))
        .replace("runs/ecc-1", str(catalog_run))
    )
    shell = f'orbitrig() {{ "{sys.executable}" -m orbitrig "$@"; }}\nset -e\n{script}'
    try:
        done = subprocess.run(["bash", "-c", shell], cwd=ROOT, env=child_env(), capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        assert done.stdout.endswith(f"{catalog_run}: 16 rows\n"), done.stdout
        url = f"postgresql://root@/campaign?host={folder}&port={port}"
        listed = orbitrig("catalog", "list", "--db", url, "--columns", "point,model", "--where", "lms = piezo")
        assert listed.returncode == 0, listed.stderr
        assert len(listed.stdout.splitlines()) == 1 + 8  # the header, 2 points x 4 fits
        # the socket lets a role in only from the system user of its name: root as `postgres` is refused
        refused = orbitrig("catalog", "list", "--db", url.replace("root@", "postgres@"))
        assert refused.returncode == 1
        assert 'FATAL:  Peer authentication failed for user "postgres"' in refused.stderr
    finally:
        pg_ctl = [pg_bin("pg_ctl"), "-D", str(folder / "data"), "-m", "immediate", "stop"]
        subprocess.run(["runuser", "-u", "postgres", "--", *pg_ctl], capture_output=True)
        shutil.rmtree(base, ignore_errors=True)


def test_initdb_refuses_root_as_the_page_quotes(tmp_path):
    refused = subprocess.run([pg_bin("initdb"), "-D", str(tmp_path / "data")], capture_output=True, text=True)
    assert refused.returncode != 0
    assert "initdb: error: cannot be run as root" in refused.stderr
    assert "`initdb: error: cannot be run as root`" in (ROOT / "docs" / "catalog.md").read_text()
