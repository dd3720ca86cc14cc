"""Without a lab folder (no --config, $ORBITRIG_HOME or rig.toml in the current directory) the
commands that write configuration refuse, exit 2, before anything starts: the shipped defaults
(in a wheel, the package's own files, copied by every later `orbitrig init`) stay as shipped.
The commands run in the test's process (support.cli_helpers.orbitrig_here, $ORBITRIG_HOME unset
meanwhile): none of them starts a process or moves a drive here."""

from __future__ import annotations

import hashlib

from orbitrig.config import shipped_config

from support.cli_helpers import orbitrig_here


def _tree(folder) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


def _orbitrig(cwd, *args):
    return orbitrig_here(*args, cwd=cwd, columns=80, env={"ORBITRIG_HOME": None})


def test_calibrate_and_design_save_refuse_to_write_the_shipped_defaults(tmp_path):
    shipped = shipped_config()
    before = _tree(shipped)
    p = _orbitrig(tmp_path, "calibrate", "runout", "--sim", "--speedup", "40")
    assert p.returncode == 2, p.stderr
    assert f"{shipped / 'rig.toml'}: belongs to the defaults shipped with orbitrig" in p.stderr
    assert "orbitrig init DIR" in p.stderr and "ORBITRIG_HOME=DIR" in p.stderr
    p = _orbitrig(tmp_path, "design", "--model", "kc8", "--spin", "1000", "--save", "leftover")
    assert p.returncode == 2 and "belongs to the defaults shipped with orbitrig" in p.stderr
    p = _orbitrig(tmp_path, "calibrate", "list")  # reading them is fine
    assert p.returncode == 0 and "initial" in p.stdout
    assert _tree(shipped) == before


def test_a_lab_in_the_current_directory_takes_the_design(tmp_path):
    lab = tmp_path / "lab"
    assert _orbitrig(tmp_path, "init", str(lab)).returncode == 0
    p = _orbitrig(lab, "design", "--model", "kc8", "--spin", "1000", "--save", "mine")
    assert p.returncode == 0, p.stderr
    assert (lab / "designs" / "mine.toml").is_file()
