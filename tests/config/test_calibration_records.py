"""Calibration records (orbitrig.config.records, record_files, record_setup; docs/calibration.md):
the shipped record, writing and reading back, the active record in the rig configuration, refusals that name the file, and
`orbitrig calibrate list|show`."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from orbitrig.config import (
    CalibrationRecord,
    activate,
    digest,
    list_names,
    load_rig,
    read_record,
    rig_from_text,
    write_record,
)
from orbitrig.errors import ConfigError

from support.cli_helpers import orbitrig
from support.paths import ROOT


def _rig_copy(tmp: Path) -> Path:
    shutil.copy(ROOT / "config/rig.toml", tmp / "rig.toml")
    shutil.copytree(ROOT / "config/calibration", tmp / "calibration")
    return tmp / "rig.toml"


def _loads_record(rig, date: str = "2026-12-01T08:30:00+00:00") -> CalibrationRecord:
    data = rig.record.model_dump()
    data.update(
        date=date,
        operator="ada",
        step="loads",
        previous=rig.calibration_record,
        reference={"id": "DW-7 dead weights", "uncertainty_pct": 0.02},
        loads={"strain": {"gain": [[0.98, 0.001], [0.0, 0.99]], "gain_u": [[1e-4, 1e-4], [1e-4, 1e-4]]}},
    )
    data["uncertainty"]["fx_strain"]["gain_pct"] = 0.01
    return CalibrationRecord.model_validate(data)


def test_the_shipped_rig_configuration_names_a_record_whose_uncertainty_is_the_budget():
    rig = load_rig()
    assert rig.calibration_record in list_names(ROOT / "config/calibration")
    assert rig.record.step == "initial" and rig.calibration_uncertainty == rig.record.uncertainty
    assert rig.calibration_uncertainty.fx_strain.gain_pct == 2.5
    assert rig.record.force_gain("strain").tolist() == [[1.0, 0.0], [0.0, 1.0]]


def test_a_written_record_reads_back_is_activated_and_drives_the_budget(tmp_path):
    rig_file = _rig_copy(tmp_path)
    rig = load_rig(rig_file)
    before = rig_file.read_text()
    name, text = write_record(tmp_path / "calibration", _loads_record(rig), "a test record")
    assert name == "2026-12-01T083000Z-loads" and text.startswith("# a test record\n")
    back, back_text = read_record(tmp_path / "calibration", name)
    assert back == _loads_record(rig) and back_text == text
    with pytest.raises(ConfigError, match="exists already"):
        write_record(tmp_path / "calibration", _loads_record(rig))
    activate(rig_file, name)
    after = rig_file.read_text()
    changed = [(a, b) for a, b in zip(before.splitlines(), after.splitlines()) if a != b]
    assert len(before.splitlines()) == len(after.splitlines()) and len(changed) == 1
    assert changed[0][1].startswith(f'calibration_record = "{name}"  #')  # the comment stays
    rig2 = load_rig(rig_file)
    assert rig2.calibration_uncertainty.fx_strain.gain_pct == 0.01
    assert np.allclose(rig2.record.force_gain("strain"), [[0.98, 0.001], [0.0, 0.99]])
    assert rig2.record.force_gain("piezo").tolist() == [[1.0, 0.0], [0.0, 1.0]]
    # a run's stored copy wins over the folder (a resume uses what the run was made with)
    stored = rig_from_text(after, str(rig_file), read_record(tmp_path / "calibration", rig.calibration_record)[1])
    assert stored.calibration_uncertainty.fx_strain.gain_pct == 2.5


def test_a_missing_or_bad_record_is_refused_naming_the_file(tmp_path):
    rig_file = _rig_copy(tmp_path)
    text = rig_file.read_text()
    rig_file.write_text(text.replace(load_rig(rig_file).calibration_record, "2020-01-01T000000Z-loads"))
    with pytest.raises(ConfigError) as err:
        load_rig(rig_file)
    assert "2020-01-01T000000Z-loads" in str(err.value) and "initial" in str(err.value)  # names what exists
    bad = tmp_path / "calibration" / "2020-01-01T000000Z-loads.toml"
    bad.write_text('date = "2020-01-01T00:00:00+02:00"\noperator = "x"\nstep = "loads"\n')
    with pytest.raises(ConfigError) as err:
        load_rig(rig_file)
    assert err.value.file == str(bad) and "line 1" in str(err.value) and "UTC" in str(err.value)


def test_calibrate_list_and_show_print_the_history(tmp_path):
    rig_file = _rig_copy(tmp_path)
    rig = load_rig(rig_file)
    name, text = write_record(tmp_path / "calibration", _loads_record(rig))
    p = orbitrig("calibrate", "list", "--config", str(rig_file))
    assert p.returncode == 0, p.stderr
    lines = p.stdout.splitlines()
    assert lines[0].startswith(f"* {rig.calibration_record}") and "initial" in lines[0]  # oldest first
    assert (
        lines[1].startswith(f"  {name}") and "operator ada" in lines[1] and "DW-7 dead weights (u 0.02 %)" in lines[1]
    )
    # the dates in one column and one format (rigunits' timestamp), whatever each file spells
    dates = [re.search(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z", line) for line in lines[:2]]
    assert all(dates) and dates[0].start() == dates[1].start(), lines
    p = orbitrig("calibrate", "show", name, "--config", str(rig_file))
    assert p.returncode == 0 and f"# sha256 {digest(text)} (of this whole file: a run records it as" in p.stdout
    assert "calibration_record_sha256; the record's own sha256 line below is of its text" in p.stdout
    assert p.stdout.endswith(text)
    p = orbitrig("calibrate", "show", "2020-01-01T000000Z-none", "--config", str(rig_file))
    assert p.returncode == 2 and "no calibration record" in p.stderr and "Traceback" not in p.stderr


def test_a_record_missing_from_a_lab_copy_names_the_lab_file_line_key_and_its_records(tmp_path):
    """The lab's rig.toml names a record its calibration/ lacks: the refusal (exit 2) names that
    rig.toml, the line of calibration_record and the lab folder's records, not the shipped ones."""
    assert orbitrig("init", str(tmp_path / "lab")).returncode == 0
    shutil.copytree(tmp_path / "lab", tmp_path / "lab2")
    rig_file = tmp_path / "lab2" / "rig.toml"
    own, _ = write_record(tmp_path / "lab2" / "calibration", _loads_record(load_rig(rig_file)))
    text = rig_file.read_text()
    rig_file.write_text(text.replace(load_rig(rig_file).calibration_record, "2026-12-01T214254Z-probe"))
    line = next(n for n, t in enumerate(text.splitlines(), 1) if t.startswith("calibration_record"))
    for args in (
        ("sweep", "--sim", "--dry-run", "--out", str(tmp_path / "run")),
        ("calibrate", "show"),
        ("calibrate", "list"),
    ):
        p = orbitrig(*args, "--config", str(rig_file))
        assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
        assert f"{rig_file}: line {line}: key 'calibration_record': no calibration record" in p.stderr
        assert f"in {tmp_path / 'lab2' / 'calibration'} (records there: " in p.stderr and own in p.stderr
        assert str(ROOT / "config") not in p.stderr  # not the shipped folder


