"""The pure protocol layer: topics, command validation with reasons, payloads."""

from __future__ import annotations

import datetime as dt
import json
import math

import numpy as np
import pydantic
import pytest

from orbitrig.run.events import ProgressEvent
from orbitrig.service.protocol import (
    STATES,
    Command,
    CommandError,
    parse_command,
    progress_payload,
    reply_error,
    reply_ok,
    result_payload,
    status_payload,
    topics,
)


def test_topics_under_default_prefix():
    t = topics("rig7")
    assert (t.status, t.progress, t.result, t.cmd, t.reply) == (
        "orbitrig/rig7/status",
        "orbitrig/rig7/progress",
        "orbitrig/rig7/result",
        "orbitrig/rig7/cmd",
        "orbitrig/rig7/reply",
    )
    assert topics("x", prefix="lab/a/rig").cmd == "lab/a/rig/cmd"


@pytest.mark.parametrize("rig_id", ["", "a/b", "a+", "#", "x" * 65])
def test_bad_rig_id(rig_id):
    with pytest.raises(ValueError, match="rig id"):
        topics(rig_id)


@pytest.mark.parametrize("prefix", ["", "a//b", "a/+/b", "a/#"])
def test_bad_prefix(prefix):
    with pytest.raises(ValueError, match="prefix"):
        topics("r", prefix=prefix)


@pytest.mark.parametrize(
    "payload, cmd",
    [
        (b'{"cmd":"start","id":"1","matrix":"quick"}', Command("start", "1", matrix="quick")),
        (b'{"cmd":"start","id":"1","matrix":"sweep_2.v1-b"}', Command("start", "1", matrix="sweep_2.v1-b")),
        (b'{"cmd":"pause","id":"a"}', Command("pause", "a")),
        (b'{"cmd":"resume","id":"a"}', Command("resume", "a")),
        (b'{"id":"a","cmd":"stop"}', Command("stop", "a")),
        (b'{"cmd":"abort","id":"a"}', Command("abort", "a")),
        (b'{"cmd":"status","id":"a"}', Command("status", "a")),
        (b'{"cmd":"confirm","id":"a","step":"orbit_radius:p0"}', Command("confirm", "a", step="orbit_radius:p0")),
        ('{"cmd":"pause","id":"\u00e9t\u00e9"}'.encode(), Command("pause", "\u00e9t\u00e9")),
    ],
)
def test_valid_commands(payload, cmd):
    assert parse_command(payload) == cmd


@pytest.mark.parametrize(
    "payload, cid, reason",
    [
        (b"", None, "payload is empty"),
        (b"start quick", None, "payload is not JSON: Expecting value at line 1 column 1"),
        (b'{"cmd":"stop","id":"x"', None, "payload is not JSON"),
        (b"\xff\xfe", None, "payload is not UTF-8"),
        (b"[1, 2]", None, "payload must be a JSON object, got array"),
        (b'"stop"', None, "payload must be a JSON object, got string"),
        (b'{"id":"q"}', "q", "missing field 'cmd'"),
        (b'{"cmd":3,"id":"q"}', "q", "field 'cmd' must be a string, got number"),
        (
            b'{"cmd":"launch","id":"q"}',
            "q",
            "unknown command 'launch' (known: abort, confirm, pause, resume, start, status, stop)",
        ),
        (b'{"cmd":"pause"}', None, "missing field 'id'"),
        (b'{"cmd":"pause","id":7}', None, "field 'id' must be a string, got number"),
        (b'{"cmd":"pause","id":""}', None, "field 'id' must have 1 to 128 characters"),
        (b'{"cmd":"start","id":"q"}', "q", "missing field 'matrix' for command 'start'"),
        (b'{"cmd":"start","id":"q","matrix":5}', "q", "field 'matrix' must be a string, got number"),
        (b'{"cmd":"start","id":"q","matrix":"quick","speed":3}', "q", "unexpected field 'speed' for command 'start'"),
        (b'{"cmd":"pause","id":"q","matrix":"quick"}', "q", "unexpected field 'matrix' for command 'pause'"),
        (b'{"cmd":"start","id":"q","matrix":"demo","now":true}', "q", "unexpected field 'now' for command 'start'"),
        (b'{"cmd":"confirm","id":"q"}', "q", "missing field 'step' for command 'confirm'"),
        (b'{"cmd":"confirm","id":"q","step":null}', "q", "field 'step' must be a string, got null"),
        (b'{"cmd":"confirm","id":"q","step":""}', "q", "field 'step' must be 1 to 128 printable characters"),
    ],
)
def test_bad_commands_have_precise_reasons(payload, cid, reason):
    with pytest.raises(CommandError) as info:
        parse_command(payload)
    assert info.value.id == cid
    assert reason in info.value.reason


