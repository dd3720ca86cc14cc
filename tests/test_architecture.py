"""The import rules of docs/architecture.md, checked on the source text.

sim must stay independent of the code under test (a shared sign or scale would
cancel out), reduction must stay pure, and imports flow one way.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from support.paths import ROOT

OURS = ("daq", "drives", "reduction", "sim", "orbitrig", "rigerrors", "rigthreads", "rigunits")

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


def _sources(package: str) -> list[Path]:
    return sorted((ROOT / package).rglob("*.py"))


def _permitted(package: str, module: str) -> bool:
    top = module.split(".")[0]
    if top not in OURS or top == package:
        return True
    return any(module == a or module.startswith(a + ".") for a in ALLOWED[package])


@pytest.mark.parametrize("package", sorted(ALLOWED))
def test_imports_flow_one_way(package: str) -> None:
    bad = [
        f"{path.relative_to(ROOT)}:{line}: imports {module}"
        for path in _sources(package)
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
        for path in _sources(package)
        for line, module in _imports(path)
        if module.split(".")[0] in ENTRY_POINTS
        and path.relative_to(ROOT).as_posix() not in ENTRY_POINTS[module.split(".")[0]]
    ]
    assert not bad, f"only the entry points {ENTRY_POINTS} import these:\n" + "\n".join(bad)
    assert all(
        any(m == top for _, m in _imports(ROOT / entry)) for top, entries in ENTRY_POINTS.items() for entry in entries
    )


def test_reduction_has_no_io() -> None:
    bad = [
        f"{path.relative_to(ROOT)}:{line}: imports {module}"
        for path in _sources("reduction")
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
    for path in _sources("orbitrig"):
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
        for p in _sources(pkg)
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
        for path in _sources(wing.replace(".", "/")):
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


# ------------------------------------------------------------------ private names
#: what the private-name rule covers: the packages and the benches (tests/ is left out, below)
PRIVATE_RULE = (*OURS, "bench")


def _is_module(module: str) -> bool:
    """Whether ``module`` (dotted) is a module or package of ours in the tree."""
    path = ROOT.joinpath(*module.split("."))
    return path.with_suffix(".py").is_file() or (path / "__init__.py").is_file()


def _private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__")


def _dotted(node: ast.expr, modules: dict[str, str]) -> str | None:
    """The dotted name ``node`` reads (``orbitrig.analysis.plots``), its first name resolved through
    ``modules`` (a name an import bound -> the module it is); None when it is no such chain."""
    if isinstance(node, ast.Name):
        return modules.get(node.id)
    if isinstance(node, ast.Attribute):
        head = _dotted(node.value, modules)
        return None if head is None else f"{head}.{node.attr}"
    return None


def _private_uses(path: Path, module: tuple[str, ...] | None = None) -> list[str]:
    """'line: module.name' for each underscore name ``path`` takes from another module of ours:
    imported (``from orbitrig.analysis.plots import _save``, on whichever line of a parenthesised
    import, relative ones resolved, ``import a._b``, ``from a._b import c``) or reached through a
    module of ours it imported (``plots._figure``, ``import a.b as m; m._c``, ``import a.b;
    a.b._c``, ``from orbitrig import analysis; analysis.plots._save``)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    parts = list(module or path.relative_to(ROOT).with_suffix("").parts)
    package = parts[:-1]
    ours = set(PRIVATE_RULE)
    found, modules = [], {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] not in ours:
                    continue
                if any(_private(part) for part in alias.name.split(".")):
                    found.append(f"{alias.lineno}: {alias.name}")
                if alias.asname:
                    modules[alias.asname] = alias.name
                else:  # `import a.b.c` binds `a`: a.b.c._d is reached through it
                    top = alias.name.split(".")[0]
                    modules[top] = top
        elif isinstance(node, ast.ImportFrom):
            base = package[: len(package) - (node.level - 1)] if node.level else []
            source = ".".join(base + ([node.module] if node.module else []))
            if source.split(".")[0] not in ours:
                continue
            if any(_private(part) for part in source.split(".")):
                found.append(f"{node.lineno}: {source}")
            for alias in node.names:
                if _private(alias.name):
                    found.append(f"{alias.lineno}: {source}.{alias.name}")
                elif _is_module(f"{source}.{alias.name}"):
                    modules[alias.asname or alias.name] = f"{source}.{alias.name}"
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _private(node.attr):
            owner = _dotted(node.value, modules)
            if owner is not None and _is_module(owner):
                found.append(f"{node.lineno}: {owner}.{node.attr}")
    return sorted(found, key=lambda use: int(use.split(":")[0]))


