"""The lab configuration every test's commands find, and the `integration` mark.

Lab: the suite runs the simulator 40 times faster than the rig (so the command-line process
decodes 40 times the rig's A/D data) while tools/cpu-hog keeps both cores busy; there the
sweep's own process was seen answering a drive poll 0.37 s late. `pytest_configure` points
ORBITRIG_HOME at a lab folder as `orbitrig init` writes it, its rig.toml with a patient
drive link (support.rig_configs.patient_lab), so the commands a test starts without --config do
not lose the link to load. The shipped timing (0.15 s x 3 polls, 1 s drive watchdog) is
tested where it is the subject: tests/drives, with its own stated timings.

Marks the tests that start processes (a broker, a browser, a database server, the
command line, GNU Octave, mount ...) as ``integration``: ``-m "not integration"`` runs
the in-process rest, ``-m integration`` only these.

A test starts processes if its module's text, or a helper module it imports (of its folder
or of tests/support), names one of PROCESS_WORDS; or if it uses a fixture defined in such a
helper, or whose source names one or what it imports from such a helper (the broker).
"""

from __future__ import annotations

import functools
import inspect
import os
import re
import shutil
import sys
import tempfile
from pathlib import Path

import pytest

from rigthreads import one_blas_thread

one_blas_thread()  # as the orbitrig command computes: before numpy loads (orbitrig.config imports it)

from orbitrig.config.home import HOME_ENV  # noqa: E402

PROCESS_WORDS = re.compile(
    r"\b(subprocess|Popen|create_subprocess_exec|mosquitto|webdriver|chromium|pg_ctl|"
    r"octave|sys\.executable)\b"
)
# `from support.X import ...` (tests/support), `from .X import ...` (inside tests/support), `from X import ...`
_IMPORT = re.compile(
    r"^[ \t]*from[ \t]+(?:support\.|\.)?(\w+)[ \t]+import[ \t]+(\([^)]*\)|[\w \t,]+)"
    r"|^[ \t]*import[ \t]+(?:support\.)?(\w+)",
    re.MULTILINE,
)
SUPPORT = Path(__file__).resolve().parent / "support"  # the helpers the tests share


@functools.cache
def _names_a_process(path: Path) -> bool:
    return path.is_file() and bool(PROCESS_WORDS.search(path.read_text(encoding="utf-8")))


@functools.cache
def _process_names(module: Path) -> frozenset[str]:
    """The names `module` imports from helper modules (its folder's or tests/support's) that start processes."""
    names: set[str] = set()
    for source, imported, plain in _IMPORT.findall(module.read_text(encoding="utf-8")):
        name = f"{source or plain}.py"
        helper = module.parent / name if (module.parent / name).is_file() else SUPPORT / name
        if helper != module and _names_a_process(helper):
            names |= {n.strip() for n in imported.strip("()").split(",") if n.strip()} | {source or plain}
    return frozenset(names)


@functools.cache
def starts_processes(module: Path) -> bool:
    """True if the test module's own text, or a helper of its folder it imports, starts processes,
    or it names what its folder's conftest imports from such a helper (a fixture asked by name)."""
    conftest = module.parent / "conftest.py"
    named = _process_names(conftest) if conftest.is_file() else frozenset()
    words = set(re.findall(r"\w+", module.read_text(encoding="utf-8")))
    return _names_a_process(module) or bool(_process_names(module)) or bool(named & words)


@functools.cache
def _fixture_starts_processes(func: object) -> bool:
    try:
        source, path = inspect.getsource(func), Path(inspect.getfile(func))  # type: ignore[arg-type]
    except (OSError, TypeError):
        return False
    if path.resolve() == Path(__file__).resolve():
        return False
    if path.name != "conftest.py" and not path.name.startswith("test_") and _names_a_process(path):
        return True  # a fixture of a helper module that starts processes (the database server)
    words = set(re.findall(r"\w+", source))
    return bool(PROCESS_WORDS.search(source)) or bool(words & _process_names(path))


def pytest_configure(config: pytest.Config) -> None:
    from support.rig_configs import patient_lab

    lab = patient_lab(Path(tempfile.mkdtemp(prefix="orbitrig-test-lab-")))
    os.environ[HOME_ENV] = str(lab)
    config.add_cleanup(functools.partial(shutil.rmtree, lab, ignore_errors=True))


def _signals_not_ignored() -> None:
    """SIGINT, SIGQUIT and SIGHUP back to their defaults where this process was started with them
    ignored (a harness running the suite as a background job of a shell without job control, or
    under nohup): the commands the tests start inherit an ignored signal and leave it ignored, as
    orbitrig does (orbitrig.cli.signals.IGNORED_AT_START), and the tests send those signals."""
    import signal

    for sig in (signal.SIGINT, signal.SIGQUIT, signal.SIGHUP):
        if signal.getsignal(sig) is signal.SIG_IGN:
            signal.signal(sig, signal.default_int_handler if sig == signal.SIGINT else signal.SIG_DFL)


_signals_not_ignored()


@pytest.fixture(autouse=True)
def _signal_dispositions():
    """The test process's signal handlers back as they were: a command run in process leaves its
    signals recorded, not acted on (orbitrig.cli.signals.hand_over), and Ctrl-Z ignored, as for the
    rest of its process."""
    import signal

    from orbitrig.cli.signals import SIGNALS, SUSPEND

    before = {sig: signal.getsignal(sig) for sig in (*SIGNALS, SUSPEND)}
    yield
    for sig, handler in before.items():
        signal.signal(sig, handler)


@pytest.fixture(autouse=True)
def _root_log_handlers():
    """The root logger's handlers and level back as they were: a command run in this process
    (`orbitrig serve`, `orbitrig drives`) sets up its logging as its own process would, a handler
    writing to the test runner's captured stream, closed after it, at the service's level; a later
    test's log line would go there ('I/O operation on closed file')."""
    import logging

    root = logging.getLogger()
    before, level = list(root.handlers), root.level
    yield
    for handler in [h for h in root.handlers if h not in before]:
        root.removeHandler(handler)
    root.setLevel(level)


@pytest.fixture(autouse=True)
def _default_figure_style():
    """The figure style back to the default: a command run in process (`report --coverage 1`, say)
    sets the style of every later figure of its process (orbitrig.analysis.plots.use_style), as the
    orbitrig command does for its own process; a later test drawing figures must not inherit it."""
    yield
    plots = sys.modules.get("orbitrig.analysis.plots")
    if plots is not None and plots.STYLE != plots.FigureStyle():
        plots.use_style(plots.FigureStyle())


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        path = Path(str(item.fspath))
        defs = getattr(getattr(item, "_fixtureinfo", None), "name2fixturedefs", {})
        uses = any(
            _fixture_starts_processes(d.func) for name in getattr(item, "fixturenames", ()) for d in defs.get(name, ())
        )
        if uses or (path.suffix == ".py" and starts_processes(path)):
            item.add_marker(pytest.mark.integration)
