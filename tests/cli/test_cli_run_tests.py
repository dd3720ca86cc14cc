"""tools/run-tests: names missing system packages before any test runs, installs the
package with its test extras, then hands pytest's exit status through.

The system commands and the Python interpreter are stand-ins here (scripts in a temporary
PATH): the real ones would install packages on the machine running this test."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

from support.packages import PACKAGES
from support.paths import ROOT

SCRIPT = ROOT / "tools" / "run-tests"
COMMANDS = [
    "mosquitto",
    "mosquitto_pub",
    "mbpoll",
    "socat",
    "chromium",
    "chromedriver",
    "strace",
    "octave-cli",
    "pg_ctlcluster",
    "mkfs.ext4",
    "findmnt",
    "openssl",
    "git",
]


def _bin(tmp_path, commands):
    """A PATH directory with the script's own tools and stand-ins for ``commands``; no apt-get."""
    path = tmp_path / "bin"
    path.mkdir()
    for tool in ("dirname", "id", "env", "bash"):
        real = subprocess.run(["bash", "-c", f"command -v {tool}"], capture_output=True, text=True).stdout.strip()
        (path / tool).symlink_to(real)
    for name in commands:
        (path / name).write_text("#!/bin/sh\nexit 0\n")
        (path / name).chmod(0o755)
    return path


def _fake_python(tmp_path, pytest_status: int, installed: bool = False):
    """An interpreter that logs its arguments, fakes pip and pytest, says orbitrig is installed as
    pip would install it (tools/install_state.py) when ``installed``, and runs everything else."""
    log = tmp_path / "python.log"
    fake = tmp_path / "python"
    fake.write_text(
        "#!/bin/bash\n"
        f'echo "$*" >> {log}\n'
        'if [ "$1" = tools/install_state.py ]; then\n'
        + ("  exit 0\n" if installed else "  echo 'orbitrig is not installed'; exit 1\n")
        + "fi\n"
        'if [ "$1" = -m ] && [ "$2" = pip ]; then exit 0; fi\n'
        f'if [ "$1" = -m ] && [ "$2" = pytest ]; then exit {pytest_status}; fi\n'
        f'exec {sys.executable} "$@"\n'
    )
    fake.chmod(0o755)
    return fake, log


def _run(tmp_path, path_dir, python, *args):
    # /usr/sbin and /sbin are searched by the script itself; keep them out of this test's reach
    env = {"PATH": str(path_dir), "PYTHON": str(python), "HOME": str(tmp_path)}
    return subprocess.run(
        [str(path_dir / "bash"), str(SCRIPT), *args], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60
    )


def test_missing_system_packages_are_named_before_anything_runs(tmp_path):
    present = {"mosquitto", "socat"}
    python, log = _fake_python(tmp_path, 0)
    p = _run(tmp_path, _bin(tmp_path, present), python, "-q")
    assert p.returncode == 2, p.stderr
    package_of = {
        "mosquitto": "mosquitto",
        "mosquitto_pub": "mosquitto-clients",
        "mbpoll": "mbpoll",
        "socat": "socat",
        "chromium": "chromium",
        "chromedriver": "chromium-driver",
        "strace": "strace",
        "octave-cli": "octave",
        "pg_ctlcluster": "postgresql",
        "mkfs.ext4": "e2fsprogs",
        "findmnt": "util-linux",
        "openssl": "openssl",
        "git": "git",
    }
    on_sbin = {c for c in COMMANDS if os.path.exists(f"/usr/sbin/{c}") or os.path.exists(f"/sbin/{c}")}
    expected = {package_of[c] for c in COMMANDS if c not in present | on_sbin}  # the script also looks in sbin
    line = next(l for l in p.stderr.splitlines() if "apt-get install -y" in l)
    assert set(line.split("apt-get install -y", 1)[1].split()) == expected
    assert {"mbpoll", "chromium-driver", "openssl", "git"} <= expected  # the TLS tests' certificates, git ls-files
    assert "sudo apt-get update" in line
    logged = log.read_text() if log.exists() else ""
    assert "-m pip" not in logged and "-m pytest" not in logged  # nothing installed, no test run


