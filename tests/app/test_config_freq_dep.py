"""A matrix's freq_dep is checked against the identification's own limits when the file
is loaded, naming file, line, key and what is allowed (never first met mid-run)."""

import pytest

from orbitrig import config as cfg
from orbitrig.errors import ConfigError
from reduction.models import MAX_ORDER, parse_freq_dep

MATRIX = """name = "fd"
[operating]
spin_rpm = [1000.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.4]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.096]
[orbit]
ratios = [0.3, 0.5, 0.7]
[[models]]
model = "kc7"
freq_dep = "{fd}"
"""


@pytest.mark.parametrize(
    "fd",
    [f"power:{MAX_ORDER + 1}", f"poly:{MAX_ORDER + 4}", f"power:1,2,{MAX_ORDER + 1}", "none\n", "power:0", "poly:2,2"],
)
def test_freq_dep_beyond_the_identification_limits_is_a_config_error(tmp_path, fd):
    path = tmp_path / "m.toml"
    path.write_text(MATRIX.format(fd=fd.replace("\n", "\\n")))
    with pytest.raises(ConfigError) as info:
        cfg.load_matrix(path)
    text = str(info.value)
    assert str(path) in text and "line 12" in text and "models[0].freq_dep" in text
    assert f"integers 1..{MAX_ORDER}" in text


@pytest.mark.parametrize("fd", ["none", "power:auto", "power:2", "power:1,2,3", f"poly:{MAX_ORDER}"])
def test_every_spelling_the_identification_takes_loads(tmp_path, fd):
    path = tmp_path / "m.toml"
    path.write_text(MATRIX.format(fd=fd))
    m = cfg.load_matrix(path)
    assert m.models[0].freq_dep == fd and parse_freq_dep(fd).text == fd
