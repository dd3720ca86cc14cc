"""`orbitrig dashboard` ended by a signal says why on standard error, as `sweep` and `serve` do, in
the house's words (orbitrig.cli.signals.signal_cause first: ``SIGTERM: the dashboard stops``), one
line, and exits 0. Real parts: the `orbitrig dashboard` process serving
its page; its broker need not answer for this (it tries again in the background)."""

from __future__ import annotations

import signal
import subprocess

import pytest

from support.cli_helpers import orbitrig_started, reaped
from support.ports import free_port, wait_port


@pytest.mark.parametrize(("sig", "words"), [(signal.SIGTERM, "SIGTERM"), (signal.SIGINT, "Ctrl-C")])
def test_the_dashboard_ended_by_a_signal_says_so_and_exits_0(tmp_path, sig, words):
    port, log = free_port(), tmp_path / "dashboard.log"
    args = ("dashboard", "--broker", f"mqtt://127.0.0.1:{free_port()}", "--http", f"127.0.0.1:{port}")
    with open(log, "wb") as err:
        proc = orbitrig_started(*args, stdin=None, stdout=subprocess.DEVNULL, stderr=err, env={"PYTHONUNBUFFERED": "1"})
    with reaped(proc):
        wait_port(port, timeout=30)
        proc.send_signal(sig)
        code = proc.wait(timeout=30)
    text = log.read_text()
    assert code == 0, text
    said = [line for line in text.splitlines() if "the dashboard stops" in line]
    assert len(said) == 1 and said[0].endswith(f"INFO orbitrig.cli.dashboard: {words}: the dashboard stops"), text
    assert "Traceback" not in text, text
