"""Values of the wrong TOML type are refused, not converted (a string, a boolean or a float where
a number, a whole number or a boolean belongs), and an operating variable's list gives each value
once: each refusal names the file, the line and the key (the loader on the shipped files' text,
and the command line's dry run)."""

from __future__ import annotations

import pytest

from daq.adc_mode import AdcMode
from orbitrig import config as cfg
from orbitrig.errors import ConfigError

from support.cli_helpers import orbitrig

RIG_TEXT = (cfg.shipped_config() / "rig.toml").read_text()
DEMO_TEXT = (cfg.shipped_config() / "matrices" / "demo.toml").read_text()
PAPER_TEXT = (cfg.shipped_config() / "matrices" / "paper.toml").read_text()


def _line_no(text: str, startswith: str) -> int:
    return next(n for n, line in enumerate(text.splitlines(), 1) if line.strip().startswith(startswith))


def _one_problem(load, text: str) -> str:
    with pytest.raises(ConfigError) as info:
        load(text, "bad.toml")
    (problem,) = info.value.problems
    return problem


@pytest.mark.parametrize(
    "old, new, key, message",
    [
        ("gain = 0.1", 'gain = "0.1"', "channels[0].gain", "valid number (got '0.1')"),
        ("spin_id = 1", 'spin_id = "1"', "drives.spin_id", "valid integer (got '1')"),
        ("spin_id = 1", "spin_id = true", "drives.spin_id", "valid integer (got True)"),
        ("link_loss_polls = 3", "link_loss_polls = 3.0", "drives.link_loss_polls", "valid integer (got 3.0)"),
        (
            "check_supply_pressure = true",
            'check_supply_pressure = "yes"',
            "interlocks.check_supply_pressure",
            "boolean",
        ),
        ("check_supply_pressure = true", "check_supply_pressure = 1", "interlocks.check_supply_pressure", "boolean"),
        ("hold_s = 2.0", "hold_s = true", "settle.hold_s", "valid number (got True)"),
        (
            'adc_mode = "sequential"',
            'adc_mode = "parallel"',
            "transports.adc_mode",
            "Input should be 'sequential' or 'simultaneous' (got 'parallel')",
        ),
    ],
)
def test_a_rig_value_of_the_wrong_type_is_refused_naming_line_and_key(old, new, key, message):
    text = RIG_TEXT.replace(old, new, 1)
    assert text != RIG_TEXT
    problem = _one_problem(cfg.rig_from_text, text)
    assert problem.startswith(f"line {_line_no(text, new)}: key '{key}': ") and message in problem, problem


@pytest.mark.parametrize(
    "old, new, key",
    [
        ("spin_rpm = [1000.0]", 'spin_rpm = ["1000"]', "operating.spin_rpm[0]"),
        ("pressure_ratio = [0.4]", "pressure_ratio = [true]", "operating.pressure_ratio[0]"),
        ("ratios = [0.3,", 'ratios = ["0.3",', "orbit.ratios[0]"),
    ],
)
def test_a_matrix_value_of_the_wrong_type_is_refused_naming_line_and_key(old, new, key):
    text = DEMO_TEXT.replace(old, new, 1)
    assert text != DEMO_TEXT
    problem = _one_problem(cfg.matrix_from_text, text)
    assert problem.startswith(f"line {_line_no(text, new)}: key '{key}': Input should be a valid number"), problem


def test_integers_for_numbers_and_names_for_choices_still_load():
    """A TOML integer is a number (1000 for 1000.0); enums and literals are read from their names."""
    rig = cfg.rig_from_text(RIG_TEXT.replace("max_spin_rpm = 2500.0", "max_spin_rpm = 2500", 1), "rig.toml")
    assert rig.drives.max_spin_rpm == 2500.0 and isinstance(rig.drives.max_spin_rpm, float)
    text = DEMO_TEXT.replace("spin_rpm = [1000.0]", "spin_rpm = [1000]").replace(
        'name = "demo"', 'name = "demo"\norder = "written"', 1
    )
    matrix = cfg.matrix_from_text(text + '\n[[models]]\nmodel = "kc7"\nmethod = "wls"\n', "m.toml")
    assert matrix.operating.spin_rpm == [1000.0] and matrix.order == cfg.PointOrder.WRITTEN
    assert [str(d) for d in matrix.orbit.directions] == ["forward", "backward"] and matrix.models[-1].method == "wls"
    cfg.matrix_from_text(PAPER_TEXT, "paper.toml")


def test_the_adc_mode_is_read_from_its_word():
    text = RIG_TEXT.replace('adc_mode = "sequential"', 'adc_mode = "simultaneous"', 1)
    assert text != RIG_TEXT
    rig = cfg.rig_from_text(text, "rig.toml")
    assert rig.transports.adc_mode is AdcMode.SIMULTANEOUS
    assert rig.model_dump(mode="json")["transports"]["adc_mode"] == "simultaneous"


def test_a_static_offset_and_orbit_that_touch_the_bearing_are_refused():
    """eps_s c + eps_d c must stay inside the clearance c (the simulator refused it mid-run)."""
    ecc = (cfg.shipped_config() / "matrices" / "eccentricity.toml").read_text()
    cfg.matrix_from_text(ecc.replace("[0.0, 0.15, 0.3]", "[0.0, 0.15, 0.9]"), "ok.toml")  # 0.9 + 0.096 < 1
    text = ecc.replace("[0.0, 0.15, 0.3]", "[0.0, 0.15, 0.95]")
    problem = _one_problem(cfg.matrix_from_text, text)
    assert problem == (
        f"line {_line_no(text, '[operating]')}: key 'operating': static_eccentricity 0.95 + dynamic_eccentricity "
        "0.096 = 1.046: the journal would touch the bearing; their sum must stay below 1"
    )


