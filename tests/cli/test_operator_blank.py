"""`--operator ""` (or blank) is refused (exit 2) naming the option, by `sweep` and every
`calibrate` step: it became the login name, recorded in the run or record as if given.

Real parts: the `orbitrig` command line (subprocesses)."""

from __future__ import annotations

import pytest

from support.cli_helpers import orbitrig


@pytest.mark.parametrize("blank", ["", "   "])
@pytest.mark.parametrize(
    "command", [("sweep", "--sim"), ("calibrate", "runout", "--sim"), ("calibrate", "loads", "--sim")]
)
def test_an_empty_operator_is_refused_naming_the_option(tmp_path, command, blank):
    out = tmp_path / "run"
    extra = ("--out", str(out)) if command[0] == "sweep" else ()
    p = orbitrig(*command, *extra, "--operator", blank)
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert "Invalid value for '--operator': an empty operator name" in p.stderr, p.stderr
    assert not out.exists()  # nothing was started or made
