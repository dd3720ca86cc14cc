"""Simulator configuration files: a SimConfig read from TOML (text, a file, or plain data), and
the shipped scenarios by name (config/sim.toml, config/sim/NAME.toml; an installed wheel's
sim/scenarios). Standard library only (no numpy): the command line lists the scenarios with it.

In a TOML file a key may carry an edge unit as a suffix, converted on load: ``_deg`` (degrees ->
rad), ``_um`` (micrometres -> m), ``_mpa`` (MPa -> Pa), ``_kpa`` (kPa -> Pa), ``_degc`` (degC ->
K). Example: ``trigger_phase_deg = 20`` sets ``AdcConfig.trigger_phase`` to 0.349 rad. See
config/sim.toml.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

from sim.config import (
    AdcConfig,
    BearingConfig,
    CanConfig,
    ChainConfig,
    DrivesConfig,
    GeometryConfig,
    LmsConfig,
    NoiseConfig,
    SimConfig,
    SupplyConfig,
)


_SUFFIXES = {
    "_deg": lambda v: math.radians(v),
    "_um": lambda v: v * 1e-6,
    "_mpa": lambda v: v * 1e6,
    "_kpa": lambda v: v * 1e3,
    "_degc": lambda v: v + 273.15,
}


def _convert(value, fn):
    if isinstance(value, list):
        return [_convert(v, fn) for v in value]
    return fn(value)


def _to_field_type(value):
    if isinstance(value, list):
        return tuple(_to_field_type(v) for v in value)
    return value


def _section(cls, table: dict, where: str, problems: list[str]):
    names = {f.name: f for f in dataclasses.fields(cls)}
    kwargs = {}
    for key, value in table.items():
        name, fn = key, None
        if key not in names:
            for suffix, conv in _SUFFIXES.items():
                if key.endswith(suffix) and key[: -len(suffix)] in names:
                    name, fn = key[: -len(suffix)], conv
                    break
            else:
                problems.append(f"unknown key '{where}{key}'")
                continue
        try:
            kwargs[name] = _to_field_type(_convert(value, fn) if fn else value)
        except TypeError:
            problems.append(f"key '{where}{key}': expected numbers, got {value!r}")
    return kwargs


# config/ of the source tree; an installed wheel carries sim.toml and sim/ as sim/scenarios
_SHIPPED = Path(__file__).resolve().parent / "scenarios"
SCENARIO_DIR = _SHIPPED if (_SHIPPED / "sim.toml").is_file() else Path(__file__).resolve().parents[1] / "config"
#: the name of the default scenario, SCENARIO_DIR/sim.toml (the paper's rig); every other shipped
#: scenario is SCENARIO_DIR/sim/NAME.toml
DEFAULT_SCENARIO = "paper"


def scenario(name: str) -> SimConfig:
    """A shipped scenario by name (scenario_path). ValueError naming the known ones."""
    return load_sim_config(scenario_path(name))


def scenario_names() -> tuple[str, ...]:
    """The shipped scenarios' names, as their files in SCENARIO_DIR give them: DEFAULT_SCENARIO
    (sim.toml), then every sim/NAME.toml's NAME, sorted."""
    return (DEFAULT_SCENARIO, *sorted(p.stem for p in (SCENARIO_DIR / "sim").glob("*.toml")))


def scenario_path(name: str) -> Path:
    """A shipped scenario's file by its name (scenario_names): DEFAULT_SCENARIO is sim.toml (the
    default rig), any other config/sim/NAME.toml. ValueError naming the known ones."""
    path = SCENARIO_DIR / "sim.toml" if name == DEFAULT_SCENARIO else SCENARIO_DIR / "sim" / f"{name}.toml"
    if not path.is_file():
        raise ValueError(f"unknown simulator scenario {name!r}; known: {', '.join(scenario_names())}")
    return path


def load_sim_config(path: str | Path) -> SimConfig:
    """Read a SimConfig from TOML. Raises ValueError naming the file and key."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as err:
        raise ValueError(f"{path}: {err}") from err
    return sim_config_from_text(text, str(path))


def sim_config_from_text(text: str, source: str = "<text>") -> SimConfig:
    """A SimConfig from TOML text (as a scenario file; "" is the default rig). ValueError
    naming `source` and the key."""
    if text.startswith("\ufeff"):  # TOML forbids it; its parser would say "Invalid statement" of an invisible character
        raise ValueError(f"{source}: line 1: starts with a byte order mark (BOM), which TOML does not allow")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ValueError(f"{source}: {err}") from err
    except RecursionError:  # the parser recurses per level of nesting
        raise ValueError(f"{source}: not valid TOML: arrays or tables nested too deeply") from None
    return sim_config_from_data(data, source)


def sim_config_to_data(cfg: SimConfig) -> dict:
    """A SimConfig as plain data (SI field names, lists; JSON-ready): sim_config_from_data
    makes the same SimConfig of it (how the simulator process receives its scenario)."""
    return dataclasses.asdict(cfg)


def sim_config_from_data(data: dict, source: str = "<data>") -> SimConfig:
    """A SimConfig from parsed TOML or from sim_config_to_data. ValueError naming `source` and the key."""
    path = source
    problems: list[str] = []
    classes = {
        "bearing": BearingConfig,
        "geometry": GeometryConfig,
        "adc": AdcConfig,
        "lms": LmsConfig,
        "chain": ChainConfig,
        "noise": NoiseConfig,
        "supply": SupplyConfig,
        "drives": DrivesConfig,
        "can": CanConfig,
    }
    kwargs = {}
    for key, value in data.items():
        if key in classes:
            if not isinstance(value, dict):
                problems.append(f"'{key}' must be a table")
                continue
            kwargs[key] = classes[key](**_section(classes[key], value, f"{key}.", problems))
        elif key in ("speedup", "seed"):
            kwargs[key] = value
        else:
            problems.append(f"unknown key '{key}'")
    if problems:
        raise ValueError(f"{path}: " + "; ".join(problems))
    try:
        return SimConfig(**kwargs)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{path}: {err}") from err
