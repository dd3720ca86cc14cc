"""A run that waits a long time between two completed points (a flood of state changes,
commands and run.log lines: a flapping suspend trip, an operator pausing and resuming)
grows its journal and run.log by a bounded number of lines; what was left out is counted,
and the newest lines are kept when the interval closes (a point completes, the run ends)."""

from __future__ import annotations

import json

import h5py
import pytest
from support.report_synthetic import write_synthetic_run

from orbitrig.store.quota import COMMANDS_HEAD, COMMANDS_TAIL, RUN_LOG_HEAD, RUN_LOG_TAIL
from orbitrig.store.records import EVENTS_KEPT, MONITOR_ROWS_KEPT
from orbitrig.store.writer import RunStore
from orbitrig.store.status import RunStatus

pytestmark = pytest.mark.timeout(120)
FLOOD = 4_000  # state changes, commands and run.log lines while no point completes


def kinds(path) -> dict[str, int]:
    out: dict[str, int] = {}
    for line in path.read_text().splitlines():
        k = json.loads(line)["k"]
        out[k] = out.get(k, 0) + 1
    return out


def test_a_long_wait_grows_the_logs_by_a_bounded_amount(tmp_path):
    run = write_synthetic_run(tmp_path / "run", n_points=1, incomplete=0, finished=False)
    store = RunStore.open_existing(run)
    before, log_before = kinds(store.layout.journal), 0  # the synthetic run wrote no run.log
    for i in range(FLOOD):
        state = ("paused", "running")[i % 2]
        store.logs.add("events", (float(i), state, f"flood {i}"))
        store.logs.add("can", (float(i),) + (0.0,) * 13)
        store.command(("pause", "resume")[i % 2], "alice", f"#{i}")  # one run.log line each
        store.log(f"[{state}] flood {i}")
    store.flush_logs()
    grown = {k: n - before.get(k, 0) for k, n in kinds(store.layout.journal).items() if n > before.get(k, 0)}
    # the first COMMANDS_HEAD commands are journal lines of their own; the rows wait for the next write
    assert grown == {"command": COMMANDS_HEAD, "event": EVENTS_KEPT + 1, "can": MONITOR_ROWS_KEPT}, grown
    assert len(store.log_path.read_text().splitlines()) - log_before == RUN_LOG_HEAD

    store.set_status(RunStatus.STOPPED, "after the wait")  # closes the interval: counts and the newest lines
    journal = [json.loads(line) for line in store.layout.journal.read_text().splitlines()]
    commands = [r for r in journal if r["k"] == "command"]
    assert len(commands) == COMMANDS_HEAD + 1 + COMMANDS_TAIL
    left = commands[COMMANDS_HEAD]
    assert left["command"] == "(left out)" and left["detail"].startswith(f"{FLOOD - COMMANDS_HEAD - COMMANDS_TAIL} ")
    assert commands[-1]["detail"] == f"#{FLOOD - 1}"  # the newest command is kept
    events = [r for r in journal if r["k"] == "event"]
    assert events[-EVENTS_KEPT - 1]["message"].startswith(f"{FLOOD - EVENTS_KEPT} earlier events")
    assert events[-1]["message"] == f"flood {FLOOD - 1}"

    text = store.log_path.read_text().splitlines()[log_before:]
    assert len(text) == RUN_LOG_HEAD + 1 + RUN_LOG_TAIL
    assert f"{2 * FLOOD - RUN_LOG_HEAD - RUN_LOG_TAIL} left out, the newest {RUN_LOG_TAIL} follow" in text[RUN_LOG_HEAD]
    assert text[-1].endswith(f"[running] flood {FLOOD - 1}")
    with h5py.File(run / "run.h5") as f:  # run.h5 shows the same bounded logs
        assert len(f["logs/commands"]) == COMMANDS_HEAD + 1 + COMMANDS_TAIL
        assert len(f["logs/can"]) == MONITOR_ROWS_KEPT
