"""read_export (the public reader of ross_bearings.json) refuses, with
orbitrig.errors.ExportFileError naming the file, what it let through: a JSON key given twice
(the last silently won: another reader takes the first), nesting too deep for the parser
(RecursionError) and a file that cannot be read (OSError: a folder, a missing file).

Real parts: the export `orbitrig export RUN --format ross` writes, edited on disk."""

from __future__ import annotations

import json
import re

import pytest
from typer.testing import CliRunner

from orbitrig.analysis.ross_elements import read_export
from orbitrig.cli import app
from orbitrig.errors import ExportFileError, OrbitrigError


def _export(synthetic_run, tmp_path):
    res = CliRunner().invoke(app, ["export", str(synthetic_run), "--format", "ross", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    return tmp_path / "ross_bearings.json"


def test_a_key_given_twice_deep_nesting_and_an_unreadable_file_are_named(synthetic_run, tmp_path):
    path = _export(synthetic_run, tmp_path)
    text = path.read_text()
    assert read_export(path)["bearings"]  # the export itself reads
    twice = tmp_path / "twice.json"
    twice.write_text(re.sub(r"^\{", '{"bearings": [],', text, count=1))
    assert json.loads(twice.read_text())["bearings"]  # plain json: the last one wins, unsaid
    with pytest.raises(ExportFileError) as err:
        read_export(twice)
    assert str(err.value) == f"{twice}: not an orbitrig ROSS export (key 'bearings' given twice)"
    assert err.value.file == str(twice) and isinstance(err.value, (OrbitrigError, ValueError))
    deep = tmp_path / "deep.json"
    deep.write_text('{"bearings": ' + "[" * 100_000 + "]" * 100_000 + "}")
    with pytest.raises(ExportFileError, match=rf"^{deep}: not JSON of an export \(nested too deep to read\)$"):
        read_export(deep)
    for unreadable in (tmp_path, tmp_path / "missing.json"):
        with pytest.raises(ExportFileError, match=rf"^{unreadable}: cannot be read \("):
            read_export(unreadable)
