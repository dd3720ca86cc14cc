"""The service's SIGTERM while its broker is gone mid-run: nobody can send it a stop or an abort,
and its own shutdown still reaches the drives. One signal stops the run at once with a ramp (OFF1),
both drives confirmed at standstill, the run stored stopped; a second one makes it the emergency
stop (OFF3), the run stored aborted. The service exits 0 either way, without its broker.

Real parts: mosquitto (stopped mid-run), `orbitrig serve --sim` and its simulator's drives."""

import re
import signal
import time

import pytest

from test_mqtt_serve import OwnRun, run_status

pytestmark = pytest.mark.timeout(120)


@pytest.mark.parametrize(
    "signals, status, stop",
    [
        (1, "stopped", r"drives: ramp stop \(OFF1\); standstill after"),
        # the second signal finds the ramp begun or not yet (load): '... (OFF3) after an abort during the ramp; ...'
        (2, "aborted", r"drives: emergency stop \(OFF3\)( after an abort during the ramp)?; standstill after"),
    ],
    ids=["one", "two"],
)
def test_a_signal_with_the_broker_gone_stops_the_run_and_both_drives(tmp_path, signals, status, stop):
    with OwnRun(tmp_path, "--speedup", "5") as own:  # a ramp of a fraction of a second
        log = next(p for p in (tmp_path / "runs").glob("*/run.log") if own.run_id in p.read_text())
        own.rc.close()
        own.broker.stop()
        for _ in range(signals):
            own.svc.proc.send_signal(signal.SIGTERM)
            time.sleep(0.05)
        assert own.svc.proc.wait(60) == 0, own.svc.text()[-3000:]
        assert run_status(tmp_path, own.run_id) == status
        text = log.read_text()
        assert re.search(stop, text) and "spin ACT 0 rpm" in text and "orbit ACT 0 rpm" in text, text[-3000:]
        assert "the service shutting down on SIGTERM" in text, text[-3000:]