def test_a_rig_configuration_without_a_records_folder_takes_the_shipped_record(tmp_path):
    shutil.copy(ROOT / "config/rig.toml", tmp_path / "rig.toml")  # alone: the shipped record
    assert load_rig(tmp_path / "rig.toml").record == load_rig().record
    (tmp_path / "calibration").mkdir()  # a records' folder of its own: searched alone
    with pytest.raises(ConfigError) as err:
        load_rig(tmp_path / "rig.toml")
    assert err.value.file == str(tmp_path / "rig.toml")
    assert "key 'calibration_record'" in str(err.value) and "(records there: none)" in str(err.value)


@pytest.mark.parametrize("name", ["../rig", "../calibration/2026-11-26T214732Z-initial", "/etc/hostname", ""])
def test_calibrate_show_refuses_a_name_that_is_not_a_plain_record_name(tmp_path, name):
    """`calibrate show NAME` reads NAME.toml in the records' folder only: a path (``../rig``
    would print the rig.toml beside the folder) is a usage error naming the argument and the rule;
    the library's read_record refuses it too, naming the folder."""
    rig_file = _rig_copy(tmp_path)
    p = orbitrig("calibrate", "show", name, "--config", str(rig_file))
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr
    assert (
        p.stdout == "" and "Invalid value for 'NAME'" in p.stderr and "is not a calibration record name" in p.stderr
    ), p.stderr
    assert "<date>T<hhmmss>Z-<step>" in p.stderr, p.stderr
    with pytest.raises(ConfigError) as err:
        read_record(tmp_path / "calibration", name)
    assert err.value.file == str(tmp_path / "calibration") and "not a calibration record name" in str(err.value)


