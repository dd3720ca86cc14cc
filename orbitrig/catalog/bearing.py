"""Which bearing a run tested, as catalog columns: the rig (``rig_id``, and the journal
radius and radial clearance of the run's rig configuration) and, for a --sim run, the
simulator scenario (its name, the SHA-256 of its TOML text, its seed).

Rows of different bearings never repeat one another, however equal their operating
conditions: KEY_COLUMNS are what `compare` groups repeats by besides the conditions
(orbitrig.catalog.compare.bearing_key).

A number the catalog computes from written ones (the bearing's lengths in m, the planned orbit
frequencies) is kept without float noise (rigunits.without_noise: 6e-05 m, not
5.9999999999999995e-05; 5.0 Hz, not 4.999999999999999), as every file orbitrig writes keeps it.
"""

from __future__ import annotations

import hashlib
import tomllib
from typing import Any

from pydantic import ValidationError

from rigunits import micrometres, without_noise

from orbitrig.config import Bearing
from orbitrig.store.stored_run import Run, scenario_label

#: the simulator's seed when a scenario sets none (sim.config.SimConfig().seed)
SIM_DEFAULT_SEED = 1

#: the columns naming the bearing, beside rig_id (docs/catalog.md)
BEARING_COLUMNS = ("bearing_radius", "bearing_clearance", "sim_scenario", "sim_scenario_sha256", "sim_seed")


def bearing_columns(run: Run) -> dict[str, Any]:
    """The run's bearing columns: radius and clearance in m (None when the stored rig
    configuration cannot be read), and the scenario's name, text SHA-256 and seed ("" and
    None for a run on the rig)."""
    bearing = _rig_bearing(run.rig_config)
    columns: dict[str, Any] = {
        "bearing_radius": without_noise(bearing.radius_mm * 1e-3) if bearing else None,
        "bearing_clearance": without_noise(bearing.clearance) if bearing else None,
        "sim_scenario": "",
        "sim_scenario_sha256": "",
        "sim_seed": None,
    }
    if run.sim:
        text = run.sim_scenario_config
        columns.update(
            sim_scenario=run.sim_scenario_name,
            sim_scenario_sha256=hashlib.sha256(text.encode()).hexdigest(),
            sim_seed=_seed(text),
        )
    return columns


#: the columns that tell one bearing from another, beside rig_id: the scenario by its text's
#: SHA-256, not by its name (a path, which another machine spells otherwise); the seed is in the text
KEY_COLUMNS = ("bearing_radius", "bearing_clearance", "sim_scenario_sha256")


def bearing_label(row: dict[str, Any]) -> str:
    """A short name of the row's bearing: `sim NAME` (the scenario file's stem; `paper` for the
    shipped sim.toml, the default scenario; an older run's default by its name's first word) or
    the rig id with the clearance (`SAC-DS-1 c = 60 µm`, rigunits.micrometres), made when shown
    from the stored clearance (m): no catalog stores the label."""
    scenario = row.get("sim_scenario") or ""
    if scenario:
        return "sim " + scenario_label(scenario)
    clearance = row.get("bearing_clearance")
    return (row.get("rig_id") or "rig") + (f" c = {micrometres(clearance, '.4g')}" if clearance else "")


def _rig_bearing(text: str) -> Bearing | None:
    """The [bearing] of a stored rig configuration (its defaults where it sets none; None
    when the run stores none or it cannot be read)."""
    if not text.strip():
        return None
    try:
        return Bearing.model_validate(tomllib.loads(text).get("bearing", {}))
    except (tomllib.TOMLDecodeError, ValidationError, AttributeError):
        return None


def _seed(text: str) -> int | None:
    """The seed a scenario's TOML text sets (the simulator's default when none; None unreadable)."""
    try:
        seed = tomllib.loads(text).get("seed", SIM_DEFAULT_SEED)
    except tomllib.TOMLDecodeError:
        return None
    return seed if isinstance(seed, int) and not isinstance(seed, bool) else None