def test_no_private_name_crosses_a_module() -> None:
    """A name with a leading underscore belongs to its module: no other module of the packages
    or the benches imports it or reaches it through its module, not even inside its own
    package; a name another module needs is public, under a name in the rig's words, in its one
    owner. tests/ may import one: a white-box test (or a test helper) reaches a step of the code
    it checks, and the name stays private to the code. Modules of other projects are not ours
    to judge (``matplotlib._mathtext`` where no public way exists)."""
    bad = [
        f"{path.relative_to(ROOT)}:{use}"
        for package in PRIVATE_RULE
        for path in _sources(package)
        for use in _private_uses(path)
    ]
    assert not bad, "underscore names taken from another module:\n" + "\n".join(bad)


def test_private_name_checker_catches_each_form(tmp_path: Path) -> None:
    src = tmp_path / "mod.py"
    src.write_text(
        "from orbitrig.config.fields import _Model, ChannelName\n"
        "from .plots import _save\n"
        "from orbitrig.analysis import plots\n"
        "import orbitrig.cli.drives_hold as hold\n"
        "from matplotlib import _mathtext\n"
        "from orbitrig import __version__\n"
        "import orbitrig.cli._hidden\n"
        "fig = plots._figure(1, 1)\n"
        "hold._hold\n"
        "plots.save_figure\n"
        "from orbitrig.config.messages import (\n"
        "    key_line,\n"
        "    _at,\n"
        ")\n"
        "import orbitrig.config.reading\n"
        "orbitrig.config.reading._parse('', '')\n"
        "from orbitrig import analysis\n"
        "analysis.plots._save\n"
        "from orbitrig.cli._hidden import shown\n"
        "from . import plot_marks as marks\n"
        "marks._colors(3)\n"
        "plots.STYLE._private_field\n"
        "orbitrig.config.reading.read_text\n"
    )
    assert _private_uses(src, ("orbitrig", "analysis", "mod")) == [
        "1: orbitrig.config.fields._Model",
        "2: orbitrig.analysis.plots._save",
        "7: orbitrig.cli._hidden",
        "8: orbitrig.analysis.plots._figure",
        "9: orbitrig.cli.drives_hold._hold",
        "13: orbitrig.config.messages._at",
        "16: orbitrig.config.reading._parse",
        "18: orbitrig.analysis.plots._save",
        "19: orbitrig.cli._hidden",
        "21: orbitrig.analysis.plot_marks._colors",
    ]


# ------------------------------------------------------------------ private attributes
#: underscore attributes of other projects' objects, per module of ours, each with why no public
#: way exists (the list only shrinks: an entry no longer used fails the test until it is removed)
FOREIGN_PRIVATE_ATTRIBUTES: dict[str, tuple[set[str], str]] = {
    "orbitrig/analysis/canvas.py": (
        {"_prepare_font", "_layout", "_set_transform", "_render_glyph", "_find_fonts_by_props"},
        "matplotlib's Agg text path, glyph by glyph: the report rasterises each string once as matplotlib does",
    ),
    "orbitrig/analysis/figure_text.py": (
        {"_parse_cached"},
        "matplotlib's mathtext layout cache, dropped when the script scale changes (getattr: absent in some release)",
    ),
    "orbitrig/analysis/plot_marks.py": (
        {"_get_lines", "_prop_cycle", "_request_autoscale_view"},
        "matplotlib Axes' property cycle and autoscale request: a line added as ax.plot adds it, without its parsing",
    ),
    "orbitrig/analysis/plots_narrow.py": (
        {"_suptitle", "_left_title", "_right_title"},
        "matplotlib keeps the suptitle and the side titles' Text artists without a getter; the report wraps them",
    ),
    "orbitrig/analysis/report_axes.py": (
        {
            "_align_label_groups",
            "_get_ticklabel_bboxes",
            "_get_tick_boxes_siblings",
            "_request_autoscale_view",
            "_unstale_viewLim",
            "_update_ticks",
            "_update_label_position",
            "_update_offset_text_position",
            "_stale_viewlims",
        },
        "matplotlib Axis/Axes drawing steps that ReportAxes overrides to measure tick labels once per draw",
    ),
    "orbitrig/catalog/store.py": ({"_mapping"}, "SQLAlchemy's documented Row._mapping (underscored: no column clash)"),
    "orbitrig/cli/terminal.py": ({"_check_buffer"}, "rich Console's write step, extended to go quiet on a broken file"),
    "orbitrig/dashboard/puback.py": (
        {"_on_connect", "_on_subscribe", "_on_unsubscribe", "_on_publish"},
        "aiomqtt's paho callbacks, extended to keep the PUBACK's reason code aiomqtt drops",
    ),
    "orbitrig/service/broker_calls.py": (
        {"_client"},
        "aiomqtt keeps its paho client without a public handle (paho_of)",
    ),
    "orbitrig/service/flood_read.py": (
        {"_selector", "_callback", "_args", "_handle_publish", "_in_packet", "_protocol", "_send_puback"},
        "asyncio's registered reader (no public view of it) and paho's packet decoding, read in bursts and shed",
    ),
    "orbitrig/service/reconnect.py": ({"_out_messages"}, "paho forgets a refused publish's topic after on_publish"),
    "bench/bench_abort_flood.py": ({"_on_message"}, "aiomqtt's paho message callback, timed by the bench"),
}
#: the standard library's underscore names a module of ours may use anywhere, with why
STDLIB_PRIVATE = {"os._exit": "the one exit that runs no clean-up: a process that must end now"}