def test_a_step_ending_within_the_second_of_its_last_record_writes_it_at_the_next_free_second(tmp_path, capsys):
    """Two `calibrate loads` ending within one second (two --sim steps at once on one lab) lost the
    second's measurement: it stopped on "a record of that name exists already" after measuring.
    The record is now dated at the next free second, written and made active; the records
    there stay as they were."""
    import datetime as dt

    from orbitrig.cli.calibrate_records import _write

    rig_file = _rig_copy(tmp_path)
    rig = load_rig(rig_file)
    folder = tmp_path / "calibration"
    now = dt.datetime.now(dt.timezone.utc)
    measured = _loads_record(rig, now.isoformat())  # dated as the step ended
    taken = [write_record(folder, _loads_record(rig, (now + dt.timedelta(seconds=s)).isoformat()))[0] for s in (0, 1)]
    before = {p.name: p.read_bytes() for p in folder.glob("*.toml")}
    _write(rig, folder, measured, True, "Units: a test")
    (name,) = set(list_names(folder)) - {p.removesuffix(".toml") for p in before}
    assert name.endswith("-loads") and name > max(taken), (name, taken)
    assert f"calibration record {name} written to {folder}" in capsys.readouterr().out
    assert load_rig(rig_file).calibration_record == name
    written, _ = read_record(folder, name)
    assert written.model_dump(exclude={"date"}) == measured.model_dump(exclude={"date"})
    assert {p: (folder / p).read_bytes() for p in before} == before


def test_a_record_is_never_written_over_nor_through_a_link_at_its_name(tmp_path):
    """write_record creates its file new (O_EXCL, as it writes: another writer's record of the same
    second made after any look for it is not written over): a name taken, even by a dangling
    symbolic link (which a look for the file missed: the record went through it, outside the
    folder), is refused naming it; nothing is written."""
    rig = load_rig(_rig_copy(tmp_path))
    path = tmp_path / "calibration" / "2026-12-01T083000Z-loads.toml"
    path.symlink_to(tmp_path / "elsewhere.toml")
    with pytest.raises(ConfigError, match="exists already") as err:
        write_record(tmp_path / "calibration", _loads_record(rig))
    assert err.value.file == str(path) and not (tmp_path / "elsewhere.toml").exists()


def test_calibrate_list_orders_two_steps_of_one_second_as_they_were_taken(tmp_path):
    """A loads step then a delay step within one second (records dated to the millisecond as each
    is written): listed in that order, not by name (delay < loads: the delay step came first)."""
    rig_file = _rig_copy(tmp_path)
    rig, folder = load_rig(rig_file), tmp_path / "calibration"
    first = _loads_record(rig, "2026-12-01T08:30:00.100Z")
    second = CalibrationRecord.model_validate(
        first.model_dump() | {"date": "2026-12-01T08:30:00.900Z", "step": "delay", "loads": {}}
    )
    names = [write_record(folder, r)[0] for r in (first, second)]
    assert names == ["2026-12-01T083000Z-loads", "2026-12-01T083000Z-delay"]
    (folder / "2026-12-01T083000Z-runout.toml").write_text("not a record\n")  # unreadable: at its name's second
    p = orbitrig("calibrate", "list", "--config", str(rig_file))
    assert p.returncode == 0, p.stderr
    listed = [line[2:].split()[0] for line in p.stdout.splitlines()]
    assert listed == [rig.calibration_record, "2026-12-01T083000Z-runout", *names], p.stdout
    assert "08:30:00.100Z  loads" in p.stdout and "08:30:00.900Z  delay" in p.stdout
