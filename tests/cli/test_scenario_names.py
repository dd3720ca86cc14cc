"""The shipped simulator scenarios' names have one owner, their folder, read by the simulator's
sim.scenario_files.scenario_names(): every --sim-config help lists what the folder holds (a file added
there is listed without a line of code changed), in the source tree and in an installed wheel's
layout alike, with no numpy loaded; the docs name the same ones."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from sim.scenario_files import scenario_names
from support.cli_helpers import child_env
from support.paths import ROOT

#: the commands with a --sim-config option, each as its --help is asked
COMMANDS = (("sim",), ("sweep",), ("serve",), *(("calibrate", step) for step in ("loads", "runout", "delay", "probes")))

PROBE = f"""
import json, sys
from typer.testing import CliRunner
import orbitrig.cli
helps = [" ".join(CliRunner().invoke(orbitrig.cli.app, [*c, "--help"], terminal_width=10_000).output.split())
         for c in {COMMANDS!r}]
numpy = "numpy" in sys.modules
import sim.scenario_files
print(json.dumps([list(sim.scenario_files.scenario_names()), helps, str(sim.scenario_files.SCENARIO_DIR), numpy]))
"""


def _seen_from(sim_root: Path) -> tuple[list[str], list[str], str, bool]:
    """(sim.scenario_files.scenario_names(), every --sim-config command's help in one line,
    sim.scenario_files.SCENARIO_DIR, numpy loaded by drawing the helps) of a process whose `sim` package
    is the one in `sim_root` (this tree's orbitrig)."""
    import json

    env = child_env({"PYTHONPATH": f"{sim_root}:{ROOT}"})
    done = subprocess.run(
        [sys.executable, "-c", PROBE], cwd=sim_root, env=env, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    return tuple(json.loads(done.stdout))  # type: ignore[return-value]


def _listed(help_text: str) -> list[str]:
    """The names a --sim-config help lists after "a shipped one by NAME:"."""
    found = re.search(r"a shipped one by NAME: ([a-z0-9_, -]+?) \(config/sim/\)", help_text)
    assert found, help_text
    return found.group(1).split(", ")


@pytest.mark.parametrize("layout", ["source tree", "installed wheel"])
def test_a_scenario_file_added_is_in_every_help_with_no_numpy_loaded(tmp_path, layout):
    """A copy of the simulator's package with one more scenario file, laid out as the source tree
    (config/sim.toml, config/sim/) or as a wheel installs it (sim/scenarios/): each command's
    --sim-config help lists the new name, in the order sim.scenario_files.scenario_names() gives, and
    drawing the help loads no numpy."""
    package = tmp_path / "sim"
    package.mkdir()
    for module in ("config.py", "scenario_files.py"):  # plain Python: its names
        shutil.copyfile(ROOT / "sim" / module, package / module)
    (package / "__init__.py").write_text("")
    folder = tmp_path / "config" if layout == "source tree" else package / "scenarios"
    shutil.copytree(ROOT / "config" / "sim", folder / "sim")
    shutil.copyfile(ROOT / "config" / "sim.toml", folder / "sim.toml")
    (folder / "sim" / "a_added.toml").write_text("[chain]\nenabled = false\n")
    simulator, helps, scenario_dir, numpy = _seen_from(tmp_path)
    assert Path(scenario_dir) == folder
    assert simulator[:2] == ["paper", "a_added"] and "clean" in simulator
    assert [_listed(h) for h in helps] == [simulator] * len(COMMANDS)
    assert not numpy


def test_the_docs_name_every_shipped_scenario():
    """README and docs/simulator.md list the shipped names where they say what NAME takes,
    docs/simulator.md's table has a row for every scenario file and the README's configuration
    table names each."""
    names = ", ".join(scenario_names())
    for page in (ROOT / "README.md", ROOT / "docs" / "simulator.md"):
        flat = " ".join(page.read_text(encoding="utf-8").split())
        lists = re.findall(r"a shipped one by NAME: ([a-z0-9_, -]+?) ?[();]", flat)
        assert lists and all(listed == names for listed in lists), (page.name, lists)
    table = (ROOT / "docs" / "simulator.md").read_text(encoding="utf-8")
    (row,) = [
        line
        for line in (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
        if "| `config/sim/*.toml` |" in line
    ]
    for path in (ROOT / "config" / "sim").glob("*.toml"):
        assert f"| `{path.relative_to(ROOT)}` |" in table
        assert f"`{path.stem}`" in row, row


def test_only_a_drawn_help_reads_the_scenario_folder():
    """`orbitrig --version` (as every command that draws no --sim-config help) does not import
    sim.scenario_files (nor sim.config) to name the scenarios; `orbitrig sweep --help` still names every one."""
    probe = (
        "import runpy, sys\ntry:\n    runpy.run_module('orbitrig', run_name='__main__')\nexcept SystemExit:\n    pass\n"
    )
    probe += "print('sim.config' in sys.modules or 'sim.scenario_files' in sys.modules, file=sys.stderr)"
    done = subprocess.run(
        [sys.executable, "-c", probe, "--version"], env=child_env(), capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0 and done.stderr.strip().splitlines()[-1] == "False", done.stdout + done.stderr
    helped = subprocess.run(
        [sys.executable, "-m", "orbitrig", "sweep", "--help"],
        env=child_env({"COLUMNS": "10000"}), capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert helped.returncode == 0, helped.stderr
    assert _listed(" ".join(helped.stdout.split())) == list(scenario_names())


@pytest.mark.parametrize("command", COMMANDS)
def test_a_help_asked_of_the_command_itself_names_the_scenarios(command):
    """A command's help drawn by its own get_help (as a documentation tool or a shell's completion
    asks it, no --help parsed by its group) names the shipped scenarios, not a placeholder."""
    import typer.core
    import typer.main

    import orbitrig.cli

    found = typer.main.get_command(orbitrig.cli.app)
    ctx = typer.Context(found, info_name="orbitrig")
    for name in command:
        assert isinstance(found, typer.core.TyperGroup)
        found = found.get_command(ctx, name)
        ctx = typer.Context(found, parent=ctx, info_name=name)
    assert _listed(" ".join(found.get_help(ctx).split())) == list(scenario_names())
