"""The service's stop that no run carries out (orbitrig.service.idle_stop) tries the drives' link
once more when its first connect fails: a gateway that refused the first connection (rebooting,
busy for a moment) still gets the emergency stop; one that refuses both is said so, both failures
named. Real parts: the simulator's drives over Modbus TCP behind a relay whose socket listens only
once the first connect has been refused."""

from __future__ import annotations

import logging
import socket
import threading

import pytest
from support.drives_testkit import CW_EMERGENCY, SimDrives
from support.mqtt_helpers import CutProxy

from orbitrig.config import Drives
from orbitrig.service import idle_stop

pytestmark = pytest.mark.timeout(30)

CONFIG = Drives(timeout_s=0.5, comm_loss_timeout_s=5.0)  # spin id 1, orbit id 2


class LateGateway(logging.Handler):
    """A TCP relay to the drives at 127.0.0.1:`port` that refuses connections (its socket bound,
    not listening) until the idle stop says it tries once more, then relays them."""

    def __init__(self, port: int) -> None:
        super().__init__()
        self.target = ("127.0.0.1", port)
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.url = f"tcp://127.0.0.1:{self.sock.getsockname()[1]}"
        self.listening = False

    def emit(self, record: logging.LogRecord) -> None:
        if "trying once more" in record.getMessage() and not self.listening:
            self.listening = True
            self.sock.listen(4)
            threading.Thread(target=self._relay, daemon=True).start()

    def _relay(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            up = socket.create_connection(self.target)
            for a, b in ((conn, up), (up, conn)):
                threading.Thread(target=CutProxy._pump, args=(a, b), daemon=True).start()


@pytest.fixture
def gateway(tcp_sim: SimDrives):
    gw = LateGateway(tcp_sim.endpoint.port)
    logger = logging.getLogger("orbitrig.service.rig_service")
    logger.addHandler(gw)
    try:
        yield gw
    finally:
        logger.removeHandler(gw)
        gw.sock.close()


async def test_an_abort_whose_first_connect_is_refused_gets_through_on_the_second(tcp_sim, gateway):
    error, detail = await idle_stop.emergency_stop(gateway.url, CONFIG)
    assert gateway.listening  # the first connect was refused
    assert error is None, error
    assert detail == "emergency stop (OFF3) sent to both drives over a link of the service's own (no run held them)"
    for dev in (1, 2):
        assert CW_EMERGENCY in [cw for _, cw in tcp_sim.models[dev].control_words], dev


async def test_an_abort_refused_twice_is_said_not_sent_naming_both_failures(tcp_sim, gateway):
    gateway.listening = True  # it never listens
    error, detail = await idle_stop.emergency_stop(gateway.url, CONFIG)
    assert detail is None and error.startswith("emergency stop NOT sent (no run holds the drives): "), error
    assert "cannot open their link (tried twice): " in error and error.count("cannot connect to") == 2, error
    assert error.endswith("use the rig's emergency stop"), error