@pytest.mark.parametrize(
    "key, values",
    [
        ("spin_rpm", "[1000.0, 1000.0]"),
        ("recess_pressure_mpa", "[0.4826, 1.0, 0.4826]"),
        ("pressure_ratio", "[0.4, 0.4]"),
        ("static_eccentricity", "[0.0, 0]"),
        ("dynamic_eccentricity", "[0.096, 0.096]"),
    ],
)
def test_an_operating_value_given_twice_is_refused_as_repeated_ratios_are(key, values):
    lines = [f"{key} = {values}" if line.startswith(f"{key} =") else line for line in DEMO_TEXT.splitlines()]
    text = "\n".join(lines)
    problem = _one_problem(cfg.matrix_from_text, text)
    assert problem.startswith(f"line {_line_no(text, key)}: key 'operating.{key}': '{key}' has repeated values"), (
        problem
    )


@pytest.mark.parametrize(
    "rig, matrix, says",
    [
        (("gain = 0.1", 'gain = "0.1"'), None, "key 'channels[0].gain'"),
        (("spin_id = 1", 'spin_id = "1"'), None, "key 'drives.spin_id'"),
        (
            ("check_supply_pressure = true", 'check_supply_pressure = "yes"'),
            None,
            "key 'interlocks.check_supply_pressure'",
        ),
        (None, ("spin_rpm = [1000.0]", 'spin_rpm = ["1000"]'), "key 'operating.spin_rpm[0]'"),
        (
            None,
            ("spin_rpm = [1000.0]", "spin_rpm = [1000.0, 1000.0]"),
            "key 'operating.spin_rpm': 'spin_rpm' has repeated",
        ),
    ],
)
def test_the_dry_run_exits_2_naming_file_line_and_key(tmp_path, rig, matrix, says):
    rig_text = RIG_TEXT.replace(*rig, 1) if rig else RIG_TEXT
    matrix_text = DEMO_TEXT.replace(*matrix, 1) if matrix else DEMO_TEXT
    (tmp_path / "rig.toml").write_text(rig_text)
    (tmp_path / "m.toml").write_text(matrix_text)
    bad, text, new = (tmp_path / "rig.toml", rig_text, rig[1]) if rig else (tmp_path / "m.toml", matrix_text, matrix[1])
    p = orbitrig(
        "sweep", "--sim", "--dry-run", "--config", str(tmp_path / "rig.toml"), "--matrix", str(tmp_path / "m.toml")
    )
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert f"error: {bad}: line {_line_no(text, new)}: {says}" in p.stderr


def _nth(text: str, old: str, new: str, n: int) -> str:
    """``text`` with the ``n``-th (0-based) ``old`` replaced by ``new``."""
    parts = text.split(old)
    assert len(parts) > n + 1, old
    return old.join(parts[: n + 1]) + new + old.join(parts[n + 1 :])


@pytest.mark.parametrize(
    "old, new, n, key, message",
    [
        (
            "index = 7",
            "index = 6",
            0,
            "channels[7].index",
            "index 6 (also channels[6]): indices must be 0..7, each once",
        ),
        ("index = 7", "index = 9", 0, "channels[7].index", "index 9: indices must be 0..7, each once"),
        ('name = "y_b"', 'name = "y_a"', 0, "channels[7].name", "channel y_a given twice (also channels[5])"),
        ('unit = "m"', 'unit = "N"', 1, "channels[5].unit", "channel y_a must have unit 'm'"),
    ],
)
def test_a_channel_map_problem_names_the_line_and_key_of_its_entry(old, new, n, key, message):
    """The channel map's checks (every channel once by name and index, its unit) name the entry's
    line and key, not '(top level)' without a line."""
    text = _nth(RIG_TEXT, old, new, n)
    with pytest.raises(ConfigError) as info:
        cfg.rig_from_text(text, "bad.toml")
    want = [i for i, line in enumerate(RIG_TEXT.splitlines(), 1) if line.startswith(old)][n]  # the edited line
    assert f"line {want}: key '{key}': {message}" in info.value.problems, info.value.problems


def test_missing_channels_name_the_line_of_the_channels_table(tmp_path):
    """'missing channels' concerns the whole [[channels]] array: it names the line of its first
    [[channels]] header (the lookup matched no [[channels]] header: no line at all)."""
    text = _nth(RIG_TEXT, 'name = "y_b"', 'name = "y_a"', 0)
    header = _line_no(RIG_TEXT, "[[channels]]")
    says = f"line {header}: key 'channels': missing channels ['y_b']; every one of "
    with pytest.raises(ConfigError) as info:
        cfg.rig_from_text(text, "bad.toml")
    assert any(p.startswith(says) for p in info.value.problems), info.value.problems
    (tmp_path / "rig.toml").write_text(text)
    p = orbitrig("sweep", "--sim", "--dry-run", "--config", str(tmp_path / "rig.toml"))
    assert p.returncode == 2 and f"{tmp_path / 'rig.toml'}: {says}" in p.stderr, p.stderr
