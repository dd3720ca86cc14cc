#!/usr/bin/env python3
"""Is orbitrig installed as tools/run-tests would install it, so that its `pip install` can be skipped?

    python tools/install_state.py [EXTRA ...]      # exit 0: installed as pip would; 1: install (the reason said)

Installed as pip would means, for the interpreter running this: orbitrig installed editable from
this source tree (its direct_url.json), with this tree's pyproject.toml version, requirements
(Requires-Dist, every extra's) and top-level packages (the editable finder's mapping), and every
requirement of the package and of each EXTRA installed at a version it allows. Anything else, or
anything that cannot be read (a fresh machine: no orbitrig, no `packaging`), says install.
Standard library only, and `packaging` where installed (pip's own dependency).
"""

from __future__ import annotations

import json
import re
import sys
import tomllib
from importlib import metadata
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _name(requirement: str) -> str:
    """A requirement's project name, normalised (PEP 503)."""
    return re.sub(r"[-_.]+", "-", re.split(r"[\s\[<>=!~;]", requirement.strip(), maxsplit=1)[0]).lower()


def wanted_requirements(project: dict) -> set[str]:
    """Requires-Dist as pip writes it from pyproject.toml's [project]: the dependencies, and each
    extra's with `; extra == "NAME"`, spaces dropped (the comparison's form)."""
    out = {r for r in project.get("dependencies", [])}
    for extra, reqs in project.get("optional-dependencies", {}).items():
        out |= {f'{r}; extra == "{extra}"' for r in reqs}
    return {_canonical(r) for r in out}


def _canonical(requirement: str) -> str:
    """A requirement without spaces, its version specifiers sorted (pip writes `<3.17,>=3.16`)."""
    text = requirement.replace(" ", "").replace("'", '"')
    head, _, marker = text.partition(";")
    m = re.match(r"([^<>=!~]+)(.*)", head)
    assert m is not None
    specs = ",".join(sorted(s for s in m.group(2).split(",") if s))
    return m.group(1).lower().replace("_", "-") + specs + (";" + marker if marker else "")


def _packages(project_root: Path) -> set[str]:
    """The top-level packages pyproject.toml's include patterns find in the tree."""
    config = tomllib.loads((project_root / "pyproject.toml").read_text(encoding="utf-8"))
    patterns = config["tool"]["setuptools"]["packages"]["find"]["include"]
    names = {p.rstrip("*") for p in patterns}
    return {n for n in names if (project_root / n / "__init__.py").is_file()}


def _finder_mapping(dist: metadata.Distribution) -> dict[str, str] | None:
    """The editable install's {package: folder} (setuptools' __editable___*_finder.py), None without one."""
    for f in dist.files or ():
        if f.name.startswith("__editable__") and f.name.endswith("_finder.py"):
            m = re.search(r"^MAPPING[^=]*=\s*(\{.*?\})\s*$", Path(str(f.locate())).read_text(), re.M)
            return json.loads(m.group(1).replace("'", '"')) if m else None
    return None


def install_needed(project_root: Path, dist: metadata.Distribution | None, extras: list[str]) -> str | None:
    """Why `pip install -e .[EXTRAS]` is needed in the environment ``dist`` (the installed orbitrig,
    None: not installed) belongs to; None when it is installed exactly as that install would."""
    if dist is None:
        return "orbitrig is not installed"
    direct = json.loads(dist.read_text("direct_url.json") or "{}")
    if not direct.get("dir_info", {}).get("editable"):
        return "orbitrig is installed, not editable"
    if direct.get("url") != project_root.resolve().as_uri():
        return f"orbitrig is installed editable from {direct.get('url')}, not from this tree"
    project = tomllib.loads((project_root / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    if dist.version != project["version"]:
        return f"installed version {dist.version}, pyproject.toml's {project['version']}"
    if {_canonical(r) for r in dist.requires or ()} != wanted_requirements(project):
        return "the installed requirements are not pyproject.toml's"
    mapping = _finder_mapping(dist)
    if mapping is None or set(mapping) != _packages(project_root):
        return "the installed packages are not pyproject.toml's"
    if any(Path(folder) != project_root.resolve() / name for name, folder in mapping.items()):
        return "the installed packages are another tree's"
    return _unmet(project, extras)


def _unmet(project: dict, extras: list[str]) -> str | None:
    """The first requirement of the package or of ``extras`` not installed at a version it allows."""
    try:
        from packaging.requirements import Requirement
    except ImportError:
        return "packaging is not installed: the requirements cannot be checked"
    reqs = list(project.get("dependencies", []))
    for extra in extras:
        reqs += project.get("optional-dependencies", {}).get(extra, [])
    for text in reqs:
        req = Requirement(text)
        try:
            version = metadata.version(req.name)
        except metadata.PackageNotFoundError:
            return f"{req.name} is not installed"
        if not req.specifier.contains(version, prereleases=True):
            return f"{req.name} {version} is installed, {text} wanted"
    return None


def main(argv: list[str]) -> int:
    try:
        dist: metadata.Distribution | None = metadata.distribution("orbitrig")
    except metadata.PackageNotFoundError:
        dist = None
    try:
        reason = install_needed(ROOT, dist, argv)
    except (OSError, ValueError, KeyError) as err:  # an unreadable install: install again
        reason = f"the installed orbitrig cannot be read ({err})"
    if reason is not None:
        print(reason)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
