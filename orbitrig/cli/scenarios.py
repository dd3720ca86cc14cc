"""The simulator's scenarios as the command line names them: a FILE or the NAME of a shipped one
(`scenario_file`; the names: `shipped_scenarios`), the default (`default_scenario`), the scenario a
run records (`scenario_of`) and the simulator's configuration of it (`sim_config_of`;
`sim_scenario`: sweep's and serve's --sim-config, given only with --sim: `needs_sim`). Light: a
dry run, and every --sim-config help, reads them with the simulator's sim.scenario_files and sim.config only (standard library,
no numpy), without loading the simulator or the rig's I/O."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from orbitrig.run.scenario import Scenario


def shipped_scenarios() -> tuple[str, ...]:
    """The shipped scenarios' names: the simulator's sim.scenario_files.scenario_names() (its DEFAULT_SCENARIO,
    then every sim/NAME.toml's NAME in its scenario folder, sorted). sim.scenario_files is standard
    library only: no numpy is loaded."""
    from sim.scenario_files import scenario_names

    return scenario_names()


def scenario_of(sim_config: Path | None) -> Scenario:
    """The scenario as a run records it (its file: ``--sim-config`` resolved, else the default's,
    and its TOML text), also a --sim calibration record's ``simulator`` and ``simulator_sha256``.
    BadParameter when the file cannot be read as text."""
    path = scenario_file(sim_config)
    if path is None:
        return default_scenario()
    try:
        return Scenario(str(path), path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as err:
        import typer

        raise typer.BadParameter(f"{path}: {err}", param_hint="--sim-config") from None


def sim_scenario(sim_config: Path | None) -> tuple[Any, Scenario]:
    """(the simulator's sim.config.SimConfig, None for its own default; the scenario as a run records
    it) of ``--sim-config`` (a FILE or a shipped NAME; None: the default scenario), parsed as the
    simulator reads it, nothing started: BadParameter naming the option when it cannot be read or parsed."""
    path = scenario_file(sim_config)
    if path is None:
        return None, default_scenario()  # the simulator's own default (sim.config.SimConfig())
    scenario = scenario_of(path)
    return sim_config_of(scenario, scenario.name), scenario


def sim_config_of(scenario: Scenario, where: str) -> Any:
    """The simulator's sim.config.SimConfig of `scenario`'s text, parsed as the simulator reads it
    (nothing started): BadParameter naming --sim-config and `where` when it cannot be parsed."""
    from sim.scenario_files import sim_config_from_text  # parsing only

    try:
        return sim_config_from_text(scenario.text, where)
    except ValueError as err:
        import typer

        raise typer.BadParameter(str(err), param_hint="--sim-config") from None


def needs_sim(sim: bool, sim_config: Path | None) -> None:
    """BadParameter when --sim-config is given without --sim (sweep, serve, calibrate)."""
    if sim_config is not None and not sim:
        import typer

        raise typer.BadParameter("--sim-config needs --sim", param_hint="--sim-config")


def default_scenario() -> Scenario:
    """The default scenario as a run records it: its file and TOML text, as `--sim-config paper`
    gives them (one bearing in the catalog; the run names its rig whatever later defaults become):
    the simulator's sim.scenario_files.DEFAULT_SCENARIO (the paper's rig, config/sim.toml, equal to
    sim.config.SimConfig()), read when asked so that no command loads sim.config at its start."""
    from sim.scenario_files import DEFAULT_SCENARIO

    path = scenario_file(Path(DEFAULT_SCENARIO))
    assert path is not None
    return Scenario(str(path), path.read_text())


def scenario_file(path: Path | None, option: str = "--sim-config") -> Path | None:
    """A simulator scenario `option` (FILE, or the NAME of a shipped one: shipped_scenarios)."""
    if path is None or path.is_file() or path.suffix or len(path.parts) != 1:
        return path
    from sim.scenario_files import scenario_path

    try:
        return scenario_path(str(path))
    except ValueError as err:
        import typer

        raise typer.BadParameter(f"{path}: no such file; {err}", param_hint=option) from None
