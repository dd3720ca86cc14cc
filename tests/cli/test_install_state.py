"""tools/install_state.py: whether tools/run-tests may skip its `pip install -e ".[test,ross]"`.

Each case is a real source tree (pyproject.toml and its packages) and a real installed
distribution (a dist-info folder with METADATA, RECORD, direct_url.json and setuptools' editable
finder) in a temporary folder, read by importlib.metadata as pip's are; nothing is installed."""

from __future__ import annotations

import importlib.util
import json
import shutil
import tomllib
from importlib import metadata

from support.packages import PACKAGES
from support.paths import ROOT

spec = importlib.util.spec_from_file_location("install_state", ROOT / "tools" / "install_state.py")
assert spec is not None and spec.loader is not None
install_state = importlib.util.module_from_spec(spec)
spec.loader.exec_module(install_state)


def _tree(tmp_path, pyproject: str | None = None):
    """A source tree: this one's pyproject.toml (or ``pyproject``) and its packages, empty."""
    tree = tmp_path / "tree"
    for name in PACKAGES:
        (tree / name).mkdir(parents=True)
        (tree / name / "__init__.py").write_text("")
    (tree / "pyproject.toml").write_text(pyproject or (ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    return tree


def _installed(
    tmp_path, tree, *, url=None, editable=True, version=None, requires=None, packages=PACKAGES, scripts=None
):
    """orbitrig as `pip install -e TREE` leaves it in a site-packages folder (a real dist-info)."""
    project = tomllib.loads((tree / "pyproject.toml").read_text())["project"]
    scripts = project.get("scripts", {}) if scripts is None else scripts
    (info := tmp_path / "site" / "orbitrig-0.1.0.dist-info").mkdir(parents=True)
    (info / "entry_points.txt").write_text("[console_scripts]\n" + "".join(f"{k} = {v}\n" for k, v in scripts.items()))
    site = tmp_path / "site"
    if requires is None:
        requires = list(project["dependencies"])
        for extra, reqs in project["optional-dependencies"].items():
            requires += [f'{r.split("#")[0].strip()}; extra == "{extra}"' for r in reqs]
    lines = ["Metadata-Version: 2.4", "Name: orbitrig", f"Version: {version or project['version']}"]
    (info / "METADATA").write_text("\n".join(lines + [f"Requires-Dist: {r}" for r in requires]) + "\n")
    direct = {"url": url or tree.resolve().as_uri(), "dir_info": {"editable": editable}}
    (info / "direct_url.json").write_text(json.dumps(direct))
    finder = "__editable___orbitrig_0_1_0_finder.py"
    mapping = {name: str(tree.resolve() / name) for name in packages}
    (site / finder).write_text(f"import sys\nMAPPING: dict[str, str] = {mapping!r}\nNAMESPACES = {{}}\n")
    (info / "RECORD").write_text(f"{finder},,\norbitrig-0.1.0.dist-info/METADATA,,\n")
    return metadata.PathDistribution(info)


def test_an_editable_install_of_this_tree_as_pip_makes_it_needs_none(tmp_path):
    tree = _tree(tmp_path)
    dist = _installed(tmp_path, tree)
    assert install_state.install_needed(tree, dist, "test ross".split()) is None


def test_no_install_or_another_kind_of_install_needs_one(tmp_path):
    tree = _tree(tmp_path)
    assert install_state.install_needed(tree, None, []) == "orbitrig is not installed"
    dist = _installed(tmp_path, tree, editable=False)
    assert install_state.install_needed(tree, dist, []) == "orbitrig is installed, not editable"


def test_an_install_from_another_tree_needs_one(tmp_path):
    tree = _tree(tmp_path)
    dist = _installed(tmp_path, tree, url="file:///elsewhere/orbitrig")
    why = install_state.install_needed(tree, dist, [])
    assert why == "orbitrig is installed editable from file:///elsewhere/orbitrig, not from this tree"


def test_metadata_that_pyproject_no_longer_says_needs_one(tmp_path):
    tree = _tree(tmp_path)
    dist = _installed(tmp_path / "old-version", tree, version="0.0.9")
    assert install_state.install_needed(tree, dist, []) == "installed version 0.0.9, pyproject.toml's 0.1.0"
    dist = _installed(
        tmp_path / "old-packages", tree, packages=tuple(p for p in PACKAGES if p != "sim")
    )  # sim added since
    assert install_state.install_needed(tree, dist, []) == "the installed packages are not pyproject.toml's"
    dist = _installed(tmp_path / "current", tree)
    text = (tree / "pyproject.toml").read_text()
    (tree / "pyproject.toml").write_text(text.replace('"numpy>=1.26",', '"numpy>=2.0",', 1))  # a requirement raised
    assert install_state.install_needed(tree, dist, []) == "the installed requirements are not pyproject.toml's"


def test_a_requirement_not_installed_needs_one(tmp_path):
    """The metadata match, but a requirement of an extra asked for is not in the environment."""
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    tree = _tree(tmp_path, text.replace("test = [\n", 'test = [\n    "no-such-project-here>=1",\n', 1))
    dist = _installed(tmp_path, tree)
    assert install_state.install_needed(tree, dist, []) is None  # not asked for: not needed
    assert install_state.install_needed(tree, dist, "test".split()) == "no-such-project-here is not installed"


def test_a_command_pyproject_toml_adds_or_changes_needs_one(tmp_path):
    """[project.scripts] makes the `orbitrig` command on install: one added or pointed elsewhere since
    is made only by installing again."""
    tree = _tree(tmp_path)
    dist = _installed(tmp_path / "old-command", tree, scripts={"orbitrig": "orbitrig.cli:main"})
    why = install_state.install_needed(tree, dist, [])
    assert why == "the installed commands are not pyproject.toml's [project.scripts]"
    dist = _installed(tmp_path / "current", tree)
    assert install_state.install_needed(tree, dist, []) is None


def _project(site, name: str, version: str, requires=()) -> None:
    """A project installed in ``site`` (its dist-info: METADATA alone), as importlib.metadata finds it."""
    info = site / f"{name.replace('-', '_')}-{version}.dist-info"
    info.mkdir(parents=True)
    lines = [
        "Metadata-Version: 2.4",
        f"Name: {name}",
        f"Version: {version}",
        *(f"Requires-Dist: {r}" for r in requires),
    ]
    (info / "METADATA").write_text("\n".join(lines) + "\n")


def test_what_a_requirement_requires_in_turn_is_checked_extras_included(tmp_path, monkeypatch):
    """pip installs what each requirement requires too, with the extras it names (psycopg[binary]:
    psycopg-binary): one missing, or at a version refused, needs the install although every
    requirement pyproject.toml names directly is there."""
    site = tmp_path / "deps"
    _project(site, "lib-a", "1.0", ["lib-b>=2", 'lib-c; extra == "fast"', 'lib-d; python_version < "3"'])
    _project(site, "lib-b", "1.5")
    _project(site, "lib-c", "0.1")
    monkeypatch.syspath_prepend(str(site))
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    tree = _tree(tmp_path, text.replace("test = [\n", 'test = [\n    "lib-a[fast]>=1",\n', 1))
    dist = _installed(tmp_path, tree)
    assert install_state.install_needed(tree, dist, []) is None  # the extra not asked for
    assert install_state.install_needed(tree, dist, ["test"]) == "lib-b 1.5 is installed, lib-b>=2 wanted (by lib-a)"
    shutil.rmtree(site / "lib_b-1.5.dist-info")
    _project(site, "lib-b", "2.1")
    shutil.rmtree(site / "lib_c-0.1.dist-info")
    assert install_state.install_needed(tree, dist, ["test"]) == "lib-c is not installed (lib-a[fast] requires it)"
    _project(site, "lib-c", "0.1")
    assert install_state.install_needed(tree, dist, ["test"]) is None  # lib-d: not for this Python
