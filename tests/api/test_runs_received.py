"""A run as another lab receives it: a run file of the first format (orbitrig-run/1, which
stored no channel list), a copy whose point settings or run header were damaged on the way.
What still loads loads, and what does not is named with why and where the data still is."""

from __future__ import annotations

import os
import shutil

import h5py
import pytest
import scipy.io
from nptdms import TdmsFile

import orbitrig
from orbitrig.store import journal as journal_lines
from orbitrig.store import run_file_beside
from orbitrig.store.errors import RunDirError
from orbitrig.store.h5_values import open_h5
from orbitrig.store.journal_file import deleted
from orbitrig.store.status import RunStatus
from support.cli_helpers import orbitrig as orbitrig_cli

CHANNELS = ["fx_piezo", "fy_piezo", "fx_strain", "fy_strain", "x_a", "y_a", "x_b", "y_b"]


@pytest.fixture
def first_format(sim_run, tmp_path):
    """The run's run.h5 alone in a folder, as format orbitrig-run/1 wrote it: no /channels and
    /channel_units, the channels named only by the rig configuration stored in its attributes."""
    folder = tmp_path / "v1"
    folder.mkdir()
    shutil.copy(sim_run / "run.h5", folder / "run.h5")
    with h5py.File(folder / "run.h5", "r+") as f:
        del f["channels"], f["channel_units"]
        f.attrs["format"] = "orbitrig-run/1"
    return folder


def test_a_first_format_run_names_its_channels_as_its_rig_configuration_did(sim_run, first_format):
    old, new = orbitrig.open_run(first_format), orbitrig.open_run(sim_run)
    assert old.run.channels == CHANNELS
    assert old.run.channel_units == ["N"] * 4 + ["m"] * 4
    waves = old.waveforms(0)  # was: xarray's "conflicting sizes for dimension 'channel'"
    assert waves.identical(new.waveforms(0))
    assert waves["mean"].attrs["units_fx_piezo"] == "N" and waves["mean"].attrs["units_y_b"] == "m"


def test_a_first_format_run_exports_its_waveforms_by_channel(first_format, tmp_path):
    for fmt in ("tdms", "mat"):
        p = orbitrig_cli("export", str(first_format), "--format", fmt, "--out", str(tmp_path / fmt))
        assert p.returncode == 0, p.stderr
    tdms = TdmsFile.read(tmp_path / "tdms" / "run.tdms")
    group = next(g for g in tdms.groups() if g.name.startswith("waveforms 0000 "))
    units = {c.name: c.properties["unit_string"] for c in group.channels()}
    assert [n for n in units if not n.endswith("_theta")] == CHANNELS  # was: no channel at all
    assert units["fx_piezo"] == "N" and units["y_b"] == "m" and units["x_a_theta"] == "rad"
    mat = scipy.io.loadmat(tmp_path / "mat" / "run.mat", simplify_cells=True)
    assert list(mat["run"]["channels"]) == CHANNELS
    block = next(iter(mat["points"]["p0000"]["waveforms"].values()))
    assert list(block["channels"]) == CHANNELS and block["mean"].shape[0] == 8


def test_a_first_format_run_whose_configuration_cannot_be_read_names_why_for_its_waveforms(first_format):
    with h5py.File(first_format / "run.h5", "r+") as f:
        f.attrs["rig_config"] = "[[channels]\n"  # not TOML: a configuration this version cannot read
    run = orbitrig.open_run(first_format)  # what needs no channel names still loads
    assert run.run.channels == [] and not run.coefficients.empty
    with pytest.raises(RunDirError) as err:
        run.waveforms(0)  # was: xarray's "conflicting sizes for dimension 'channel'"
    said = f"{first_format}: cannot name the stored channels: rig configuration stored in the run: not valid TOML: "
    assert str(err.value).startswith(said) and "(at line 1, column " in str(err.value)


@pytest.fixture
def copied(sim_run, tmp_path):
    return shutil.copytree(sim_run, tmp_path / "copy")