@pytest.mark.parametrize(
    "matrix",
    [
        "../quick",
        "/etc/passwd",
        "sub/quick",
        "..",
        ".hidden",
        "a\\b",
        "~root",
        "quick\n",
        "",
        "x" * 65,
        "C:quick",
        "a..b",
    ],
)
def test_matrix_must_be_a_name_not_a_path(matrix):
    with pytest.raises(CommandError, match="not a path") as info:
        parse_command(json.dumps({"cmd": "start", "id": "m", "matrix": matrix}))
    assert info.value.id == "m"


def test_several_problems_are_all_named():
    with pytest.raises(CommandError) as info:
        parse_command(b'{"cmd":"start","matrix":1,"extra":2}')
    reason = info.value.reason
    assert "missing field 'id'" in reason
    assert "unexpected field 'extra'" in reason
    assert "field 'matrix' must be a string" in reason


def test_oversized_payload_refused():
    with pytest.raises(CommandError, match="too large"):  # (a stop or abort is read whole: test_abort_payloads_*)
        parse_command(b'{"cmd":"status","id":"a","x":"' + b"x" * 5000 + b'"}')


def test_status_payload():
    since = dt.datetime(2026, 1, 2, 3, 4, 5, 678000, tzinfo=dt.timezone.utc)
    obj = json.loads(status_payload("running", "run-1", since, "point 1"))
    assert obj == {"state": "running", "run_id": "run-1", "since": "2026-01-02T03:04:05.678Z", "message": "point 1"}
    for state in STATES:
        assert json.loads(status_payload(state))["state"] == state
    obj = json.loads(status_payload("idle", since=0.0))
    assert obj["since"] == "1970-01-01T00:00:00.000Z" and obj["run_id"] is None
    with pytest.raises(ValueError, match="unknown state 'busy'"):
        status_payload("busy")


def test_progress_payload_keys():
    label = "w1000rpm_pr0.4826MPa_b0.4_es0.15_ed0.1"
    # point 2 of 5, block 3 of 8 with 25 of its 50 revolutions: (1 + (2 + 0.5) / 8) / 5
    obj = json.loads(progress_payload(ProgressEvent("r", 2, 5, 3, 8, 25, 12.5, label, 50)))
    assert obj == {
        "run_id": "r",
        "point": 2,
        "points": 5,
        "frequency": 3,
        "frequencies": 8,
        "revolutions": 25,
        "eta_s": 12.5,
        "point_label": label,
        "block_revolutions": 50,
        "fraction": 0.2625,
    }
    # the block's acquisition done: counted whole, whatever its count (an adaptive block stops short)
    done = json.loads(progress_payload(ProgressEvent("r", 2, 5, 8, 8, 30, 0.0, label, 50, acquired=True)))
    assert done["fraction"] == 0.4
    assert json.loads(progress_payload(ProgressEvent("r", 0, 0, 0, 0, 0, None)))["fraction"] == 0.0
    # a run's status names its latest progress: the same object as the progress message (an extension)
    waiting = json.loads(
        status_payload("waiting", "r", 0.0, "set by hand", progress=ProgressEvent("r", 2, 5, 3, 8, 25, 12.5, label, 50))
    )
    assert waiting["progress"] == obj and waiting["state"] == "waiting"
    assert "progress" not in json.loads(status_payload("waiting", "r", 0.0, "set by hand"))


