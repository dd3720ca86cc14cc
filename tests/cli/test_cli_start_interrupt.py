"""A Ctrl-C while `orbitrig` imports its command line (about a second, before any command runs)
ends it with a line saying so and exit 130, not a KeyboardInterrupt traceback.

The interrupt is made to land inside that import (a meta-path hook raising KeyboardInterrupt when
`orbitrig.cli` is imported, as Python's SIGINT handler does at that moment): a real SIGINT lands
there only if it is sent within a window that moves with the host's load."""

import subprocess
import sys

from support.cli_helpers import orbitrig
from support.paths import ROOT

INTERRUPTED_IMPORT = """
import sys

class CtrlC:
    def find_spec(self, name, path=None, target=None):
        if name == "orbitrig.cli":
            raise KeyboardInterrupt
        return None

sys.meta_path.insert(0, CtrlC())
sys.argv = ["orbitrig", "sweep", "--sim", "--dry-run"]
from orbitrig.__main__ import main
main()
"""


def test_ctrl_c_while_the_command_line_loads_says_so_and_exits_130():
    done = subprocess.run(
        [sys.executable, "-c", INTERRUPTED_IMPORT], cwd=ROOT, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 130, done.stderr
    assert done.stderr == "orbitrig: interrupted (Ctrl-C) while starting; no command was run\n"


def test_the_installed_command_and_python_m_start_the_same_way():
    """`orbitrig` (the console script, pyproject.toml) and `python -m orbitrig` both enter through
    orbitrig.__main__.main."""
    text = (ROOT / "pyproject.toml").read_text()
    assert 'orbitrig = "orbitrig.__main__:main"' in text
    done = orbitrig("--version", timeout=60)
    assert done.returncode == 0 and done.stdout.startswith("orbitrig "), done.stderr


def test_the_command_line_loads_without_numpy():
    """`orbitrig --help` and `--version` stay fast (bench/bench_startup.py: at most 0.6 x numpy +
    scipy.linalg): loading every command's module imports none of the heavy libraries (the
    reduction's Enums, plain Python, are read at registration); each command imports them when it runs."""
    probe = "import sys, orbitrig.cli; print(sorted(m for m in sys.modules if m.split('.')[0] in ('numpy', 'scipy', 'pandas', 'h5py', 'matplotlib', 'sqlalchemy')))"
    done = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_a_drives_command_does_not_load_scipy():
    """`orbitrig drives stop` reads the rig's configuration (its drive ids and limits), whose
    sequential-design checks import the reduction: scipy.linalg (about 0.25 s of a stop command's
    start) is imported only when a least-squares solve runs (reduction.regression)."""
    probe = "import sys, orbitrig.config, orbitrig.cli.drives; print(sorted({m.split('.')[0] for m in sys.modules} & {'scipy'}))"
    done = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"