def _underscored(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _attribute_uses(path: Path) -> list[tuple[int, str, str]]:
    """(line, attribute, as written) of each underscore attribute ``path`` reads, sets or deletes on
    an object other than ``self`` and ``cls`` (``cfg._file = f``, ``other._last``, ``f()._x``,
    ``self.part._x``, ``super()._hook()``, ``getattr(loop, "_selector")``); dunders are not private."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _underscored(node.attr):
            if not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls")):
                found.append((node.lineno, node.attr, ast.unparse(node)))
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Name)
            and node.func.id in ("getattr", "setattr", "hasattr", "delattr")
            and len(node.args) >= 2
            and isinstance(name := node.args[1], ast.Constant)
            and isinstance(name.value, str)
            and _underscored(name.value)
        ):
            found.append((node.lineno, name.value, ast.unparse(node)))
    return sorted(found)


def _unexcused(rel: str, uses: list[tuple[int, str, str]]) -> tuple[list[str], set[str]]:
    """('line: use' not excused, the exceptions that excused one: 'module: attribute' or a STDLIB_PRIVATE name)."""
    listed = FOREIGN_PRIVATE_ATTRIBUTES.get(rel, (set(), ""))[0]
    bad, excused = [], set()
    for line, attr, written in uses:
        if written in STDLIB_PRIVATE:
            excused.add(written)
        elif attr in listed:
            excused.add(f"{rel}: {attr}")
        else:
            bad.append(f"{line}: {written}")
    return bad, excused


def test_no_underscore_attribute_crosses_an_object() -> None:
    """An underscore attribute belongs to its object: its own class reads and sets it on ``self``
    (``cls``); another module's code, or another instance's, goes through a public name or a method
    of the owner (a configuration read names its file with ``remember_file``, not ``cfg._file =``).
    tests/ is left out (a white-box test looks inside). Other projects' objects with no public way:
    FOREIGN_PRIVATE_ATTRIBUTES and STDLIB_PRIVATE, each with its reason."""
    bad, excused = [], set()
    for package in PRIVATE_RULE:
        for path in _sources(package):
            rel = path.relative_to(ROOT).as_posix()
            found, used = _unexcused(rel, _attribute_uses(path))
            bad += [f"{rel}:{use}" for use in found]
            excused |= used
    assert not bad, "underscore attributes of another object:\n" + "\n".join(bad)
    listed = {f"{rel}: {a}" for rel, (names, _) in FOREIGN_PRIVATE_ATTRIBUTES.items() for a in names}
    stale = sorted((listed | set(STDLIB_PRIVATE)) - excused)
    assert not stale, f"no longer used, remove from FOREIGN_PRIVATE_ATTRIBUTES / STDLIB_PRIVATE: {stale}"


def test_underscore_attribute_checker_catches_each_form(tmp_path: Path) -> None:
    src = tmp_path / "mod.py"
    src.write_text(
        "class Model:\n"
        "    def f(self, other, cfg, os):\n"
        "        self._x = 1\n"
        "        other._x\n"
        "        cfg._file = 'a'\n"
        "        cls._y\n"
        "        cfg.__dict__, cfg.name, getattr(cfg, 'name'), getattr(cfg, '__doc__')\n"
        "        super()._hook()\n"
        "        self.part._inner += 1\n"
        "        getattr(loop, '_selector', None)\n"
        "        setattr(cfg, '_text', '')\n"
        "        os._exit(0)\n"
        "        other.__mangled\n"
        "        del cfg._file\n"
        "        make()._made.public\n"
    )
    uses = _attribute_uses(src)
    assert [(line, attr) for line, attr, _ in uses] == [
        (4, "_x"),
        (5, "_file"),
        (8, "_hook"),
        (9, "_inner"),
        (10, "_selector"),
        (11, "_text"),
        (12, "_exit"),
        (13, "__mangled"),
        (14, "_file"),
        (15, "_made"),
    ]
    assert uses[4][2] == "getattr(loop, '_selector', None)"
    bad, excused = _unexcused("orbitrig/service/flood_read.py", uses)
    assert excused == {"os._exit", "orbitrig/service/flood_read.py: _selector"}
    assert bad == [
        "4: other._x",
        "5: cfg._file",
        "8: super()._hook",
        "9: self.part._inner",
        "11: setattr(cfg, '_text', '')",
        "13: other.__mangled",
        "14: cfg._file",
        "15: make()._made",
    ]
    assert _unexcused("orbitrig/run/engine.py", uses)[0][4] == "10: getattr(loop, '_selector', None)"