def test_pytest_exit_status_passes_through_after_the_install(tmp_path):
    python, log = _fake_python(tmp_path, 5)
    p = _run(tmp_path, _bin(tmp_path, COMMANDS), python, "-q", "tests/daq")
    assert p.returncode == 5, p.stderr
    calls = [l for l in log.read_text().splitlines() if l.startswith("-m ")]
    assert calls[0].startswith("-m pip install") and calls[0].endswith("-e .[test,ross]")
    assert calls[1] == "-m compileall -q " + " ".join(PACKAGES)  # once, not per start; pyproject.toml's packages
    assert calls[2] == "-m pytest -n 4 --dist loadfile -q tests/daq"  # four workers by default (TEST_WORKERS)
    assert len(calls) == 3
    assert "tools/install_state.py test ross" in log.read_text().splitlines()  # asked first, for both extras
    assert "installing orbitrig with its test extras (orbitrig is not installed)" in p.stderr, p.stderr


def test_an_install_as_pip_would_make_it_is_not_made_again(tmp_path):
    """orbitrig installed editable from this tree as pyproject.toml says (tools/install_state.py,
    tests/cli/test_install_state.py): no pip install; the byte-compiling and pytest as always."""
    python, log = _fake_python(tmp_path, 0, installed=True)
    p = _run(tmp_path, _bin(tmp_path, COMMANDS), python, "-q", "tests/daq")
    assert p.returncode == 0, p.stderr
    calls = [l for l in log.read_text().splitlines() if l.startswith("-m ")]
    assert [c.split()[1] for c in calls] == ["compileall", "pytest"], calls
    assert "not installed again" in p.stderr, p.stderr


def test_ci_calls_the_same_command():
    text = (ROOT / ".ci" / "run").read_text()
    assert 'exec tools/run-tests "$@"' in text  # the README's command, as written
    assert os.access(SCRIPT, os.X_OK) and os.access(ROOT / ".ci" / "run", os.X_OK)


def _installing_bin(tmp_path, present):
    """`_bin` with ``present`` commands, an `id` that says root, an apt-get that installs every
    missing command (logging its arguments) and a `service` that logs what it is asked."""
    path = _bin(tmp_path, present)
    (path / "id").unlink()
    log = tmp_path / "system.log"
    stand_ins = {
        "id": "echo 0",
        "apt-get": f'echo "apt-get $*" >> {log}\nfor c in {" ".join(COMMANDS)}; do\n'
        f'  [ "$1" = install ] && [ ! -e {path}/$c ] && printf "#!/bin/sh\\nexit 0\\n" > {path}/$c && chmod 755 {path}/$c\n'
        "done; true",
        "service": f'echo "service $*" >> {log}',
    }
    for name, body in stand_ins.items():
        (path / name).write_text(f"#!/bin/bash\n{body}\n")
        (path / name).chmod(0o755)
    return path, log


def test_a_running_broker_is_left_alone_when_other_packages_are_installed(tmp_path):
    """Run as root, the script installs what is missing; it stops the broker a fresh mosquitto
    package starts, never one that was there before (on a rig's computer: the rig's broker)."""
    python, _ = _fake_python(tmp_path, 0)
    path, log = _installing_bin(tmp_path, {"mosquitto", "mosquitto_pub", "socat"})
    p = _run(tmp_path, path, python, "-q")
    assert p.returncode == 0, p.stderr
    calls = log.read_text().splitlines()
    install = next(c for c in calls if c.startswith("apt-get install"))
    assert "mbpoll" in install.split() and "mosquitto" not in install.split()
    assert not [c for c in calls if c.startswith("service")], calls


