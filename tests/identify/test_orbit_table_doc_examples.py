"""docs/orbit-table.md's Examples run as written, from the source tree: each command's exit
status is the one its comment gives (0 without one), the JSON one prints the contract's object
(the example tables state their u_*), and the refused one says which coefficients the table
cannot separate."""

from __future__ import annotations

import json
import re
import shlex
import subprocess
import sys

from support.identify_keys import keys
from support.paths import ROOT


def _examples() -> list[tuple[str, int]]:
    """(command, exit status its comment gives) of the block after '## Examples'."""
    text = (ROOT / "docs" / "orbit-table.md").read_text(encoding="utf-8")
    block = re.search(r"```\n(.*?)```", text[text.index("## Examples") :], re.S)
    assert block, "docs/orbit-table.md: no block after ## Examples"
    out = []
    for line in block.group(1).splitlines():
        command, _, comment = line.partition("#")
        status = re.search(r"exit (\d)", comment)
        out.append((command.strip(), int(status.group(1)) if status else 0))
    return out


def test_the_examples_run_as_written():
    examples = _examples()
    assert len(examples) == 3
    for command, status in examples:
        words = shlex.split(command)
        assert words[:3] == ["python3", "-m", "orbitrig"], command
        p = subprocess.run([sys.executable, *words[1:]], cwd=ROOT, capture_output=True, text=True, timeout=120)
        assert p.returncode == status, f"{command}: {p.stderr[-1500:]}"
        if "--json" in words:
            d = json.loads(p.stdout)
            assert list(d) == keys(True) and d["units"]["Kxx"] == "N/m"
        elif status == 2:
            assert p.stdout == "" and "cannot be identified" in p.stderr and "Kxx_1 - Cxy" in p.stderr
        else:
            assert "Coefficients (Omega in rad/s)" in p.stdout and re.search(r"^Kxx .* MN/m$", p.stdout, flags=re.M)