def test_a_point_whose_settings_cannot_be_read_is_named_with_why(copied):
    settings = copied / "points" / "0000" / "point.json"
    os.truncate(settings, settings.stat().st_size // 2)  # a copy cut short
    run = orbitrig.open_run(copied)
    assert run.points.empty
    with pytest.raises(KeyError) as err:
        run.table(0)
    assert err.value.args[0] == (
        f"{copied}: no operating point 0 (points: none); point 0000: {settings}: unreadable point settings "
        f"(JSONDecodeError: {run.run.unreadable[0].split('(JSONDecodeError: ', 1)[1]}"
    )
    settings.unlink()
    with pytest.raises(KeyError, match=r"no operating point 0 \(points: none\); point 0000: never begun \(no settings"):
        orbitrig.open_run(copied).fit(0, "piezo", "kcd11")


def test_a_run_directory_named_like_a_point_gives_no_point_anothers_fault(sim_run, tmp_path):
    run_dir = shutil.copytree(sim_run, tmp_path / "0001")  # runs/0001: a run named by number
    settings = run_dir / "points" / "0000" / "point.json"
    os.truncate(settings, settings.stat().st_size // 2)
    run = orbitrig.open_run(run_dir)
    with pytest.raises(KeyError) as err:
        run.table(1)
    assert err.value.args[0] == f"{run_dir}: no operating point 1 (points: none)"  # was: point 0000's file
    with pytest.raises(KeyError, match=r"\(points: none\); point 0000: .*/0001/points/0000/point.json: unreadable"):
        run.table(0)


def test_an_unreadable_run_header_points_to_the_run_file_beside_it(sim_run, copied):
    header = copied / "run.json"
    os.truncate(header, header.stat().st_size // 2)
    beside = (
        f"; {copied / 'run.h5'}, consolidated when the run ended, holds the run: read that file "
        f"(orbitrig.open_run('{copied / 'run.h5'}'), or a folder holding only it for orbitrig's commands)"
    )
    with pytest.raises(RunDirError) as err:
        orbitrig.open_run(copied)
    assert str(err.value).startswith(f"{header}: not a readable run header (JSONDecodeError: ")
    assert str(err.value).endswith(beside)
    assert orbitrig.open_run(copied / "run.h5").coefficients.equals(orbitrig.open_run(sim_run).coefficients)
    p = orbitrig_cli("export", str(copied), "--format", "csv")
    assert p.returncode == 2 and p.stderr.rstrip("\n").endswith(beside), p.stderr
    (copied / "run.h5").unlink()  # nothing whole left: the header's own fault alone
    with pytest.raises(RunDirError) as err:
        orbitrig.open_run(copied)
    assert str(err.value).endswith(")") and "run.h5" not in str(err.value)


def test_a_journal_cut_short_before_its_final_status_is_named_beside_the_run_file(sim_run, copied):
    journal = copied / "journal.jsonl"
    assert orbitrig.open_run(copied).run.warnings == []  # whole: nothing to say
    text = journal.read_bytes()
    last = text.rstrip(b"\n").rsplit(b"\n", 1)[1]
    assert b'"k":"status","status":"completed"' in last
    os.truncate(journal, len(text) - len(last) // 2 - 1)  # the copy stopped in the final status line
    run = orbitrig.open_run(copied)
    said = (
        f"warning: {journal} says the run is running, but {copied / 'run.h5'}, written only after the "
        "journal's final status, says completed: the journal was cut short or edited (1 unreadable line(s)); "
        "run.h5 holds the run's status and logs as it ended"
    )
    assert run.run.status == "running" and run.run.warnings == [said]  # was: running, and not a word
    assert orbitrig.open_run(copied / "run.h5").run.status == "completed"
    p = orbitrig_cli("export", str(copied), "--format", "csv")
    assert p.returncode == 0 and said in p.stderr.splitlines(), p.stderr
    (copied / "run.h5").unlink()  # a run cut off by a kill: no run.h5, running is all there is
    assert orbitrig.open_run(copied).run.warnings == []


def test_a_run_that_ends_while_it_is_read_is_not_said_cut_short(copied, monkeypatch):
    """A reader of a live run reads the journal (running); the writer then appends the final
    status and renames run.h5 into place; the reader finds run.h5 completed. The journal, read
    again, has that status too: nothing was cut short, nothing to warn of."""
    journal = copied / "journal.jsonl"
    text = journal.read_bytes()
    final = text.rstrip(b"\n").rsplit(b"\n", 1)[1] + b"\n"
    assert b'"k":"status","status":"completed"' in final and text.endswith(final)
    journal.write_bytes(text[: -len(final)])  # as the run still going on wrote it
    opened = []

    def ended_meanwhile(path):
        if path == copied / "run.h5" and not opened:  # the writer's order: final status, then run.h5
            opened.append(path)
            with journal.open("ab") as f:
                f.write(final)
        return open_h5(path)

    monkeypatch.setattr(run_file_beside, "open_h5", ended_meanwhile)
    run = orbitrig.open_run(copied)
    assert opened == [copied / "run.h5"]  # run.h5 was looked at, after the journal was read
    assert run.run.status == RunStatus.RUNNING and run.run.warnings == []  # was: "cut short or edited"


def test_a_resume_that_found_its_journal_missing_is_not_said_cut_short(copied):
    """A resume that finds journal.jsonl missing starts a new one with a `continued` line, then
    verifies every point, and removes the old run.h5 only before it says running: a reader in
    between finds a journal with no status beside run.h5 completed. The continued warning says
    the status was lost; nothing was cut short."""
    journal = copied / "journal.jsonl"
    journal.unlink()
    said = deleted(journal, "2026-12-08T00:00:00Z", True)
    journal.write_text(journal_lines.line("continued", at="2026-12-08T00:00:00Z", detail=said) + "\n")
    run = orbitrig.open_run(copied)
    assert run.run.status == RunStatus.RUNNING and run.run.warnings == [f"warning: {said}"]
    journal.write_text(journal.read_text() + journal_lines.status_line(RunStatus.RUNNING, "resumed") + "\n")
    warned = orbitrig.open_run(copied).run.warnings  # a status said, beside run.h5 completed: that is warned of
    assert warned[0] == f"warning: {said}" and warned[1].startswith(f"warning: {journal} says the run is running, but ")
