"""Configuration files: the shipped ones load; a bad one names every problem."""

import math
import re

import pytest

from orbitrig import config as cfg
from orbitrig.errors import ConfigError


def test_shipped_rig_config_matches_the_channel_map():
    rig = cfg.load_rig()
    assert [c.name for c in rig.ordered_channels] == list(cfg.CHANNEL_NAMES)
    assert rig.gains == [0.1] * 4 + [5e-9] * 4
    assert rig.offsets == [0.0] * 8
    assert rig.bearing.clearance == pytest.approx(60e-6)
    assert rig.averaging.revolutions == 50
    assert rig.max_spin == pytest.approx(2500 * 2 * math.pi / 60)


def test_paper_matrix_is_the_papers():
    m = cfg.load_matrix(cfg.default_matrix_path("paper"))
    op = m.operating
    assert op.spin_rpm == [1000, 2000]
    assert op.recess_pressure_mpa == [0.4826, 1.0342]
    assert op.pressure_ratio == [0.25, 0.4, 0.55]
    assert op.static_eccentricity == [0.0, 0.15, 0.3]
    assert op.dynamic_eccentricity == [0.04, 0.096, 0.15]
    r = m.orbit.ratio_list
    assert len(r) == 10 and r[0] == pytest.approx(0.2) and r[-1] == pytest.approx(1.2)
    assert m.orbit.directions == ["forward", "backward"]
    assert {(s.model, s.freq_dep) for s in m.models} >= {("kc7", "none"), ("kcd11", "none"), ("kcd11", "power:1")}


BAD_MATRIX = """
name = "bad"
colour = "red"
[operating]
spin_rpm = [-5]
recess_pressure_mpa = [0.4]
pressure_ratio = [1.5]
static_eccentricity = [0]
[orbit]
ratios = [0.5]
directions = ["sideways"]
[[models]]
model = "kc9"
freq_dep = "power:x"
method = "foo"
"""


def test_bad_matrix_reports_every_problem_with_file_and_key(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(BAD_MATRIX)
    with pytest.raises(ConfigError) as ei:
        cfg.load_matrix(path)
    err = ei.value
    assert err.file == str(path)
    text = str(err)
    expected = {
        "operating.spin_rpm[0]": "greater than 0",
        "operating.pressure_ratio[0]": "less than 1",
        "operating.dynamic_eccentricity": "missing",
        "orbit.directions[0]": "'forward' or 'backward'",
        "models[0].model": "'kc7', 'kc8', 'kcd11' or 'kcd12'",
        "models[0].freq_dep": "power:M",
        "models[0].method": "'ols', 'wls', 'tls' or 'iv'",
        "colour": "allowed keys here: name, description, operating",
    }
    assert len(err.problems) == len(expected)
    for key, allowed in expected.items():
        line = next(p for p in err.problems if f"key '{key}'" in p)
        assert allowed in line
    for line in text.splitlines():
        assert re.match(rf"{re.escape(str(path))}: (line \d+: )?key '", line)  # line unless the key is absent


def test_bad_rig_config_names_keys(tmp_path):
    text = cfg.default_rig_path().read_text()
    text = text.replace("clearance_um = 60.0", "clearance_um = -1").replace('name = "y_b"', 'name = "y_c"')
    text = text.replace("[settle]", "[settle]\nhold = 3")
    path = tmp_path / "rig.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as ei:
        cfg.load_rig(path)
    probs = ei.value.problems
    assert any("key 'bearing.clearance_um'" in p and "greater than or equal to 1" in p for p in probs)
    assert any("key 'channels[7].name'" in p and "'fx_piezo'" in p for p in probs)
    assert any("key 'settle.hold'" in p and "allowed keys here: hold_s, timeout_s" in p for p in probs)


def test_toml_syntax_error_names_file_and_line(tmp_path):
    path = tmp_path / "m.toml"
    path.write_text("name = \n")
    with pytest.raises(ConfigError, match=r"m.toml: not valid TOML: .*line 1"):
        cfg.load_matrix(path)


def test_matrix_beyond_drive_limits(tmp_path):
    rig = cfg.load_rig()
    text = cfg.default_matrix_path("paper").read_text().replace("[1000.0, 2000.0]", "[1000.0, 2400.0]")
    path = tmp_path / "m.toml"
    path.write_text(text)
    m = cfg.load_matrix(path)
    with pytest.raises(ConfigError) as ei:
        cfg.check_matrix_against_rig(m, rig)
    assert len(ei.value.problems) == 1
    assert "2880 rpm orbit, above the rig's drives.max_orbit_rpm = 2500" in ei.value.problems[0]
