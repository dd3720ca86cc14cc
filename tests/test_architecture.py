"""The import rules of docs/architecture.md, checked on the source text.

sim must stay independent of the code under test (a shared sign or scale would
cancel out), reduction must stay pure, and imports flow one way.
"""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import pytest

from support.packages import PACKAGES, sources
from support.paths import ROOT

#: the top-level packages (pyproject.toml's include patterns)
OURS = PACKAGES

# package -> packages of ours it may import (module-level or inside functions);
# rigerrors, the root of the exception tree, and rigunits, the units and the timestamp
# format, import nothing of ours and every package but sim may import them. rigthreads, the
# one-BLAS-thread rule, imports nothing of ours either and only the entry points take it: the
# orbitrig command (orbitrig/cli, below) and the simulator's own (sim/__main__.py, ENTRY_POINTS),
# which shares no sign or scale with the code under test through a thread count.
ALLOWED = {
    "rigerrors": set(),
    "rigthreads": set(),
    "rigunits": set(),
    "reduction": {"rigerrors", "rigunits"},
    "sim": {"rigthreads"},
    "daq": {"reduction", "rigerrors", "rigunits"},
    "drives": {"rigerrors", "rigunits"},
    "orbitrig": {"daq", "drives", "reduction", "sim", "rigerrors", "rigthreads", "rigunits"},
}
#: package -> the modules of its that may import it (the processes' first acts; bench/ and tests/
#: start processes too and are outside these rules)
ENTRY_POINTS = {"rigthreads": ("orbitrig/cli/__init__.py", "sim/__main__.py")}

# the application's wings -> the parts of orbitrig they may import. orbitrig.config
# and the neutral top-level modules (errors, the rig's vocabulary) are shared by all;
# cli/ wires everything and is the only wing that knows the simulator exists (it builds it);
# it is the orbitrig command's entry point, the only wing that sets the BLAS threads (rigthreads).
NEUTRAL = {"errors", "load_systems", "shipped"}
APP_SHARED = {"orbitrig", "orbitrig.config"} | {f"orbitrig.{m}" for m in NEUTRAL}
WINGS = {
    "orbitrig.cli": {
        "orbitrig.cli",
        "orbitrig.run",
        "orbitrig.store",
        "orbitrig.analysis",
        "orbitrig.service",
        "orbitrig.dashboard",
        "orbitrig.catalog",
        "sim",
        "rigthreads",
    },
    "orbitrig.service": {"orbitrig.service", "orbitrig.run", "orbitrig.store", "orbitrig.analysis", "orbitrig.catalog"},
    "orbitrig.catalog": {"orbitrig.catalog", "orbitrig.store", "orbitrig.analysis"},
    "orbitrig.dashboard": {
        "orbitrig.dashboard",
        "orbitrig.service.protocol",
        "orbitrig.service.reconnect",
        "orbitrig.service.broker_calls",
    },
    "orbitrig.run": {"orbitrig.run", "orbitrig.store"},
    "orbitrig.store": {"orbitrig.store", "orbitrig.run.plan", "orbitrig.run.steps"},
    "orbitrig.analysis": {"orbitrig.analysis", "orbitrig.store"},
}
# I/O libraries the pure numerical core must never import
IO_MODULES = ("serial", "socket", "asyncio", "can", "pymodbus", "aiomqtt", "h5py", "typer", "rich")


