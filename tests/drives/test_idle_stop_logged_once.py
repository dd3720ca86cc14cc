"""The service's stop that no run carries out (orbitrig.service.idle_stop) logs its outcome once:
by itself when asked by an `abort`/`stop` (`log_outcome`), by `idle_stop.start` when it carries out
a request of the service's own (a signal), its log lines naming that request either way. Real
parts: the simulator's drives over Modbus TCP."""

from __future__ import annotations

import asyncio
import logging

import pytest
from support.drives_testkit import CW_EMERGENCY, SimDrives

from orbitrig.config import Drives
from orbitrig.service import idle_stop

pytestmark = pytest.mark.timeout(30)

CONFIG = Drives(timeout_s=0.5, comm_loss_timeout_s=5.0)  # spin id 1, orbit id 2
SENT = "emergency stop (OFF3) sent to both drives"


def said(caplog: pytest.LogCaptureFixture, text: str) -> list[str]:
    return [r.getMessage() for r in caplog.records if text in r.getMessage()]


def took_off3(sim: SimDrives) -> bool:
    return all(CW_EMERGENCY in [cw for _, cw in sim.models[dev].control_words] for dev in (1, 2))


async def test_an_abort_logs_its_outcome_itself(tcp_sim, caplog):
    caplog.set_level(logging.WARNING, logger="orbitrig.service.rig_service")
    assert (await idle_stop.emergency_stop(tcp_sim.url, CONFIG))[0] is None
    assert took_off3(tcp_sim)
    assert said(caplog, SENT) == [f"abort: {SENT} (no run held them)"]


async def test_a_callers_request_is_named_and_its_outcome_left_to_the_caller(tcp_sim, caplog):
    caplog.set_level(logging.WARNING, logger="orbitrig.service.rig_service")
    out = await idle_stop.emergency_stop(tcp_sim.url, CONFIG, who="abort (SIGTERM)", log_outcome=False)
    assert out[0] is None and took_off3(tcp_sim)
    assert said(caplog, "no run holds the drives")[0].startswith("abort (SIGTERM): no run holds the drives: ")
    assert said(caplog, SENT) == []


async def test_a_signals_stop_is_logged_once_naming_the_signal(tcp_sim, caplog):
    caplog.set_level(logging.WARNING, logger="orbitrig.service.rig_service")
    task = idle_stop.start(None, (tcp_sim.url, CONFIG), None, "SIGTERM")
    assert isinstance(task, asyncio.Task)
    assert (await task)[0] is None and took_off3(tcp_sim)
    await asyncio.sleep(0)  # the outcome's done callback
    assert said(caplog, SENT) == [f"abort (SIGTERM): {SENT} over a link of the service's own (no run held them)"]
