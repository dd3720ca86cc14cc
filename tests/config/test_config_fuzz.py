"""Mutated rig and matrix files never produce a traceback: the loader either
accepts the file or raises ConfigError naming the file (and, for a bad value,
the line and key); the CLI exits 0 or 2 with a message. Property tests with a
bounded number of examples (hypothesis)."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from orbitrig.config import load_matrix, load_rig
from orbitrig.errors import ConfigError
from orbitrig.run.plan import make_plan, summarize
from rigunits import format_duration

from support.cli_helpers import orbitrig

REPO = Path(__file__).resolve().parents[2]
RIG_TEXT = (REPO / "config" / "rig.toml").read_bytes()
MATRIX_TEXT = (REPO / "config" / "matrices" / "demo.toml").read_bytes()
_VALUE = re.compile(rb"(?m)^(\s*[A-Za-z_]+\s*=\s*)([^#\n]+?)(\s*(#.*)?)$")
HOSTILE = [
    b"inf",
    b"-inf",
    b"nan",
    b"+nan",
    b"1e308",
    b"-1e308",
    b"1e-320",
    b"0",
    b"-1",
    b"99999999999999999999999",
    b"-0.0",
    b'"text"',
    b"true",
    b"[]",
    b"[inf, nan]",
    b"{}",
    b"{ a = 1 }",
    b"1979-05-27",
    b"[[1]]",
    b"''",
    b"0x7fffffffffffffff",
]


def _value_spans(text: bytes) -> list[tuple[int, int]]:
    return [(m.start(2), m.end(2)) for m in _VALUE.finditer(text)]


@st.composite
def mutated(draw, text: bytes) -> bytes:
    """``text`` with a few mutations: a value replaced by a hostile one, a line
    deleted (missing key), bytes replaced, inserted or deleted (also bytes that
    are not UTF-8)."""
    data = bytearray(text)
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["value", "value", "line", "byte", "insert", "delete"]))
        if kind == "value":
            spans = _value_spans(bytes(data))
            if spans:
                a, b = draw(st.sampled_from(spans))
                data[a:b] = draw(st.sampled_from(HOSTILE))
        elif kind == "line":
            lines = bytes(data).split(b"\n")
            del lines[draw(st.integers(0, len(lines) - 1))]
            data = bytearray(b"\n".join(lines))
        elif data:
            i = draw(st.integers(0, len(data) - 1))
            if kind == "byte":
                data[i] = draw(st.integers(0, 255))
            elif kind == "insert":
                data[i:i] = draw(st.binary(min_size=1, max_size=4))
            else:
                del data[i : i + draw(st.integers(1, 8))]
    return bytes(data)


def _load_both(tmp: Path, rig: bytes, matrix: bytes):
    (tmp / "rig.toml").write_bytes(rig)
    (tmp / "matrix.toml").write_bytes(matrix)
    problems = []
    try:
        r = load_rig(tmp / "rig.toml")
    except ConfigError as err:
        problems.append(err)
        r = None
    try:
        m = load_matrix(tmp / "matrix.toml")
    except ConfigError as err:
        problems.append(err)
        m = None
    return r, m, problems


def _check_refusal(err: ConfigError, tmp: Path) -> None:
    assert err.problems and err.file in (str(tmp / "rig.toml"), str(tmp / "matrix.toml"))
    for p in err.problems:
        assert p and "Traceback" not in p
        if "finite number" in p:
            assert re.match(r"line \d+: key '[^']+': ", p), p


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(rig=mutated(RIG_TEXT), matrix=mutated(MATRIX_TEXT))
@example(rig=RIG_TEXT.replace(b"hold_s = 2.0", b"hold_s = inf"), matrix=MATRIX_TEXT)
@example(rig=RIG_TEXT, matrix=MATRIX_TEXT.replace(b"[1000.0]", b"[1e308]"))
@example(rig=RIG_TEXT.replace(b"[bearing]", b"[bearing]\xff"), matrix=MATRIX_TEXT + b"\n\xc3")
@example(rig=RIG_TEXT, matrix=MATRIX_TEXT.replace(b"[0.3,", b"[" * 3000 + b"]" * 3000 + b" # [0.3,"))
@example(rig=RIG_TEXT, matrix=MATRIX_TEXT.replace(b"[0.3, 0.5, 0.7, 0.9, 1.2]", b"[]"))
@example(rig=RIG_TEXT.replace(b"gain = 0.1", b"gain = 1e308", 1), matrix=MATRIX_TEXT)
def test_mutated_files_load_or_are_refused_by_name(tmp_path, rig, matrix):
    r, m, problems = _load_both(tmp_path, rig, matrix)
    for err in problems:
        _check_refusal(err, tmp_path)
    if r is None or m is None:
        return
    for f in (*_floats(r), *_floats(m)):
        assert math.isfinite(f)
    try:
        steps = make_plan(m, r).steps
    except ConfigError as err:
        _check_refusal(err, tmp_path)
        return
    total = summarize(steps).duration
    assert math.isfinite(total) and format_duration(total)


DESIGN_TEXT = (REPO / "config" / "designs" / "kcd11-demo.toml").read_bytes()
DESIGN_MATRIX = MATRIX_TEXT.replace(b"ratios = [0.3, 0.5, 0.7, 0.9, 1.2]", b'design = "d.toml"').replace(
    b'directions = ["forward", "backward"]', b""
)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(design=mutated(DESIGN_TEXT))
@example(design=DESIGN_TEXT.replace(b"[0.65, 1.5]", b"[0.65]").replace(b"[163, 63]", b"[163]"))
@example(design=DESIGN_TEXT.replace(b"[0.65, 1.5]", b"[0.65, 1e308]"))
def test_mutated_design_files_load_or_are_refused_by_name(tmp_path, design):
    (tmp_path / "d.toml").write_bytes(design)
    r, m, problems = _load_both(tmp_path, RIG_TEXT, DESIGN_MATRIX)
    for err in problems:
        _check_refusal(err, tmp_path)
    if m is None:
        return
    assert len(m.orbit.ratio_list) >= 2 and all(0 < x <= 100 for x in m.orbit.ratio_list)
    try:
        assert math.isfinite(summarize(make_plan(m, r).steps).duration)
    except ConfigError as err:
        _check_refusal(err, tmp_path)


def _floats(model) -> list[float]:
    out = []
    for value in model.model_dump().values():
        stack = [value]
        while stack:
            v = stack.pop()
            if isinstance(v, float):
                out.append(v)
            elif isinstance(v, dict):
                stack.extend(v.values())
            elif isinstance(v, list):
                stack.extend(v)
    return out


CLI_CASES = [
    (RIG_TEXT, MATRIX_TEXT, 0, ""),
    (RIG_TEXT.replace(b"hold_s = 2.0", b"hold_s = inf"), MATRIX_TEXT, 2, "key 'settle.hold_s'"),
    (RIG_TEXT.replace(b"[bearing]", b"[bearing]\n# caf\xe9"), MATRIX_TEXT, 2, "not UTF-8 text"),
    (b"\xef\xbb\xbf" + RIG_TEXT, MATRIX_TEXT, 2, "rig.toml: line 1: starts with a byte order mark (BOM"),
    (RIG_TEXT.replace(b"clearance_um = 60.0", b"clearance_um = 6e-5"), MATRIX_TEXT, 2, "'bearing.clearance_um'"),
    (RIG_TEXT.replace(b"radius_mm = 19.05", b"radius_mm = 0.01905"), MATRIX_TEXT, 2, "'bearing.radius_mm'"),
    (RIG_TEXT, b"\xef\xbb\xbf" + MATRIX_TEXT, 2, "m.toml: line 1: starts with a byte order mark (BOM, bytes EF BB BF)"),
    (RIG_TEXT, MATRIX_TEXT.replace(b"[1000.0]", b"[nan]"), 2, "key 'operating.spin_rpm[0]'"),
    (RIG_TEXT, MATRIX_TEXT.replace(b'name = "demo"', b"name = 3"), 2, "key 'name'"),
    (RIG_TEXT, MATRIX_TEXT.replace(b"[0.3, 0.5, 0.7, 0.9, 1.2]", b"[]"), 2, "key 'orbit': 'ratios' has 0 value(s)"),
    (RIG_TEXT, MATRIX_TEXT.replace(b"[0.3, 0.5, 0.7, 0.9, 1.2]", b"[0.5]"), 2, "give at least 2 orbit frequencies"),
    (
        RIG_TEXT,
        MATRIX_TEXT.replace(b"ratios = [0.3, 0.5, 0.7, 0.9, 1.2]", b"ratio_start = 0.3\nratio_stop = 0.9\ncount = 1"),
        2,
        "key 'orbit.count'",
    ),
    (RIG_TEXT.replace(b"gain = 0.1", b"gain = 1e308", 1), MATRIX_TEXT, 2, "key 'channels[0].gain': gain 1e+308"),
    (RIG_TEXT.replace(b"gain = 0.1", b"gain = 0", 1), MATRIX_TEXT, 2, "key 'channels[0].gain': gain must be non-zero"),
    (RIG_TEXT.replace(b"gain = 5e-9", b"gain = -5e-9", 1), MATRIX_TEXT, 2, "key 'channels[4].gain'"),
    (RIG_TEXT.replace(b"offset = 0.0", b"offset = 1e300", 1), MATRIX_TEXT, 2, "key 'channels[0].offset'"),
    (RIG_TEXT.replace(b"gain = 0.1", b"gain = -0.1", 1), MATRIX_TEXT, 0, ""),  # a load cell's sign
]


@pytest.mark.parametrize("rig, matrix, code, says", CLI_CASES)
def test_cli_dry_run_exits_0_or_2_with_a_message(tmp_path, rig, matrix, code, says):
    (tmp_path / "rig.toml").write_bytes(rig)
    (tmp_path / "m.toml").write_bytes(matrix)
    done = orbitrig(
        "sweep",
        "--dry-run",
        "--config",
        str(tmp_path / "rig.toml"),
        "--matrix",
        str(tmp_path / "m.toml"),
        timeout=120,
        columns=None,
    )
    assert done.returncode == code, done.stderr[-2000:]
    assert "Traceback" not in done.stderr and says in done.stderr
    if code == 2:  # one line naming the file and the line
        assert re.fullmatch(r"orbitrig sweep: error: \S+\.toml: line \d+: [^\n]+\n", done.stderr), done.stderr