def _imports(path: Path, module: tuple[str, ...] | None = None) -> list[tuple[int, str]]:
    """(line, absolute module name) of every import in ``path``; relative imports
    (``from ..daq import frames``) are resolved against the file's own module
    (``module``, default: its path under ROOT), so they cannot slip past the rules."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = list((module or path.relative_to(ROOT).with_suffix("").parts)[:-1])
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.lineno, node.module))
        elif isinstance(node, ast.ImportFrom) and node.level > 0:
            base = package[: len(package) - (node.level - 1)] if node.level - 1 <= len(package) else []
            if node.module:
                found.append((node.lineno, ".".join(base + [node.module])))
            else:  # from .. import daq: the names are modules of the base package
                found += [(node.lineno, ".".join(base + [alias.name])) for alias in node.names]
    return found


def _permitted(package: str, module: str) -> bool:
    top = module.split(".")[0]
    if top not in OURS or top == package:
        return True
    return any(module == a or module.startswith(a + ".") for a in ALLOWED[package])


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_imports_flow_one_way(package: str) -> None:
    bad = [
        f"{path.relative_to(ROOT)}:{line}: imports {module}"
        for path in sources(package)
        for line, module in _imports(path)
        if not _permitted(package, module)
    ]
    assert not bad, "forbidden imports:\n" + "\n".join(bad)


def _wing_permitted(wing: str, module: str) -> bool:
    top = module.split(".")[0]
    if top in ("sim", "rigthreads"):
        return top in WINGS[wing]
    if top != "orbitrig":
        return True
    return module in APP_SHARED or any(module == a or module.startswith(a + ".") for a in WINGS[wing])


@pytest.mark.parametrize("wing", sorted(WINGS))
def test_application_wings(wing: str) -> None:
    folder = ROOT / wing.replace(".", "/")
    bad = [
        f"{path.relative_to(ROOT)}:{line}: imports {module}"
        for path in sorted(folder.rglob("*.py"))
        for line, module in _imports(path)
        if not _wing_permitted(wing, module)
    ]
    assert not bad, f"{wing} may import only {sorted(WINGS[wing] | APP_SHARED)} of orbitrig:\n" + "\n".join(bad)


def test_every_application_module_is_in_a_wing() -> None:
    loose = {p.stem for p in (ROOT / "orbitrig").glob("*.py")} - {"__init__", "__main__"} - NEUTRAL
    folders = {p.name for p in (ROOT / "orbitrig").iterdir() if p.is_dir() and p.name != "__pycache__"}
    assert not loose, f"modules outside the wings: {sorted(loose)}"
    assert folders <= {w.split(".")[1] for w in WINGS} | {"data", "config"}, f"unknown wings: {sorted(folders)}"


def test_wing_checker_catches_a_violation() -> None:
    assert not _wing_permitted("orbitrig.run", "sim.rig")
    assert not _wing_permitted("orbitrig.run", "orbitrig.cli.sweep")
    assert not _wing_permitted("orbitrig.store", "orbitrig.run.engine")
    assert _wing_permitted("orbitrig.store", "orbitrig.run.plan")
    assert _wing_permitted("orbitrig.cli", "sim.rig")
    assert _wing_permitted("orbitrig.cli", "rigthreads")
    assert not _wing_permitted("orbitrig.run", "rigthreads")
    assert _wing_permitted("orbitrig.run", "rigunits")
    assert _wing_permitted("orbitrig.analysis", "orbitrig.config")


def test_entry_points_alone_take_their_rules() -> None:
    """rigthreads is a process's first act: within the packages only its entry points import it."""
    bad = [
        f"{path.relative_to(ROOT)}:{line}: imports {module}"
        for package in OURS
        for path in sources(package)
        for line, module in _imports(path)
        if module.split(".")[0] in ENTRY_POINTS
        and path.relative_to(ROOT).as_posix() not in ENTRY_POINTS[module.split(".")[0]]
    ]
    assert not bad, f"only the entry points {ENTRY_POINTS} import these:\n" + "\n".join(bad)
    assert all(
        any(m == top for _, m in _imports(ROOT / entry)) for top, entries in ENTRY_POINTS.items() for entry in entries
    )


def _assigned(path: Path, name: str) -> object:
    """The literal ``path`` assigns to ``name`` at module level (read, not imported)."""
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == name for t in node.targets):
            return ast.literal_eval(node.value)
    raise AssertionError(f"{path.relative_to(ROOT)}: no {name} = ...")


def test_every_list_of_the_packages_is_pyprojects() -> None:
    """pyproject.toml's include patterns are the one list of the top-level packages (support.packages,
    which the hooks take); the lists that cannot read it say the same: the tree's packages (the
    benches are no part of the distribution), the import rule, the sources the revision digests in
    an installed wheel too (orbitrig.run.provenance.PACKAGES) and mypy's packages. tools/run-tests'
    compileall: tests/cli/test_cli_run_tests.py."""
    packages = set(PACKAGES)
    assert len(PACKAGES) == len(packages) and {"orbitrig", "sim", "rigerrors", "rigthreads", "rigunits"} <= packages
    assert {p.parent.name for p in ROOT.glob("*/__init__.py")} - {"bench"} == packages
    assert set(ALLOWED) == packages
    provenance = _assigned(ROOT / "orbitrig" / "run" / "provenance.py", "PACKAGES")
    assert isinstance(provenance, tuple) and set(provenance) == packages and len(provenance) == len(packages)
    mypy = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["mypy"]["packages"]
    assert set(mypy) == packages


