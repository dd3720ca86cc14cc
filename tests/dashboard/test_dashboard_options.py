"""`orbitrig dashboard` refuses a time option out of range before it serves anything (exit 2,
naming the option): `--idle-timeout nan` or `--reply-timeout inf` were taken, a session that
never ends and a reply waited for forever. A --tls-ca that is a folder is said to be one (it was
"no such file")."""

from __future__ import annotations

import pytest

from support.cli_helpers import orbitrig


@pytest.mark.parametrize(
    "args, message",
    [
        (("--idle-timeout", "nan"), "--idle-timeout nan: a finite number of seconds > 0"),
        (("--idle-timeout", "0"), "--idle-timeout 0: a finite number of seconds > 0"),
        (("--reply-timeout", "inf"), "--reply-timeout inf: a finite number of seconds > 0"),
        (("--tick", "-1"), "--tick must be > 0 and at most 60 s"),
    ],
)
def test_a_time_out_of_range_exits_2_naming_the_option(args, message):
    p = orbitrig("dashboard", "--broker", "mqtt://127.0.0.1:1", "--http", "127.0.0.1:0", *args, timeout=60)
    assert p.returncode == 2, p.stderr
    assert f"orbitrig dashboard: error: {message}" in p.stderr and "Traceback" not in p.stderr and p.stdout == ""


def test_a_tls_ca_that_is_a_folder_is_said_to_be_one(tmp_path):
    p = orbitrig("dashboard", "--broker", "mqtts://127.0.0.1:1", "--tls-ca", str(tmp_path), timeout=60)
    assert p.returncode == 2 and p.stderr == f"orbitrig dashboard: error: --tls-ca: a folder, not a file: {tmp_path}\n"
