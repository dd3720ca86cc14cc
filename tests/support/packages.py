"""The distribution's top-level packages, as one list: pyproject.toml's find-include patterns
(``[tool.setuptools.packages.find]``). The tests' hooks take them from here; the lists that cannot
read pyproject.toml at run time (orbitrig.run.provenance's PACKAGES in an installed wheel, mypy's
``packages``, tools/run-tests' compileall) are checked against it (tests/test_architecture.py,
tests/cli/test_cli_run_tests.py)."""

from __future__ import annotations

import tomllib
from pathlib import Path

from support.paths import ROOT

_FIND = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]["setuptools"]["packages"]["find"]

#: the top-level packages of ours, in pyproject.toml's order (daq, drives, ..., rigunits)
PACKAGES: tuple[str, ...] = tuple(pattern.removesuffix("*") for pattern in _FIND["include"])


def sources(package: str) -> list[Path]:
    """Every Python file of ``package`` (a top-level folder of the tree: one of PACKAGES, or bench)."""
    return sorted((ROOT / package).rglob("*.py"))