def test_reduction_has_no_io() -> None:
    bad = [
        f"{path.relative_to(ROOT)}:{line}: imports {module}"
        for path in sources("reduction")
        for line, module in _imports(path)
        if module.split(".")[0] in IO_MODULES
    ]
    assert not bad, "reduction/ must stay pure:\n" + "\n".join(bad)


def test_rule_checker_catches_a_violation(tmp_path: Path) -> None:
    """The checker itself must be able to fail."""
    assert not _permitted("sim", "daq.frames")
    assert not _permitted("reduction", "orbitrig.errors")
    assert not _permitted("drives", "reduction.identify")
    assert not _permitted("daq", "drives.rig")
    assert _permitted("daq", "reduction.fourier")
    assert _permitted("drives", "rigerrors")
    assert not _permitted("drives", "reduction.errors")
    assert not _permitted("sim", "rigerrors")
    assert not _permitted("sim", "rigunits")
    assert _permitted("sim", "rigthreads")
    assert not _permitted("reduction", "rigthreads")
    assert not _permitted("rigthreads", "rigunits")
    assert _permitted("orbitrig", "sim.rig")
    assert _permitted("sim", "numpy")


def test_relative_imports_are_resolved(tmp_path: Path) -> None:
    """``from ..daq import frames`` inside sim/ is an import from daq."""
    src = tmp_path / "mod.py"
    src.write_text(
        "from ..daq import frames\nfrom . import physics\nfrom .. import drives\nfrom .drive_model import DriveModel\n"
    )
    found = [m for _, m in _imports(src, ("sim", "mod"))]
    assert found == ["daq", "sim.physics", "drives", "sim.drive_model"]
    assert [m for m in found if not _permitted("sim", m)] == ["daq", "drives"]


# ------------------------------------------------------------------ size and seams
MAX_MODULE_LINES, MAX_FUNCTION_LINES = 400, 60
#: modules and functions of orbitrig/ still over the limits, outside the run wing (the list
#: only shrinks: an entry that fits the limits fails the test until it is removed)
NOT_YET_SPLIT: set[str] = set()


def _too_long(path: Path) -> dict[str, int]:
    """'<path>' -> lines if the module is too long, '<path>::<function>' -> lines per long function."""
    rel = path.relative_to(ROOT).as_posix()
    text = path.read_text(encoding="utf-8")
    out = {rel: len(text.splitlines())} if len(text.splitlines()) > MAX_MODULE_LINES else {}
    for node in ast.walk(ast.parse(text, filename=str(path))):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            n = node.end_lineno - node.lineno + 1
            if n > MAX_FUNCTION_LINES:
                out[f"{rel}::{node.name}"] = n
    return out


def test_application_modules_and_functions_are_small() -> None:
    found: dict[str, int] = {}
    for path in sources("orbitrig"):
        found.update(_too_long(path))
    new = {k: v for k, v in found.items() if k not in NOT_YET_SPLIT}
    assert not new, f"over {MAX_MODULE_LINES} lines per module or {MAX_FUNCTION_LINES} per function: " + ", ".join(
        f"{k} ({v})" for k, v in sorted(new.items())
    )
    fixed = NOT_YET_SPLIT - set(found)
    assert not fixed, f"now within the limits, remove from NOT_YET_SPLIT: {sorted(fixed)}"


def test_every_module_of_ours_is_small() -> None:
    """The module limit holds in every package (the function limit is checked in orbitrig/)."""
    long = {
        p.relative_to(ROOT).as_posix(): n
        for pkg in OURS
        for p in sources(pkg)
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_MODULE_LINES
    }
    assert not long, f"over {MAX_MODULE_LINES} lines: {long}"


