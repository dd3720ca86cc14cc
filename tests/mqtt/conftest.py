"""Fixtures of the MQTT tests: a real mosquitto per test module."""

from __future__ import annotations

from support.mqtt_helpers import broker_fixture

broker = broker_fixture()
