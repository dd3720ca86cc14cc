"""docs/architecture.md and docs/interfaces.md against the source: every module they name
exists, the lists that stand for a whole package name every module of it, and the
signatures of docs/interfaces.md's code blocks take the parameters the code takes.

The lists that stand for a whole package: architecture.md's table of the run engine
(orbitrig/run) and interfaces.md's sections of reduction/, daq/, drives/ and sim/. A
module is named by its path (`daq/frames.py`), its dotted name (`daq.frames`) or, inside
its package's list, its file name (`frames.py`).
"""

from __future__ import annotations

import ast
import importlib
import inspect
import itertools
import re
from pathlib import Path

import pytest

from support.packages import PACKAGES
from support.paths import ROOT

ARCHITECTURE = ROOT / "docs" / "architecture.md"
INTERFACES = ROOT / "docs" / "interfaces.md"
OURS = PACKAGES
_PATH = re.compile(rf"(?<![\w/.])((?:{'|'.join(OURS)})(?:/\w+)*\.py)\b")
_DOTTED = re.compile(rf"(?<![\w/.])((?:{'|'.join(OURS)})(?:\.\w+)+)")


def _modules(package: str) -> list[str]:
    """The modules of ``package`` as paths relative to the repository (no __init__.py)."""
    return sorted(
        str(p.relative_to(ROOT)) for p in (ROOT / package).rglob("*.py") if p.name != "__init__.py" and p.is_file()
    )


def _section(text: str, heading: str) -> str:
    """The text under ``heading`` (a whole line) up to the next heading of its level or above
    (a `#` line inside a code block is no heading)."""
    lines = text.split("\n")
    start = lines.index(heading)
    level = len(heading.split(" ")[0])
    fenced = False
    for end in range(start + 1, len(lines)):
        fenced ^= lines[end].startswith("```")
        head = re.match(r"(#+) ", lines[end])
        if not fenced and head and len(head.group(1)) <= level:
            break
    else:
        end = len(lines)
    return "\n".join(lines[start:end])


def _names(module: str, text: str) -> bool:
    """Does ``text`` name ``module`` (a path such as daq/frames.py) by path, dotted name or file name?"""
    dotted = module[:-3].replace("/", ".")
    name = Path(module).name
    return (
        re.search(rf"(?<![\w/.]){re.escape(module)}\b", text) is not None
        or re.search(rf"(?<![\w.]){re.escape(dotted)}\b", text) is not None
        or re.search(rf"(?<![\w/.]){re.escape(name)}\b", text) is not None
    )


