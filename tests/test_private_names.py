"""No underscore name crosses a module, no underscore attribute crosses an object: checked on the
source of the packages and the benches (docs/architecture.md's house rules; tests/ is left out, a
white-box test looks inside)."""

from __future__ import annotations

import ast
from pathlib import Path

from support.packages import PACKAGES, sources
from support.paths import ROOT

# ------------------------------------------------------------------ private names
#: what the private-name rule covers: the packages and the benches (tests/ is left out, below)
PRIVATE_RULE = (*PACKAGES, "bench")


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
        for path in sources(package)
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
        for path in sources(package):
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