def test_result_payload_is_plain_json():
    payload = {
        "point": 0,
        "spin_rpm": np.float64(1200.0),
        "coefficients": {"Kxx": np.float32(1.5e7)},
        "orbit_hz": np.array([1.0, 2.0]),
        "bad": math.nan,
        "z": 1 + 2j,
        "ok": np.bool_(True),
    }
    obj = json.loads(result_payload("r9", payload))
    assert obj == {
        "run_id": "r9",
        "point": 0,
        "point_name": "0000",  # the run files' name of the point (orbitrig.store.layout.point_name)
        "spin_rpm": 1200.0,
        "coefficients": {"Kxx": 1.5e7},
        "orbit_hz": [1.0, 2.0],
        "bad": None,
        "z": [1.0, 2.0],
        "ok": True,
    }
    assert json.loads(result_payload("r9", {"run_id": "own"}))["run_id"] == "own"


@pytest.mark.parametrize(
    ("settings", "name"),
    [({"index": 3, "point": 3}, "0003"), ({"index": np.int64(12)}, "0012"), ({"point": 10000}, "10000")],
)
def test_result_payload_names_the_point_as_the_run_files(settings, name):
    assert json.loads(result_payload("r9", settings))["point_name"] == name


@pytest.mark.parametrize("settings", [{}, {"index": None}, {"index": True}, {"index": "3"}])
def test_result_payload_without_a_point_index_names_no_point(settings):
    assert "point_name" not in json.loads(result_payload("r9", settings))


def test_result_payload_times_are_the_house_timestamps():
    local = dt.timezone(dt.timedelta(hours=2))
    when = dt.datetime(2026, 11, 27, 3, 30, 5, 123456, tzinfo=local)
    obj = json.loads(result_payload("r9", {"at": when, "day": dt.date(2026, 11, 27)}))
    assert obj["at"] == "2026-11-27T01:30:05.123Z"
    assert obj["day"] == "2026-11-27"


def test_replies():
    assert json.loads(reply_ok("a")) == {"id": "a", "ok": True}
    assert json.loads(reply_error(None, "no")) == {"id": None, "ok": False, "error": "no"}


@pytest.mark.parametrize(
    "payload, cid, ignored",
    [
        (b'{"cmd":"stop","id":"q","now":true}', "q", "unexpected field 'now' for command 'stop'"),
        (b'{"cmd":"abort"}', None, "missing field 'id'"),
        (b'{"cmd":"abort","id":7,"reason":"smoke"}', None, "field 'id' must be a string"),
    ],
)
def test_stop_and_abort_are_always_accepted(payload, cid, ignored):
    """docs/protocols/mqtt.md: stop and abort are always accepted, even with wrong fields."""
    cmd = parse_command(payload)
    assert cmd.cmd in ("stop", "abort") and cmd.id == cid
    assert any(ignored in problem for problem in cmd.ignored)


def test_a_payload_that_cannot_be_read_as_abort_is_still_refused():
    with pytest.raises(CommandError, match="missing field 'cmd'"):
        parse_command(b'{"command":"abort","id":"a"}')


@pytest.mark.parametrize(
    "payload",
    [
        b"[" * 1500 + b"]" * 1500,
        b'{"cmd":"status","id":"d","x":' + b"[" * 1300 + b"]" * 1300 + b"}",
        "[" * 1400 + "]" * 1400,
    ],
    ids=["array", "inside-a-status", "text"],
)
@pytest.mark.parametrize("recursion_limit", [None, 100_000])
def test_deep_nesting_is_refused_not_raised(payload, recursion_limit):
    """json.loads raises RecursionError on deep nesting, or parses it when a library
    in the process has raised the recursion limit: either way it is refused."""
    import sys

    before = sys.getrecursionlimit()
    sys.setrecursionlimit(recursion_limit or before)
    try:
        with pytest.raises(CommandError, match="nested too deeply"):
            parse_command(payload)
    finally:
        sys.setrecursionlimit(before)


