"""One rule for a stored run with nothing to analyse (no complete operating point: a sweep
stopped before its first point completed), the same for `export`, `report` and `reduce`: every
point named with why, nothing written or removed and no folder made, a line saying so, an
`error: nothing ...` line (report: no progress line counting nothing ahead of it) and exit 1. Bad usage stays 2 on such a run; a run with some complete
points is worked on as ever (exit 0, the others noted). `report` wrote an empty page and exited
0, `reduce` exited 2, and `export` said "RUN/export left as it was" of a folder it never made."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from orbitrig.cli import app
from support.report_synthetic import write_synthetic_run

#: each command, its extra options and what it says it did not do
COMMANDS = {
    "export": ((), "exported"),
    "report": (("--figures", "coefficients"), "drawn"),
    "reduce": (("--model", "kc8"), "reduced"),
}
NOTES = ("point 0000 not included: never completed", "point 0001 not included: never completed")


@pytest.fixture(scope="module")
def cut(tmp_path_factory):
    """A run stopped before its first point completed: two points stored, none complete."""
    return write_synthetic_run(tmp_path_factory.mktemp("cut") / "run", n_points=0, incomplete=2)


def _files(run) -> set[str]:
    return {str(p.relative_to(run)) for p in run.rglob("*")}


@pytest.mark.parametrize("command", COMMANDS)
def test_a_run_without_a_complete_point_is_nothing_to_analyse_exit_1(cut, command):
    extra, done = COMMANDS[command]
    before = _files(cut)
    res = CliRunner().invoke(app, [command, str(cut), *extra])
    assert res.exit_code == 1, res.output
    for note in NOTES:
        assert note in res.stderr
    error = f"orbitrig {command}: error: nothing {done}: the run has no complete operating point (each is named above with why)"
    assert res.stderr.splitlines()[-1] == error
    assert "figure(s) drawn" not in res.stderr  # report: no '0 of 0 point(s)' line ahead of the error
    assert _files(cut) == before  # no folder, page or CSV made
    folder = {"export": cut / "export", "report": cut / "plots"}.get(command)
    if folder is None:
        assert res.stdout == ""  # reduce: stdout carries only its table (or its CSV or JSON)
    else:
        assert res.stdout.splitlines()[-1] == f"nothing {done}: no folder written ({folder} not made)"
        assert "left as it was" not in res.stdout


@pytest.mark.parametrize("command", ["export", "report"])
def test_an_earlier_folder_is_left_as_it_was_and_said_so(tmp_path, command):
    run = write_synthetic_run(tmp_path / "run", n_points=0, incomplete=1)
    folder = run / ("export" if command == "export" else "plots")
    folder.mkdir()
    (folder / "index.html").write_text("an earlier page")
    extra, done = COMMANDS[command]
    res = CliRunner().invoke(app, [command, str(run), *extra])
    assert res.exit_code == 1, res.output
    assert f"nothing {done}: {folder} left as it was" in res.stdout
    assert [p.name for p in folder.iterdir()] == ["index.html"]
    assert (folder / "index.html").read_text() == "an earlier page"


@pytest.mark.parametrize(
    "command, bad, says",
    [
        ("export", ("--format", "xlsx"), "--format 'xlsx': one of"),
        ("report", ("--figures", "pie"), "--figures: unknown kind(s) pie"),
        ("reduce", ("--model", "kcd99"), "unknown model 'kcd99'"),
        ("reduce", ("--model", "kc8", "--freq-dep", "cubic"), "unknown freq-dep 'cubic'"),
    ],
)
def test_bad_usage_on_such_a_run_stays_exit_2(cut, command, bad, says):
    res = CliRunner().invoke(app, [command, str(cut), *bad])
    assert res.exit_code == 2, res.output
    assert says in res.stderr and "nothing" not in res.output


@pytest.mark.parametrize("command", COMMANDS)
def test_a_run_with_some_complete_points_works_as_before(tmp_path, command):
    run = write_synthetic_run(tmp_path / "run", n_points=1, incomplete=1)
    extra, done = COMMANDS[command]
    res = CliRunner().invoke(app, [command, str(run), *extra])
    assert res.exit_code == 0, res.output
    assert "point 0001 not included: never completed" in res.stderr
    assert not [line for line in res.stderr.splitlines() if line.startswith(f"orbitrig {command}: error")]
    assert f"nothing {done}" not in res.output
    written = {
        "export": run / "export" / "point_0000_piezo.csv",
        "report": run / "plots" / "coefficients_0000_piezo_kc7.png",
        "reduce": run / "reduce_kc8_none_ols.csv",
    }[command]
    assert written.is_file()
    assert not list(run.rglob("*0001_piezo*"))
