"""GNU Octave as the tests run it: one `octave-cli` start evaluating a script."""

from __future__ import annotations

import subprocess
from pathlib import Path


def octave_eval(script: str, cwd: Path, *, text: bool = True, timeout: float = 120) -> subprocess.CompletedProcess:
    """``octave-cli --no-gui --norc --eval SCRIPT`` in ``cwd``, its output captured (``text``
    False: as bytes, for a test that decodes UTF-8 itself)."""
    return subprocess.run(
        ["octave-cli", "--no-gui", "--norc", "--eval", script],
        capture_output=True,
        text=text,
        timeout=timeout,
        cwd=cwd,
    )
