"""Fixtures of the MQTT tests: a real mosquitto per test module; a real PostgreSQL server for the
service's catalog."""

from __future__ import annotations

from support.mqtt_helpers import broker_fixture
from support.pg_server import postgres_server  # noqa: F401 - fixture

broker = broker_fixture()
