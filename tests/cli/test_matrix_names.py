"""The shipped test matrices' names have one owner, their folder: the --matrix help of sweep and of
design lists what the shipped configuration's matrices/ holds (orbitrig.config.home.shipped_config),
in the source tree and in an installed wheel's layout alike (a file added there is listed without a
line of code changed, as the --sim-config helps list the scenarios); the README names the same."""

from __future__ import annotations

import re
import shutil

import pytest
from typer.testing import CliRunner

import orbitrig.cli
from orbitrig.cli.config_help import shipped_matrices
from orbitrig.config.home import MATRICES, shipped_config
from support.paths import ROOT


def _listed(command: str) -> list[str]:
    """The names `orbitrig COMMAND --help` gives its --matrix, as one line."""
    out = CliRunner().invoke(orbitrig.cli.app, [command, "--help"], terminal_width=10_000).output
    flat = " ".join(out.split())
    found = re.search(r"matrices/,? (?:\(|as sweep --matrix takes it: )([a-z0-9_, -]+?)[);]", flat)
    assert found, flat
    return found.group(1).split(", ")


def test_every_matrix_help_lists_the_shipped_folder():
    files = sorted(p.stem for p in (shipped_config() / MATRICES).glob("*.toml"))
    assert {"demo", "paper", "designed", "eccentricity"} <= set(files)
    assert list(shipped_matrices()) == files
    assert _listed("sweep") == _listed("design") == files


@pytest.mark.parametrize("layout", ["source tree", "installed wheel"])
def test_a_matrix_file_added_is_named(tmp_path, layout):
    """A copy of the shipped configuration with one more matrix, beside the package (config/) or
    inside it as a wheel installs it (orbitrig/data/): its name is among the shipped ones."""
    package = tmp_path / "orbitrig"
    package.mkdir()
    config = tmp_path / "config" if layout == "source tree" else package / "data"
    config.mkdir()
    shutil.copyfile(ROOT / "config" / "rig.toml", config / "rig.toml")
    shutil.copytree(ROOT / "config" / "matrices", config / "matrices")
    (config / "matrices" / "b_added.toml").write_text("", encoding="utf-8")
    names = shipped_matrices(package)
    assert names[:2] == ("b_added", "demo") and names == tuple(sorted({*shipped_matrices(), "b_added"}))


def test_the_readme_names_every_shipped_matrix():
    flat = " ".join((ROOT / "README.md").read_text(encoding="utf-8").split())
    (listed,) = re.findall(r"`--matrix` takes a file or a name from `config/matrices/` \(([^:]+):", flat)
    assert listed == ", ".join(f"`{name}`" for name in shipped_matrices())
