"""A failed connect's words say what happened: its time in seconds as a person reads them (120 s,
not 1.2e+02 s), and a connect that pymodbus gave up before the time ran out without an error is
not called a timeout. The drives' server is the simulator's real Modbus TCP server; pymodbus
saying no without an error (a fault the real server cannot be made to produce) is a create that
hands back no transport."""

from __future__ import annotations

import time

import pytest

from drives.connection import _why, new_connection, open_connection
from drives.errors import DriveConnectError
from drives.link_url import parse_modbus_url

pytestmark = pytest.mark.timeout(30)


@pytest.mark.parametrize(("seconds", "said"), [(1.5, "1.5"), (120.0, "120"), (0.1 + 0.2, "0.3"), (600.0, "600")])
def test_the_time_a_connect_was_given_reads_in_plain_seconds(seconds, said):
    assert f"no answer to the connection within {said} s (" in _why(TimeoutError(), seconds)


async def test_a_connect_refused_without_an_error_before_its_time_is_not_called_a_timeout(tcp_sim):
    client = new_connection(parse_modbus_url(tcp_sim.url), tcp_sim.url, timeout=1.0)

    async def no_transport() -> tuple[None, None]:
        return None, None

    client.ctx.call_create = no_transport
    t0 = time.monotonic()
    with pytest.raises(DriveConnectError) as failed:
        await open_connection(client, tcp_sim.url, 5.0)
    assert time.monotonic() - t0 < 1.0
    said = str(failed.value)
    assert said.startswith(f"cannot connect to {tcp_sim.url}: the connection was not made"), said
    assert "not a timeout: before its 5 s ran out" in said and "no answer" not in said
    assert not client.connected