def test_a_machine_without_python3_gets_it_from_apt_first(tmp_path):
    """A fresh Debian has no python3 at all: run as root, the script installs it (with its venv)
    along with the rest, then installs orbitrig and runs pytest with it; not root, it names them."""
    python, log = _fake_python(tmp_path, 0)
    path, system = _installing_bin(tmp_path, set(COMMANDS))
    apt = path / "apt-get"
    apt.write_text(
        apt.read_text().replace(
            "done; true",
            f'done; [ "$1" = install ] && [[ " $* " == *" python3 "* ]] && {shutil.which("ln")} -sf {python} {path}/python3; true',
        )
    )
    env = {"PATH": str(path), "HOME": str(tmp_path)}  # no PYTHON: the default python3, not there yet
    p = subprocess.run(
        [str(path / "bash"), str(SCRIPT), "-q"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60
    )
    assert p.returncode == 0, p.stderr
    install = next(c for c in system.read_text().splitlines() if c.startswith("apt-get install"))
    assert {"python3", "python3-venv"} <= set(install.split()), install
    calls = [l for l in log.read_text().splitlines() if l.startswith("-m ")]
    assert calls[0].startswith("-m pip install") and calls[-1].startswith("-m pytest"), calls

    (path / "python3").unlink()
    (path / "id").write_text("#!/bin/sh\necho 1000\n")  # not root: nothing installed, both named
    p = subprocess.run(
        [str(path / "bash"), str(SCRIPT), "-q"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60
    )
    assert p.returncode == 2, p.stderr
    line = next(l for l in p.stderr.splitlines() if "apt-get install -y" in l)
    assert line.split("apt-get install -y", 1)[1].split() == ["python3", "python3-venv"], line
    assert "these commands: python3 (Python >= 3.11 with its venv module))" in p.stderr, p.stderr


#: programs the tests start that every Debian has (packages of priority required), so the script
#: installs nothing for them; python3 is the interpreter the script itself checks (and installs),
#: orbitrig the command it installs
ON_EVERY_DEBIAN = {"bash", "dd", "truncate", "stdbuf", "id", "chown", "mount", "umount", "useradd", "runuser"}
ON_EVERY_DEBIAN |= {"python3", "orbitrig"}
#: programs a package of the script's list brings besides the command it checks for
BROUGHT_ALONG = {"chattr": "e2fsprogs", "mosquitto_sub": "mosquitto-clients", "setpriv": "util-linux"}
#: words that open a list in the tests and happen to name a program on this machine
NOT_STARTED = {"reset", "size", "open"}


def _started_programs() -> dict[str, str]:
    """program -> a test file that starts it: the first word of a list (`["openssl", *args]`,
    `pub = ["mosquitto_pub", ...]`) that names a program on this machine, or a word the tests look
    for with shutil.which."""
    import re

    pattern = re.compile(r'\[\s*"([\w.+-]+)",|shutil\.which\("([\w.+-]+)"\)')
    found: dict[str, str] = {}
    for path in sorted((ROOT / "tests").rglob("*.py")):
        if path.name == Path(__file__).name:  # this file's lists are the script's stand-ins
            continue
        for m in pattern.finditer(path.read_text()):
            word = m.group(1) or m.group(2)
            if m.group(2) or shutil.which(word) or shutil.which(word, path="/usr/sbin:/sbin"):
                found.setdefault(word, str(path.relative_to(ROOT)))
    return {word: where for word, where in found.items() if word not in NOT_STARTED}


def test_every_program_the_tests_start_is_one_the_script_installs():
    """A fresh Debian lacks whatever is not of priority required: a program the tests start that is
    neither in the script's list nor on every Debian fails there (openssl and git were such). The
    scan sees the programs this machine has."""
    import re

    entries = re.findall(r'^\s+"([\w.+-]+):([\w.+-]+)"', SCRIPT.read_text(), re.M)
    packages, commands = {p for p, _ in entries}, {c for _, c in entries}
    started = _started_programs()
    assert {"mosquitto_pub", "mkfs.ext4", "chattr"} <= set(started), started  # the scan finds them
    missing = {
        program: where
        for program, where in started.items()
        if program not in commands | ON_EVERY_DEBIAN and BROUGHT_ALONG.get(program) not in packages
    }
    assert not missing, f"tests start these, which tools/run-tests does not install (add to PACKAGES): {missing}"
