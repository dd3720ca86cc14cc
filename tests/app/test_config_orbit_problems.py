"""The [orbit] table of a matrix names every one of its problems, not only the first."""

import pytest

from orbitrig import config as cfg
from orbitrig.errors import ConfigError

MATRIX = """name = "o"
[operating]
spin_rpm = [1000.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.4]
static_eccentricity = [0.0]
dynamic_eccentricity = [0.096]
[orbit]
{orbit}
[[models]]
model = "kc7"
"""


@pytest.mark.parametrize(
    "orbit, problems",
    [
        (
            'ratios = [0.3, 0.3]\ndirections = ["forward", "forward"]',
            ["'ratios' has repeated values", "'directions' has repeated values"],
        ),
        (
            "ratios = [0.3]\nratio_start = 1.2\nratio_stop = 0.2\ncount = 3",
            ["not both", "ratio_start must be smaller than ratio_stop"],
        ),
        ("ratio_stop = 1.2\ncount = 5", ["all of 'ratio_start', 'ratio_stop', 'count'"]),
    ],
)
def test_every_orbit_problem_is_named(tmp_path, orbit, problems):
    path = tmp_path / "m.toml"
    path.write_text(MATRIX.format(orbit=orbit))
    with pytest.raises(ConfigError) as info:
        cfg.load_matrix(path)
    text = str(info.value)
    assert str(path) in text and "line 8" in text and "key 'orbit'" in text
    for p in problems:
        assert p in text
