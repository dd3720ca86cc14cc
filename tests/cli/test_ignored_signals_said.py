"""A command started as a background job of a script (`orbitrig dashboard &`: POSIX starts it with
SIGINT and SIGQUIT ignored) leaves them ignored and says so at its start, as `orbitrig serve`
logs it: the same line, from one place (orbitrig.cli.signals.log_ignored). Real parts: the
`orbitrig dashboard` process, started with SIGINT ignored (inherited SIG_IGN); its broker
need not answer for this (it tries again in the background)."""

from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

from support.cli_helpers import orbitrig_started, reaped
from support.ports import free_port, wait_port

ROOT = Path(__file__).resolve().parents[2]
SAID = "started with SIGINT ignored (nohup, or a background job): left ignored"


def _as_a_background_job() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # what a shell without job control does for `cmd &`


def test_the_dashboard_started_with_sigint_ignored_says_so_and_keeps_it_ignored(tmp_path):
    port, log = free_port(), tmp_path / "dashboard.log"
    args = ("dashboard", "--broker", f"mqtt://127.0.0.1:{free_port()}", "--http", f"127.0.0.1:{port}")
    with open(log, "wb") as out:
        proc = orbitrig_started(
            *args,
            stdin=None,
            stdout=out,
            stderr=subprocess.STDOUT,
            env={"PYTHONUNBUFFERED": "1"},
            preexec_fn=_as_a_background_job,
        )
    with reaped(proc):
        wait_port(port, timeout=30)
        proc.send_signal(signal.SIGINT)  # ignored: it goes on
        time.sleep(1.0)
        assert proc.poll() is None, log.read_text()
        proc.send_signal(signal.SIGTERM)
        code = proc.wait(timeout=30)
    text = log.read_text()
    assert code == 0, text
    said = [line for line in text.splitlines() if SAID in line]
    assert len(said) == 1 and said[0].endswith(f"WARNING orbitrig.cli.dashboard: {SAID}"), text
    assert "Traceback" not in text, text