def _resolves(dotted: str) -> bool:
    """A dotted name of ours that is a module, or a module and attributes of it."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        base = ROOT.joinpath(*parts[:i])
        if base.with_suffix(".py").is_file() or (base / "__init__.py").is_file():
            obj = importlib.import_module(".".join(parts[:i]))
            for attr in parts[i:]:
                if not hasattr(obj, attr):
                    return False
                obj = getattr(obj, attr)
            return True
    return False


@pytest.mark.parametrize("doc", [ARCHITECTURE, INTERFACES], ids=lambda p: p.name)
def test_every_module_named_exists(doc: Path) -> None:
    text = doc.read_text(encoding="utf-8")
    missing = sorted(p for p in set(_PATH.findall(text)) if not (ROOT / p).is_file())
    unresolved = sorted(d for d in set(_DOTTED.findall(text)) if not _resolves(d))
    assert not missing, f"{doc.name} names modules that do not exist: {missing}"
    assert not unresolved, f"{doc.name} names what the code does not have: {unresolved}"


def test_the_run_engine_table_names_every_module_of_orbitrig_run() -> None:
    table = _section(ARCHITECTURE.read_text(encoding="utf-8"), "## The run engine (`orbitrig/run`)")
    named = set(re.findall(r"`(\w+\.py)`", table))
    modules = {Path(m).name for m in _modules("orbitrig/run")}
    assert modules - named == set(), "orbitrig/run modules missing from architecture.md's run engine table"
    assert named - modules == set(), "architecture.md's run engine table names modules orbitrig/run lacks"


@pytest.mark.parametrize(
    "package, heading", [("reduction", "## reduction/ (pure)"), ("daq", "## daq/"), ("drives", "## drives/")]
)
def test_interfaces_names_every_module_of_a_package(package: str, heading: str) -> None:
    section = _section(INTERFACES.read_text(encoding="utf-8"), heading)
    missing = [m for m in _modules(package) if not _names(m, section)]
    assert not missing, f"interfaces.md's {heading!r} does not describe {missing}"


def test_interfaces_names_every_module_of_sim() -> None:
    section = _section(
        INTERFACES.read_text(encoding="utf-8"), "## sim/ (imports nothing of ours but rigthreads, in sim/__main__.py)"
    )
    missing = [m for m in _modules("sim") if not _names(m, section)]
    assert not missing, f"interfaces.md's sim sections do not describe {missing}"


def test_the_list_check_sees_a_module_left_out() -> None:
    text = (
        "## daq/\n```python\n# daq/frames.py\n```\n`daq.revolutions` and averager.py\n### more\nadc.py\n## next\naux.py"
    )
    section = _section(text, "## daq/")
    assert section.endswith("adc.py")
    assert _names("daq/frames.py", section) and _names("daq/revolutions.py", section)
    assert _names("daq/averager.py", section)
    assert not _names("daq/aux.py", section)
    assert not _names("daq/aux.py", "orbitrig/daq/aux.py, daq.auxiliary, sim/aux.py")


# -- signatures -------------------------------------------------------------------------------

_HEADER = re.compile(r"#\s+((?:reduction|daq|drives|sim)/\w+\.py)((?:,\s*\w+\.py)*)")


def _documented_defs(text: str) -> list[tuple[list[str], str | None, str, list[str], int]]:
    """(modules, class or None, function, parameter names, line) of each `def` of interfaces.md's
    python blocks whose parameters are all given (`def f(...)` and a trailing `...` are left out)."""
    found = []
    for block in re.finditer(r"```python\n(.*?)```", text, re.S):
        first_line = text[: block.start()].count("\n") + 2
        lines = block.group(1).split("\n")
        modules: list[str] = []
        owner: str | None = None
        for i, line in enumerate(lines):
            if m := _HEADER.match(line):
                folder = m.group(1).rsplit("/", 1)[0]
                modules = [m.group(1)] + [f"{folder}/{n.strip()}" for n in m.group(2).split(",") if n.strip()]
                owner = None
            elif m := re.match(r"class (\w+)", line):
                owner = m.group(1)
            elif (m := re.match(r"( *)(?:async )?def (\w+)\(", line)) and modules:
                source = line.split("#")[0]
                for more in lines[i + 1 :]:
                    if source.count("(") <= source.count(")"):
                        break
                    source += " " + more.split("#")[0].strip()
                params = _params(source[m.end() - 1 :])
                if params is not None:
                    found.append((modules, owner if m.group(1) else None, m.group(2), params, first_line + i))
    return found


def _params(text: str) -> list[str] | None:
    """The parameter names of ``(a, b=1, *, c)...``; None for `(...)` or a list that ends in `...`."""
    depth = list(itertools.accumulate((ch in "([{") - (ch in ")]}") for ch in text))
    inner = text[1 : depth.index(0)].strip()
    if inner == "..." or inner.endswith(", ..."):
        return None
    args = ast.parse(f"def f({inner}): pass").body[0].args  # type: ignore[attr-defined]
    names = [a.arg for a in (*args.posonlyargs, *args.args, *args.kwonlyargs)]
    names += [a.arg for a in (args.vararg, args.kwarg) if a is not None]
    return [n for n in names if n != "self"]


def _code_params(modules: list[str], owner: str | None, name: str) -> list[str] | None:
    for module in modules:
        obj = importlib.import_module(module[:-3].replace("/", "."))
        if owner is not None:
            obj = getattr(obj, owner, None)
        func = getattr(obj, name, None)
        if func is not None:
            params = inspect.signature(func).parameters.values()
            ordered = [p for p in params if p.kind is not p.VAR_POSITIONAL and p.kind is not p.VAR_KEYWORD]
            ordered += [p for p in params if p.kind is p.VAR_POSITIONAL or p.kind is p.VAR_KEYWORD]
            return [p.name for p in ordered if p.name != "self"]
    return None


def test_interfaces_signatures_take_what_the_code_takes() -> None:
    defs = _documented_defs(INTERFACES.read_text(encoding="utf-8"))
    assert len(defs) > 30  # the parser still reads the blocks
    wrong = []
    for modules, owner, name, documented, line in defs:
        code = _code_params(modules, owner, name)
        where = f"interfaces.md:{line} {'.'.join(filter(None, (owner, name)))}"
        if code is None:
            wrong.append(f"{where}: not in {modules}")
        elif code != documented:
            wrong.append(f"{where}: documented {documented}, the code takes {code}")
    assert not wrong, "\n".join(wrong)


def test_the_signature_check_reads_defaults_keywords_and_a_trailing_ellipsis() -> None:
    assert _params('(self, url: str, *, mode="a"|"b", timeout=..., **kw) -> X') == ["url", "mode", "timeout", "kw"]
    assert _params("(a, b, ...) -> X") is None and _params("(...)") is None
    doc = (
        "```python\n# daq/frames.py\nclass FrameDecoder:\n    def feed(self, data,\n             extra) -> list\n```\n"
    )
    [(modules, owner, name, params, _)] = _documented_defs(doc)
    assert (modules, owner, name, params) == (["daq/frames.py"], "FrameDecoder", "feed", ["data", "extra"])
    assert _code_params(modules, owner, name) == ["data"]  # what the signature test then reports
