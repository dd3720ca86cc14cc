"""The run engine's state table: complete, reachable, and the one in docs/architecture.md."""

import re

import pytest

from orbitrig.run import plan, procedure, states, steps
from orbitrig.run.states import TRANSITIONS, next_state

from support.paths import ROOT


def test_every_state_is_reachable_from_idle_and_leads_back():
    reach, todo = {states.IDLE}, [states.IDLE]
    while todo:
        s = todo.pop()
        for (a, _), b in TRANSITIONS.items():
            if a == s and b not in reach:
                reach.add(b)
                todo.append(b)
    assert reach == set(states.STATES)
    # from every state but idle and faulted a run can end (fail) and stop (finish -> done)
    for s in set(states.STATES) - {states.IDLE, states.FAULTED}:
        assert next_state(s, "fail") == states.FAULTED
        assert next_state(next_state(s, "finish"), "done") == states.IDLE


def test_stop_abort_pause_and_suspension_are_distinct_events():
    assert next_state(states.RUNNING, "pause") == next_state(states.RUNNING, "suspend") == states.PAUSED
    assert next_state(states.PAUSED, "resume") == next_state(states.PAUSED, "clear") == states.RUNNING
    assert next_state(states.WAITING, "stop") == next_state(states.WAITING, "abort") == states.STOPPING
    with pytest.raises(LookupError, match="no transition for event 'confirm' in state 'running'"):
        next_state(states.RUNNING, "confirm")
    with pytest.raises(LookupError):
        next_state(states.IDLE, "stop")
    assert set(e for _, e in TRANSITIONS) == set(states.EVENTS)


def test_the_documented_table_is_the_code_table():
    doc = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    m = re.search(r"<!-- state table:.*?-->\n(.*?)\n<!-- end of state table -->", doc, re.S)
    assert m, "docs/architecture.md has no state table markers"
    assert m.group(1).strip() == states.transition_table()


def test_every_step_kind_has_one_handler_and_one_rule():
    kinds = set(steps.STEP_KINDS)
    assert kinds == {c for c in vars(steps).values() if isinstance(c, type) and issubclass(c, steps.Step)} - {
        steps.Step
    }
    assert set(procedure.BEFORE) == kinds
    assert set(procedure.PointProcedure(parts_stub()).handlers) == kinds


def test_every_step_kind_occurs_in_a_plan():
    from orbitrig import config as cfg

    p = plan.make_plan(cfg.load_matrix(), cfg.load_rig())
    # ChooseBlocks only in a sequential matrix's plan (tests/app/test_sweep_sequential.py)
    assert {type(s) for s in p.steps} == set(steps.STEP_KINDS) - {steps.ChooseBlocks}


def parts_stub():
    """Only what building the handler table reads."""
    from orbitrig.run.rig_io import Endpoints, RigAccess

    class Parts:
        access = RigAccess(Endpoints("", "", "", ""))

    return Parts()


def test_the_real_rig_is_reached_at_the_configured_transports_in_physical_time():
    from orbitrig import config as cfg
    from orbitrig.run.rig_io import OperatorHands, RigAccess, TimeScale

    rig = cfg.load_rig()
    access = RigAccess.of_rig(rig)
    t = rig.transports
    assert (access.endpoints.modbus_url, access.endpoints.adc_url) == (t.modbus_url, t.adc_url)
    assert (access.endpoints.can_channel, access.endpoints.can_interface) == (t.can_channel, t.can_interface)
    assert access.time_scale.wall(12.5) == 12.5 and TimeScale(40.0).wall(20.0) == 0.5
    assert isinstance(access.hands, OperatorHands) and access.truth is None and not access.simulated
