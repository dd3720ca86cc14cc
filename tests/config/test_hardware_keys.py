"""A rig.toml the lab wrote must give every key of its rig's hardware (bearing, channel offsets,
transports, drive limits and ids, supply pressure band): one left out is refused naming the
file, its section's line, the key and what to add, not silently taken as the paper's rig's (a
clearance left out gave the orbit radius of the paper's 60 µm). `orbitrig init` writes every
one; the shipped defaults (--sim, the demo without a rig.toml) and a run's stored copy still load."""

from __future__ import annotations

import re

import pytest

from orbitrig import config as cfg
from orbitrig.config import CHANNEL_KEYS, HARDWARE_KEYS, ConfigError, load_rig, rig_from_text, write_lab
from orbitrig.config.home import HOME_ENV

from support.cli_helpers import orbitrig

RIG_TEXT = (cfg.shipped_config() / "rig.toml").read_text()
EVERY_KEY = [(section, key) for section, keys in HARDWARE_KEYS.items() for key in keys]


def _header_line(text: str, header: str) -> int:
    return next(n for n, line in enumerate(text.splitlines(), 1) if line.split("#")[0].strip() == header)


def _without(text: str, section: str, key: str) -> str:
    """``text`` without the line of ``key`` in [``section``]."""
    head = text.index(f"\n[{section}]")
    body_end = text.find("\n[", head + 1)
    body = text[head:body_end]
    cut, n = re.subn(rf"(?m)^{key}\s*=.*\n", "", body)
    assert n == 1, (section, key)
    return text[:head] + cut + text[body_end:]


@pytest.mark.parametrize(("section", "key"), EVERY_KEY, ids=[f"{s}.{k}" for s, k in EVERY_KEY])
def test_a_hardware_key_left_out_is_refused_naming_section_line_and_key(tmp_path, section, key):
    text = _without(RIG_TEXT, section, key)
    rig = tmp_path / "rig.toml"
    rig.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_rig(rig)
    (problem,) = info.value.problems
    paper = getattr(getattr(cfg.RigConfig.model_fields[section].default, key), "value", None)
    assert info.value.file == str(rig)
    assert problem.startswith(
        f"line {_header_line(text, f'[{section}]')}: key '{section}.{key}': missing from [{section}]: add {key} = ..., "
        f"this rig's {HARDWARE_KEYS[section][key]}; the paper's rig has {key} = "
    ), problem
    assert problem.endswith("and a key of the rig's hardware is never taken from it"), problem
    assert paper is None or str(paper) in problem


def test_the_clearance_left_out_is_not_the_papers_60_um(tmp_path):
    """The walkthrough's case: [bearing] without clearance_um ran with c = 60 µm, so the orbit
    radius asked for (eps_d x c) was the paper's bearing's, whatever this rig's is."""
    rig = tmp_path / "rig.toml"
    rig.write_text(_without(RIG_TEXT, "bearing", "clearance_um"))
    p = orbitrig("sweep", "--dry-run", "--config", str(rig), "--matrix", "demo", timeout=60)
    assert p.returncode == 2, p.stderr
    assert f"{rig}: line {_header_line(RIG_TEXT, '[bearing]')}: key 'bearing.clearance_um': missing" in p.stderr
    assert "radial clearance c (µm; the orbit radius asked for is eps_d x c)" in p.stderr
    assert "orbit radius" not in p.stdout and "Traceback" not in p.stderr


def test_a_section_left_out_and_a_channel_offset_left_out_are_each_named(tmp_path):
    text = re.sub(r"(?ms)^\[interlocks\].*?(?=^\[estimates\])", "", RIG_TEXT)
    fy_strain = text.index('name = "fy_strain"')
    text = text[:fy_strain] + text[fy_strain:].replace("offset = 0.0\n", "", 1)
    text = text.replace("max_spin_rpm = 2500.0", "max_spin_rpm = -1.0", 1)  # and a bad value: both said at once
    rig = tmp_path / "rig.toml"
    rig.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_rig(rig)
    problems = info.value.problems
    channel_header = [n for n, ln in enumerate(text.splitlines(), 1) if ln.startswith("[[channels]]")][3]
    assert problems[0].startswith(
        "key 'interlocks': no [interlocks] section: add it with this rig's supply_pressure_min_mpa, "
        "supply_pressure_max_mpa (the paper's rig has supply_pressure_min_mpa = 0.2, supply_pressure_max_mpa = 8.0"
    ), problems
    assert problems[1].startswith(
        f"line {channel_header}: key 'channels[3].offset': missing from [[channels]] fy_strain: add offset = ..., "
        f"this rig's {CHANNEL_KEYS['offset']}"
    ), problems
    assert any("key 'drives.max_spin_rpm'" in p for p in problems[2:]), problems


def test_init_writes_every_hardware_key_and_its_rig_toml_loads(tmp_path):
    write_lab(tmp_path / "lab")
    text = (tmp_path / "lab" / "rig.toml").read_text()
    for section, key in EVERY_KEY:
        head = text.index(f"\n[{section}]")
        assert re.search(rf"(?m)^{key}\s*=", text[head : text.find("\n[", head + 1)]), (section, key)
    assert text.count("[[channels]]") == text.count("\noffset = ") == 8
    rig = load_rig(tmp_path / "lab" / "rig.toml")
    assert rig.bearing.clearance_um == 60.0


def test_the_shipped_defaults_and_a_stored_copy_still_load(tmp_path, monkeypatch):
    """--sim without a rig.toml takes the shipped one, complete by definition; a run's stored rig
    configuration (rig_from_text, as resume and the analysis read it) is read as it was stored,
    so a run made before this rule stays readable."""
    assert load_rig(cfg.shipped_config() / "rig.toml").bearing.clearance_um == 60.0
    stored = rig_from_text(_without(RIG_TEXT, "bearing", "clearance_um"), "stored run:rig_config")
    assert stored.bearing.clearance_um == 60.0
    monkeypatch.delenv(HOME_ENV)  # no lab folder, none in the current one: the shipped defaults
    p = orbitrig("sweep", "--dry-run", "--sim", "--matrix", "demo", cwd=tmp_path, timeout=60)
    assert p.returncode == 0, p.stderr
    assert "missing" not in p.stderr
