"""The benches run as modules from the repository root (``python3 -m bench.NAME``): they
import the tests' helpers (``tests.support``) and each other (``bench.NAME``) as packages,
and neither a bench nor a test edits the import path."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

from support.paths import ROOT

BENCHES = sorted((ROOT / "bench").glob("bench_*.py"))


def _imports_from_the_root(path: Path) -> bool:
    """True if the bench imports the tests' helpers or another bench (at module level)."""
    tree = ast.parse(path.read_text())
    return any(isinstance(n, ast.ImportFrom) and (n.module or "").startswith(("tests.", "bench.")) for n in tree.body)


#: benches that import the tests' helpers or another bench (each takes --help: argparse)
IMPORTING = [p.stem for p in BENCHES if _imports_from_the_root(p)]


def _path_edits(path: Path) -> list[str]:
    """'<file>:<line>' of every statement that changes sys.path (a call on it, or assigning it)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        target = None
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            target = node.func.value
        elif isinstance(node, (ast.Assign, ast.AugAssign)):
            target = node.targets[0] if isinstance(node, ast.Assign) else node.target
        if isinstance(target, ast.Attribute) and target.attr == "path" and getattr(target.value, "id", "") == "sys":
            found.append(f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}:{node.lineno}")
    return found


def test_no_bench_or_test_edits_the_import_path() -> None:
    files = [*BENCHES, *(ROOT / "tests").rglob("*.py")]
    edits = [e for f in files for e in _path_edits(f)]
    assert len(BENCHES) >= 17 and not edits, edits


def test_path_edit_finder_finds_each_kind(tmp_path: Path) -> None:
    f = tmp_path / "b.py"
    f.write_text("import sys\nsys.path.insert(0, 'x')\nsys.path = ['y']\nsys.path += ['z']\nprint(sys.argv)\n")
    assert sorted(e.rsplit(":", 1)[1] for e in _path_edits(f)) == ["2", "3", "4"]


def test_benches_import_one_another_as_a_package() -> None:
    bare = [
        f"{p.name}:{node.lineno} imports {node.module}"
        for p in BENCHES
        for node in ast.walk(ast.parse(p.read_text()))
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("bench_")
    ]
    assert not bare, bare


@pytest.mark.parametrize("name", IMPORTING)
def test_a_bench_runs_as_a_module_from_the_root(name: str) -> None:
    assert len(IMPORTING) >= 5
    done = subprocess.run(
        [sys.executable, "-m", f"bench.{name}", "--help"], cwd=ROOT, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.startswith("usage: "), done.stdout[:500]


def test_rig_time_bench_runs_through_a_designed_list_of_one_ratio() -> None:
    """README's `python3 -m bench.bench_rig_time`: kc8's designed list is one ratio (1.5), which no
    matrix may hold (two orbit frequencies at least), so the bench says the sweep has no plan for it
    instead of ending in the plan's ConfigError (a few runs per protocol: seconds)."""
    done = subprocess.run(
        [sys.executable, "-m", "bench.bench_rig_time", "3"], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert "designed ratios 1.5 x both" in done.stdout and "(sweep plan none)" in done.stdout
