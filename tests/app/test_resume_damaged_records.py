"""A resume of a run whose records are damaged says which file and which field, with the usage
exit status (2), before anything starts; it ended in a traceback (exit 1: KeyError, ValueError,
TypeError) or ran on something else than the run recorded:

- run.json without a field a resume needs (rig_config), or a field of the wrong type (a
  point_order of strings, a sim_scenario that is no object: the default scenario was run
  instead, channels that are no array: a TypeError at the first block);
- a point_order that is no order of the stored matrix's points (it was said as matrix_config's);
- a commit record (complete.json) that parses but is not an object of files: its point is
  set aside as damaged and measured again (an AttributeError ended the resume and the report).

Real parts: the `orbitrig` command line on the simulator, a real run's files edited. The refusals
and dry runs, which start nothing, run in the test's process; a resume that measures, in its own."""

from __future__ import annotations

import json
import shutil

import pytest

from support.cli_helpers import orbitrig, orbitrig_here
from support.store_checks import small_matrix

pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished two-point run on the simulator."""
    tmp = tmp_path_factory.mktemp("damaged")
    matrix, out = tmp / "two.toml", tmp / "run"
    matrix.write_text(small_matrix("two", 8))
    p = orbitrig("sweep", "--sim", "--matrix", str(matrix), "--out", str(out), "--speedup", "50", "--no-draw-figures")
    assert p.returncode == 0, p.stderr
    return out


def _copy(finished, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(finished, run)
    (run / "run.h5").unlink()
    return run


@pytest.mark.parametrize(
    "key, value, said",
    [
        ("rig_config", None, "no 'rig_config' field: the run cannot be resumed"),
        (
            "point_order",
            ["a", "b"],
            "not a readable run header (field 'point_order': an array of integers expected, "
            'found a JSON array ["a", "b"])',
        ),
        ("point_order", [0], "run.json:point_order: [0] is not an order of the stored matrix's 2 operating points"),
        (
            "sim_scenario",
            ["x"],
            "field 'sim_scenario': an object of strings name and text expected, found a JSON array",
        ),
        ("channels", 3, "field 'channels': an array of strings expected, found a JSON number 3"),
        ("sim", "yes", "field 'sim': true or false expected, found a JSON string \"yes\""),
    ],
    ids=["no-rig-config", "order-of-strings", "order-too-short", "scenario-array", "channels-number", "sim-string"],
)
@pytest.mark.parametrize("dry", [True, False], ids=["dry-run", "resume"])
def test_a_damaged_header_field_is_named(finished, tmp_path, key, value, said, dry):
    run = _copy(finished, tmp_path)
    (run / "points" / "0001" / "complete.json").unlink()  # a point left to measure
    header = json.loads((run / "run.json").read_text())
    if value is None:
        del header[key]
    else:
        header[key] = value
    (run / "run.json").write_text(json.dumps(header, indent=1))
    p = orbitrig_here("sweep", "--sim", *(["--dry-run"] if dry else []), "--resume", str(run), "--speedup", "50")
    assert p.returncode == 2, p.stderr
    assert f"error: {run / 'run.json'}" in p.stderr and said in p.stderr, p.stderr
    assert "Traceback" not in p.stderr and "simulator scenario of the run" not in p.stderr
    assert not (run / "aside").exists() and not (run / "run.h5").exists()  # nothing started


@pytest.mark.parametrize("record", [{"point": 1, "files": ["point.json"]}, {"point": 1, "files": {"point.json": "x"}}])
def test_a_commit_record_of_the_wrong_shape_sets_its_point_aside(finished, tmp_path, record):
    run = _copy(finished, tmp_path)
    (run / "points" / "0001" / "complete.json").write_text(json.dumps(record))
    dry = orbitrig_here("sweep", "--sim", "--dry-run", "--resume", str(run))
    assert dry.returncode == 0 and "resume: 1 of 2 points complete (0000)" in dry.stdout, dry.stderr
    p = orbitrig("sweep", "--sim", "--resume", str(run), "--speedup", "50", "--no-draw-figures")
    assert p.returncode == 0, p.stderr
    assert "point 0001 set aside as aside/0001.damaged.1 (commit record unreadable (ValueError: 'files' is not" in (
        p.stderr
    )
    assert (run / "aside" / "0001.damaged.1" / "complete.json").read_text() == json.dumps(record)  # kept
    assert "run completed: all points completed  (2 of 2 points complete" in p.stderr.replace("\n", " ")


def test_a_resume_runs_the_stored_scenario_and_refuses_another_or_a_damaged_one(finished, tmp_path):
    """The run's scenario (the default: paper) is the resume's; a --sim-config of the same text is
    taken, one of another text refused (exit 2), as is a stored scenario the simulator cannot parse,
    named by run.json's field. Dry runs: nothing starts."""
    run = _copy(finished, tmp_path)
    (run / "points" / "0001" / "complete.json").unlink()  # a point left to measure
    dry = ("sweep", "--sim", "--dry-run", "--resume", str(run))
    same = orbitrig_here(*dry, "--sim-config", "paper")
    assert same.returncode == 0 and "simulator scenario of the run: " in same.stderr, same.stderr
    other = orbitrig_here(*dry, "--sim-config", "clean")
    assert other.returncode == 2 and "clean.toml" in other.stderr, other.stderr
    assert "differs from the simulator scenario of the run being resumed" in other.stderr, other.stderr
    header = json.loads((run / "run.json").read_text())
    header["sim_scenario"]["text"] = "[bearing\n"
    (run / "run.json").write_text(json.dumps(header, indent=1))
    damaged = orbitrig_here(*dry)
    assert damaged.returncode == 2 and "--sim-config" in damaged.stderr, damaged.stderr
    assert "run.json: sim_scenario (" in damaged.stderr and "Traceback" not in damaged.stderr, damaged.stderr