def test_size_checker_catches_a_long_function(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr(__import__(__name__), "ROOT", tmp_path)
    src = tmp_path / "long.py"
    src.write_text("def f():\n" + "    x = 1\n" * MAX_FUNCTION_LINES + "\n\ndef g():\n    pass\n")
    assert _too_long(src) == {"long.py::f": MAX_FUNCTION_LINES + 1}


def _calls(path: Path, names: set[str]) -> list[int]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    return [
        n.lineno
        for n in ast.walk(tree)
        if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id in names
    ]


@pytest.mark.parametrize("wing", ["orbitrig/run", "orbitrig/cli"])
def test_typed_seams_no_getattr(wing: str) -> None:
    """The run engine and the command line reach daq, drives and the simulator through types."""
    bad = [
        f"{p.relative_to(ROOT)}:{line}"
        for p in sorted((ROOT / wing).rglob("*.py"))
        for line in _calls(p, {"getattr", "hasattr"})
    ]
    assert not bad, "getattr/hasattr on our own objects:\n" + "\n".join(bad)


SIM_NAMES = {"sim", "sim_rig", "simrig", "speedup", "simulator"}


def _sim_branches(path: Path) -> list[int]:
    """Lines of `if`s and conditional expressions whose test names the simulator."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    lines = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.If, ast.IfExp, ast.While)):
            names = {n.id for n in ast.walk(node.test) if isinstance(n, ast.Name)}
            names |= {n.attr for n in ast.walk(node.test) if isinstance(n, ast.Attribute)}
            if {x.lower() for x in names} & SIM_NAMES:
                lines.append(node.lineno)
    return lines


@pytest.mark.parametrize("wing", ["orbitrig/run", "orbitrig/service"])
def test_no_simulator_branch_on_the_run_path(wing: str) -> None:
    """The engine gets endpoints, a time scale, hands and truth; only cli/ knows a simulator exists.
    (A stored run's flag "made on the simulator" is data: store/ and analysis/ may read it.)"""
    bad = [f"{p.relative_to(ROOT)}:{line}" for p in sorted((ROOT / wing).rglob("*.py")) for line in _sim_branches(p)]
    assert not bad, "branches on the simulator outside orbitrig/cli:\n" + "\n".join(bad)


def test_sim_branch_checker_catches_one(tmp_path: Path) -> None:
    src = tmp_path / "m.py"
    src.write_text(
        "def f(self, x):\n    if self.sim is not None:\n        x = x / self.speedup\n    return 1 if x else 2\n"
    )
    assert _sim_branches(src) == [2]


def _runtime_imports(path: Path) -> list[tuple[int, str]]:
    """``_imports`` without those under ``if TYPE_CHECKING:`` (annotations only)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    typing_only = {
        node.lineno
        for block in ast.walk(tree)
        if isinstance(block, ast.If) and isinstance(block.test, ast.Name) and block.test.id == "TYPE_CHECKING"
        for stmt in block.body
        for node in ast.walk(stmt)
        if isinstance(node, (ast.Import, ast.ImportFrom))
    }
    return [(line, m) for line, m in _imports(path) if line not in typing_only]


def _wing_of(module: str) -> str | None:
    parts = module.split(".")
    return ".".join(parts[:2]) if parts[0] == "orbitrig" and ".".join(parts[:2]) in WINGS else None


def _wing_graph() -> dict[str, dict[str, str]]:
    """wing -> {imported wing: the first file:line that imports it} (run-time imports)."""
    graph: dict[str, dict[str, str]] = {w: {} for w in WINGS}
    for wing in WINGS:
        for path in sources(wing.replace(".", "/")):
            for line, module in _runtime_imports(path):
                other = _wing_of(module)
                if other is not None and other != wing:
                    graph[wing].setdefault(other, f"{path.relative_to(ROOT)}:{line}")
    return graph


def _cycle(graph: dict[str, dict[str, str]]) -> list[str]:
    """One cycle of the graph as [a, b, ..., a], or [] when there is none."""
    done: set[str] = set()

    def visit(node: str, path: list[str]) -> list[str]:
        if node in path:
            return path[path.index(node) :] + [node]
        if node in done:
            return []
        for nxt in graph.get(node, {}):
            found = visit(nxt, path + [node])
            if found:
                return found
        done.add(node)
        return []

    for start in graph:
        found = visit(start, [])
        if found:
            return found
    return []


def test_no_import_cycle_between_wings() -> None:
    graph = _wing_graph()
    cycle = _cycle(graph)
    where = [f"{a} -> {b} ({graph[a][b]})" for a, b in zip(cycle, cycle[1:])]
    assert not cycle, "import cycle between wings:\n" + "\n".join(where)


def test_cycle_finder_finds_a_cycle() -> None:
    assert _cycle({"a": {"b": ""}, "b": {"c": ""}, "c": {"a": ""}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b": ""}, "b": {}, "c": {"a": ""}}) == []
    assert _runtime_imports(ROOT / "orbitrig" / "store" / "writer.py")  # parses; TYPE_CHECKING lines left out
    assert all(m != "orbitrig.run.plan" for _, m in _runtime_imports(ROOT / "orbitrig" / "store" / "writer.py"))
