"""`orbitrig serve --log-file`: the service's own log rotates by size and keeps a bounded
number of files, whatever a month of status and live messages writes to it; a serve refused for
its options sets up no log (no file, no handler)."""

from __future__ import annotations

import logging

import pytest

from orbitrig.cli import service_log as service_logs
from orbitrig.cli.service_log import setup_service_log

from support.cli_helpers import orbitrig_here


def test_thousands_of_messages_keep_the_log_files_under_the_stated_size(tmp_path):
    log_file = tmp_path / "serve.log"
    root = logging.getLogger()
    before, level = list(root.handlers), root.level
    service_log = setup_service_log(verbose=True, log_file=log_file, max_mb=0.05, backups=3)
    try:
        status = logging.getLogger("orbitrig.service.rig_service")
        for i in range(20_000):  # a month of a busy service, compressed
            status.debug(
                "status running run %s: point %d of 108, block %d of 20, eta %.1f s",
                "paper-1",
                i % 108,
                i % 20,
                1e4 / (i + 1),
            )
            if i % 7 == 0:
                logging.getLogger("orbitrig.service.live").info("live: %d revolutions published", i)
            if i % 1000 == 999:  # the log's thread keeps up (on busy cores too): nothing dropped for want of room
                assert service_log.written(30.0)
    finally:
        service_log.close()  # every record written
        root.handlers[:] = before
        root.setLevel(level)
    files = sorted(tmp_path.glob("serve.log*"))
    assert [f.name for f in files] == ["serve.log", "serve.log.1", "serve.log.2", "serve.log.3"]
    sizes = [f.stat().st_size for f in files]
    assert all(s <= 50_000 for s in sizes), sizes
    assert sum(sizes) > 150_000  # it did rotate through full files
    assert "point" in log_file.read_text().splitlines()[-1] or "live" in log_file.read_text().splitlines()[-1]


def test_a_log_closed_by_its_command_and_again_at_the_exit_writes_each_record_once(tmp_path):
    log_file = tmp_path / "serve.log"
    root = logging.getLogger()
    before, level = list(root.handlers), root.level
    service_log = setup_service_log(verbose=False, log_file=log_file)
    try:
        logging.getLogger("orbitrig.service").info("stopped by SIGTERM")
        service_log.close()
        logging.getLogger("orbitrig.service").info("after the close")  # no handler of the log takes it
        service_log.close()  # as atexit does: no second stop of the thread, no error
    finally:
        root.handlers[:] = before
        root.setLevel(level)
    lines = log_file.read_text().splitlines()
    assert len(lines) == 1 and lines[0].endswith("INFO orbitrig.service: stopped by SIGTERM"), lines


def test_bad_log_options_are_a_usage_error(tmp_path):
    """Refused before the service starts anything: run in this process, 80 columns as piped."""
    bad_file = ("--log-file", str(tmp_path / "no" / "such" / "dir.log"))
    p = orbitrig_here("serve", "--broker", "mqtt://127.0.0.1:1", *bad_file, columns=80)
    assert p.returncode == 2 and "--log-file: cannot open" in p.stderr and "Traceback" not in p.stderr, p.stderr
    p = orbitrig_here("serve", "--broker", "mqtt://127.0.0.1:1", "--log-max-mb", "0", columns=80)
    assert p.returncode == 2 and "--log-max-mb 0" in p.stderr, p.stderr


@pytest.mark.parametrize(
    "options, says",
    [
        (("--rig-id", "a/b"), "--rig-id: "),  # the first check of the broker's options
        (("--confirm", "auto"), "--confirm auto only with --sim"),  # a run's options, checked last
        (("--matrices", "pyproject.toml"), "matrix folder: a file, not a folder"),
    ],
)
def test_a_serve_refused_for_its_options_leaves_no_log_behind(tmp_path, options, says):
    log_file = tmp_path / "serve.log"
    root = logging.getLogger()
    before, level, active = list(root.handlers), root.level, service_logs._active
    p = orbitrig_here(
        "serve",
        "--broker",
        "mqtt://127.0.0.1:1",
        "--log-file",
        str(log_file),
        *options,
        env={"ORBITRIG_MQTT_PASSWORD": None},
    )
    assert p.returncode == 2 and f"orbitrig serve: error: {says}" in p.stderr, p.stderr
    assert not log_file.exists()
    assert (root.handlers, root.level, service_logs._active) == (before, level, active)
