"""Every command says a failure the same way (orbitrig.cli.failure): 'orbitrig COMMAND: error:
MESSAGE', or 'orbitrig COMMAND: error (PART): MESSAGE' naming the part that failed, with the
README's exit status. They said `error: ...` (sweep, export, init...), `orbitrig acquire: ...`
or `orbitrig drives status failed (config): ...`."""

from __future__ import annotations

import re

import pytest

from support.cli_helpers import orbitrig_here

#: (arguments, the command as said, the part, what the message holds); every one exits 2
CASES = [
    (("sweep", "--dry-run", "--config", "{tmp}/none.toml"), "sweep", None, "none.toml: no such file"),
    (("drives", "status", "--config", "{tmp}/none.toml"), "drives status", "config", "none.toml: no such file"),
    (("drives", "run", "--spin", "100", "--orbit", "50", "--spin-id", "0"), "drives run", None, "--spin-id 0"),
    (("acquire", "--adc", "socket://127.0.0.1:1", "--mode", "parallel"), "acquire", None, "--mode must be"),
    (("identify", "{tmp}/none.csv", "--model", "kc8"), "identify", None, "cannot read the file"),
    (("design", "--model", "kc8", "--spin", "1000", "--ratios", "x"), "design", None, "--ratios 'x'"),
    (("init", "{tmp}/a-file"), "init", None, "not a folder"),
    (("export", "{tmp}/a-file", "--format", "csv"), "export", None, "a-file"),
    (("reduce", "{tmp}/a-file", "--model", "kc8"), "reduce", None, "not a directory"),
    (("sim", "--speedup", "0"), "sim", None, "--speedup 0"),
    (("dashboard", "--http", "nowhere", "--broker", "mqtt://127.0.0.1:1"), "dashboard", None, "--http 'nowhere'"),
    (("serve", "--broker", "mqtt://127.0.0.1:1", "--config", "{tmp}/none.toml"), "serve", None, "none.toml"),
]


@pytest.mark.parametrize(("args", "command", "part", "says"), CASES, ids=[" ".join(c[0][:2]) for c in CASES])
def test_a_failure_is_said_as_orbitrig_command_error(tmp_path, args, command, part, says):
    (tmp_path / "a-file").write_text("not a folder\n")
    p = orbitrig_here(*(a.replace("{tmp}", str(tmp_path)) for a in args))
    assert p.returncode == 2, (p.stdout, p.stderr)
    head = f"orbitrig {command}: error{f' ({part})' if part else ''}: "
    lines = [ln for ln in p.stderr.splitlines() if ln.startswith(head)]
    assert len(lines) == 1 and says in lines[0], p.stderr
    assert not re.search(r"(?m)^error: |failed \(\w+\): |^orbitrig [\w ]+: (?!error)", p.stderr), p.stderr
    assert "Traceback" not in p.stderr