@pytest.mark.parametrize(
    "payload",
    [
        b'{"cmd":"stop","id":"' + b"[" * 100 + b'"}',
        b'{"cmd":"stop","id":"a\\"' + b"[" * 40 + b'"}',
    ],
)
def test_brackets_inside_strings_do_not_count_as_nesting(payload):
    assert parse_command(payload).cmd == "stop"


def test_commands_are_the_models():
    """The command table is derived from the pydantic models, one per argument set."""
    from orbitrig.service.protocol import COMMAND_FIELDS, ConfirmCommand, StartCommand

    assert COMMAND_FIELDS == {
        "start": ("matrix",),
        "confirm": ("step",),
        "pause": (),
        "resume": (),
        "stop": (),
        "abort": (),
        "status": (),
    }
    assert StartCommand.model_validate({"cmd": "start", "id": "1", "matrix": "quick"}).matrix == "quick"
    with pytest.raises(pydantic.ValidationError):
        ConfirmCommand.model_validate({"cmd": "confirm", "id": "1", "step": 5})  # strict: no coercion


@pytest.mark.parametrize(
    "payload, reason",
    [
        (b'{"cmd":"pause","id":true}', "field 'id' must be a string, got boolean"),
        (b'{"cmd":"start","id":"q","matrix":["quick"]}', "field 'matrix' must be a string, got array"),
        (b'{"cmd":"confirm","id":"q","step":{"a":1}}', "field 'step' must be a string, got object"),
        (b'{"cmd":"status","id":"q","cmd2":1}', "unexpected field 'cmd2' for command 'status'"),
        (b'{"cmd":"resume","id":"' + b"x" * 129 + b'"}', "field 'id' must have 1 to 128 characters"),
        # pydantic's own words name no field ("String should have at least 1 character"): the reply does
        (
            b'{"cmd":"start","id":"q","matrix":"demo","by":""}',
            "field 'by' of command 'start': String should have at least 1 character",
        ),
        (
            b'{"cmd":"pause","id":"q","by":"' + b"a" * 65 + b'"}',
            "field 'by' of command 'pause': String should have at most 64 characters",
        ),
    ],
)
def test_every_wrong_field_has_its_reason(payload, reason):
    with pytest.raises(CommandError) as info:
        parse_command(payload)
    assert info.value.reason == reason


def test_abort_with_several_problems_is_accepted_and_lists_them():
    cmd = parse_command(b'{"cmd":"abort","id":"","why":1,"how":2}')
    assert cmd.cmd == "abort" and cmd.id is None
    assert len(cmd.ignored) == 3 and "unexpected field 'how' for command 'abort'" in cmd.ignored


def test_commands_are_read_as_the_closed_set_of_names():
    from orbitrig.run.states import RunCommand
    from orbitrig.service.protocol import COMMAND_WORDS, Query

    assert parse_command(json.dumps({"cmd": "pause", "id": "a"})).cmd is RunCommand.PAUSE
    assert parse_command(json.dumps({"cmd": "status", "id": "a"})).cmd is Query.STATUS
    assert parse_command(json.dumps({"cmd": "start", "id": "a", "matrix": "m"})).cmd is RunCommand.START
    loose = parse_command(json.dumps({"cmd": " STOP ", "id": "a"}))
    assert loose.cmd is RunCommand.STOP and loose.ignored == ("field 'cmd' ' STOP ' read as 'stop'",)
    assert parse_command(json.dumps({"cmd": "abort", "id": "a", "x": 1})).cmd is RunCommand.ABORT
    assert set(COMMAND_WORDS) == {*RunCommand, *Query}
