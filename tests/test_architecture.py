"""The import rules of docs/architecture.md, checked on the source text.

sim must stay independent of the code under test (a shared sign or scale would
cancel out), reduction must stay pure, and imports flow one way.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
OURS = ("daq", "drives", "reduction", "sim", "orbitrig")

# package -> packages of ours it may import (module-level or inside functions)
ALLOWED = {
    "reduction": set(),
    "sim": set(),
    "daq": {"reduction"},
    "drives": {"reduction.errors"},
    "orbitrig": {"daq", "drives", "reduction", "sim"},
}
# I/O libraries the pure numerical core must never import
IO_MODULES = ("serial", "socket", "asyncio", "can", "pymodbus", "aiomqtt", "h5py", "typer", "rich")


def _imports(path: Path) -> list[tuple[int, str]]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.lineno, node.module))
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
    assert _permitted("drives", "reduction.errors")
    assert _permitted("orbitrig", "sim.rig")
    assert _permitted("sim", "numpy")
