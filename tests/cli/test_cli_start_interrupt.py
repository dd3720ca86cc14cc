"""A Ctrl-C while `orbitrig` imports its command line (about a second, before any command runs)
ends it with a line saying so and exit 130, not a KeyboardInterrupt traceback; a SIGQUIT then
(Ctrl-\\) ends it as SIGTERM would, with a line and exit 131, not a core dump.

The interrupt is made to land inside that import (a meta-path hook raising KeyboardInterrupt when
`orbitrig.cli` is imported, as Python's SIGINT handler does at that moment): a real SIGINT lands
there only if it is sent within a window that moves with the host's load."""

import os
import signal
import subprocess
import sys
import time

from support.cli_helpers import orbitrig, orbitrig_started, reaped
from support.paths import ROOT

from orbitrig.__main__ import QUIT_STATUS

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


DRIVES_HELP_PROBE = """
import sys
import typer.main
import orbitrig.cli
for argv in (["drives", "--help"], ["drives", "status", "--help"], ["drives", "run", "--help"], ["drives", "stop", "--help"]):
    try:
        typer.main.get_command(orbitrig.cli.app)(argv, prog_name="orbitrig")
    except SystemExit:
        pass
heavy = ("numpy", "orbitrig.config", "orbitrig.cli.drives_run", "orbitrig.cli.drives_loop", "orbitrig.run.drive_setup")
print(sorted(m for m in sys.modules if m in heavy))
"""


def test_the_drives_helps_load_neither_the_run_nor_its_loop():
    """`orbitrig drives [status|run|stop] --help` are drawn from drives.py's commands alone: what
    `run` does once its options are read (drives_run), the event loop each command runs in
    (drives_loop), the rig's drives and configuration, numpy, are imported when a command runs."""
    done = subprocess.run(
        [sys.executable, "-c", DRIVES_HELP_PROBE], cwd=ROOT, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    *helps, loaded = done.stdout.splitlines()
    assert sum(line.startswith("Usage: orbitrig drives") for line in helps) == 4, done.stdout
    assert loaded == "[]"


def test_a_drives_command_does_not_load_scipy():
    """`orbitrig drives stop` reads the rig's configuration (its drive ids and limits), whose
    sequential-design checks import the reduction: scipy.linalg (about 0.25 s of a stop command's
    start) is imported only when a least-squares solve runs (reduction.regression)."""
    probe = "import sys, orbitrig.config, orbitrig.cli.drives; print(sorted({m.split('.')[0] for m in sys.modules} & {'scipy'}))"
    done = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def _catches(pid: int, sig: signal.Signals) -> bool:
    """Whether process `pid` has a handler of `sig` (its /proc status, SigCgt)."""
    with open(f"/proc/{pid}/status") as status:
        caught = next(line for line in status if line.startswith("SigCgt:")).split()[1]
    return bool(int(caught, 16) >> (sig - 1) & 1)


def test_sigquit_while_the_command_line_loads_ends_it_as_sigterm_would_without_a_core_dump():
    """A real SIGQUIT sent as soon as `orbitrig sweep --sim --dry-run` catches it (its /proc status),
    while it imports its command line or runs (neither installs a handler of its own): exit 131
    (128 + 3, as 143 for SIGTERM) with a line saying so, not death by SIGQUIT (a core dump)."""
    with reaped(orbitrig_started("sweep", "--sim", "--dry-run")) as child:
        deadline = time.monotonic() + 30
        while not _catches(child.pid, signal.SIGQUIT):
            assert child.poll() is None and time.monotonic() < deadline, "SIGQUIT never handled while it started"
            time.sleep(0.001)
        os.kill(child.pid, signal.SIGQUIT)
        out, err = child.communicate(timeout=60)
    assert child.returncode == QUIT_STATUS == 131, (child.returncode, err)
    assert err in (
        "orbitrig: SIGQUIT while starting; no command was run (no core dump)\n",
        "orbitrig: SIGQUIT; ended at once (no core dump)\n",
    ), err
    assert "ramp both drives to zero" not in out  # the dry run's plan: not printed, the process ended at once


def test_sigquit_ignored_at_start_stays_ignored():
    """Started with SIGQUIT, SIGHUP and Ctrl-Z (SIGTSTP) ignored (a background job of a script,
    nohup), the command line leaves them ignored, and the commands know it from one record
    (orbitrig.cli.signals.IGNORED_AT_START), saying the two of SIGNALS only (Ctrl-Z: nothing said)."""
    probe = (
        "import signal, sys; from orbitrig.__main__ import quit_handled; quit_handled();"
        "from orbitrig.cli import signals;"
        "print(sorted(s.name for s in signals.IGNORED_AT_START), signal.getsignal(signal.SIGQUIT) is signal.SIG_IGN);"
        "print(signals.ignored_words())"
    )

    def ignore() -> None:
        for sig in (signal.SIGQUIT, signal.SIGHUP, signal.SIGTSTP):
            signal.signal(sig, signal.SIG_IGN)

    done = subprocess.run(
        [sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=60, preexec_fn=ignore
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [
        "['SIGHUP', 'SIGQUIT', 'SIGTSTP'] True",
        "started with SIGHUP, SIGQUIT ignored (nohup, or a background job): left ignored "
        "(closing the terminal does not stop it)",
    ]
