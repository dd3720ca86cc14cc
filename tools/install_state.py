#!/usr/bin/env python3
"""Is orbitrig installed as tools/run-tests would install it, so that its `pip install` can be skipped?

    python tools/install_state.py [EXTRA ...]      # exit 0: installed as pip would; 1: install (the reason said)

Installed as pip would means, for the interpreter running this: orbitrig installed editable from
this source tree (its direct_url.json), with this tree's pyproject.toml version, requirements
(Requires-Dist, every extra's), commands ([project.scripts]) and top-level packages (the editable
finder's mapping), and every requirement of the package and of each EXTRA installed at a version it
allows, with what each of those requires in turn (a requirement's own extras, `psycopg[binary]`'s
psycopg-binary, included; markers evaluated), as pip's install would see to. Anything else, or
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
    if _commands(dist) != _wanted_commands(project):
        return "the installed commands are not pyproject.toml's [project.scripts]"
    mapping = _finder_mapping(dist)
    if mapping is None or set(mapping) != _packages(project_root):
        return "the installed packages are not pyproject.toml's"
    if any(Path(folder) != project_root.resolve() / name for name, folder in mapping.items()):
        return "the installed packages are another tree's"
    return _unmet(project, extras)


def _wanted_commands(project: dict) -> set[tuple[str, str, str]]:
    """(group, name, object) of each command pyproject.toml's [project] makes (scripts, gui-scripts)."""
    groups = {"scripts": "console_scripts", "gui-scripts": "gui_scripts"}
    return {(group, name, ref) for key, group in groups.items() for name, ref in project.get(key, {}).items()}


def _commands(dist: metadata.Distribution) -> set[tuple[str, str, str]]:
    """(group, name, object) of each command the installed orbitrig made."""
    return {(e.group, e.name, e.value) for e in dist.entry_points if e.group in ("console_scripts", "gui_scripts")}


def _unmet(project: dict, extras: list[str]) -> str | None:
    """The first requirement of the package or of ``extras``, or of what they require in turn (with
    the extras each names), not installed at a version it allows."""
    try:
        from packaging.requirements import Requirement
    except ImportError:
        return "packaging is not installed: the requirements cannot be checked"
    reqs = list(project.get("dependencies", []))
    for extra in extras:
        reqs += project.get("optional-dependencies", {}).get(extra, [])
    todo, seen = [(Requirement(text), "orbitrig") for text in reqs], set()
    while todo:
        req, wanted_by = todo.pop()
        try:
            dist = metadata.distribution(req.name)
        except metadata.PackageNotFoundError:
            return f"{req.name} is not installed" + ("" if wanted_by == "orbitrig" else f" ({wanted_by} requires it)")
        if not req.specifier.contains(dist.version, prereleases=True):
            return f"{req.name} {dist.version} is installed, {req} wanted" + (
                "" if wanted_by == "orbitrig" else f" (by {wanted_by})"
            )
        for extra in ("", *sorted(req.extras)):
            if (_name(req.name), extra) in seen:
                continue
            seen.add((_name(req.name), extra))
            for text in dist.requires or ():
                sub = Requirement(text)
                if extra and not _names_an_extra(text):  # the project's own: its pass without extras
                    continue
                if sub.marker is None or sub.marker.evaluate({"extra": extra}):
                    todo.append((sub, f"{req.name}[{extra}]" if extra else req.name))
    return None


def _names_an_extra(requirement: str) -> bool:
    """Whether a Requires-Dist's marker names an extra (it belongs to that extra alone)."""
    return re.search(r"\bextra\s*==", requirement.partition(";")[2]) is not None


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
