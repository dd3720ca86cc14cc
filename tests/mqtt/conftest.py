"""Fixtures of the MQTT tests: a real mosquitto per test module."""

from __future__ import annotations

import pytest
from support.mqtt_helpers import Broker


@pytest.fixture(scope="module")
def broker(tmp_path_factory):
    b = Broker(tmp_path_factory.mktemp("broker"))
    b.start()
    yield b
    b.stop()
