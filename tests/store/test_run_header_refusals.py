"""run.json that this version cannot trust is refused, naming the file and why, with the usage
exit status (2) of every command reading a stored run: a run of another version's format (it was
read as if it were this one's), a key given twice (JSON readers differ in which one counts;
the last one was taken silently), and JSON that is no run header: not an object, or without its
format (each said in words; both were 'format None')."""

from __future__ import annotations

import shutil

import pytest

from support.cli_helpers import orbitrig

TWICE = '"format": "orbitrig-run/2",\n "format": "orbitrig-run/1",'


@pytest.mark.parametrize(
    "edit, message",
    [
        (
            lambda text: text.replace('"orbitrig-run/2"', '"orbitrig-run/9"', 1),
            "run.json: format 'orbitrig-run/9': a run of another orbitrig version; "
            "this one reads orbitrig-run/1, orbitrig-run/2",
        ),
        (
            lambda text: text.replace('"format": "orbitrig-run/2",', TWICE, 1),
            "run.json: not a readable run header (ValueError: key 'format' given twice)",
        ),
        (lambda text: "[1, 2]\n", "run.json: not a readable run header (ValueError: a JSON array, not an object)"),
        (
            lambda text: text.replace('"format": "orbitrig-run/2",', "", 1),
            "run.json: not a readable run header (ValueError: no 'format' key)",
        ),
    ],
    ids=["other-version", "key-twice", "not-an-object", "no-format"],
)
@pytest.mark.parametrize("command", [("reduce", "--model", "kc8"), ("export", "--format", "csv")])
def test_a_header_this_version_cannot_trust_exits_2(synthetic, tmp_path, edit, message, command):
    run = tmp_path / "run"
    shutil.copytree(synthetic, run)
    header = run / "run.json"
    text = header.read_text()
    assert '"format": "orbitrig-run/2",' in text
    header.write_text(edit(text))
    p = orbitrig(command[0], str(run), *command[1:])
    assert p.returncode == 2, p.stderr
    assert f"error: {header}" in p.stderr and message in p.stderr and "Traceback" not in p.stderr
    assert not (run / "export").exists() and not list(run.glob("reduce_*.csv"))
