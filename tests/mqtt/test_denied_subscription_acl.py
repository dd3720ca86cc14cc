"""A broker that grants a subscription its ACL denies (mosquitto 2.0: SUBACK granted, then
nothing delivered) or refuses the service's publications (PUBACK 135) does not go unnoticed,
against a real mosquitto with the shipped accounts:

- the main connection checks every connection end to end (its own status must come back to
  it): a service whose topic prefix the ACL does not cover logs an error naming its account
  and the ACL lines it needs, and so does each publication the broker refuses;
- the abort connection, which may publish nothing, is watched through the aborts the main
  connection reads: one that does not come on the abort connection too is an error naming
  the abort account and its ACL line, and the abort connection no longer counts as up;
- with the shipped ACL both connections pass their checks, and say nothing.
"""

from __future__ import annotations

import asyncio
import json
import logging
from pathlib import Path

import pytest

import support.mqtt_helpers as mh
from orbitrig.service import abort_link, link
from orbitrig.service.rig_service import BrokerSettings, RigService, ServiceSettings
from orbitrig.service.settings import AbortAccount
from support.mqtt_helpers import ACCOUNTS, Broker, Watcher, serving
from support.polling import until

ABORT_LINE = "user orbitrig-service-abort\ntopic read orbitrig/+/abort\n"


@pytest.fixture
def short_checks(monkeypatch):
    monkeypatch.setattr(link, "ECHO_S", 4.0, raising=False)
    monkeypatch.setattr(abort_link, "MISSING_S", 2.0, raising=False)


@pytest.fixture
def no_abort_acl(tmp_path):
    """A broker whose ACL lacks the abort account's only line (the account has no rights)."""
    acl = tmp_path / "acl"
    shipped = mh.EXAMPLE_ACL.read_text()
    assert ABORT_LINE in shipped
    acl.write_text(shipped.replace(ABORT_LINE, "user orbitrig-service-abort\n"))
    b = Broker(tmp_path / "broker")
    b.conf.write_text(b.conf.read_text().replace(str(mh.EXAMPLE_ACL), str(acl)))
    with b:
        yield b


def _service(broker: Broker, tmp_path: Path, rig: str, *, prefix: str | None = None, abort: bool = False):
    settings = ServiceSettings(
        rig_id=rig, matrices_dir=tmp_path, prefix=prefix, reconnect_initial=0.2, reconnect_max=0.5
    )
    account = AbortAccount("orbitrig-service-abort", ACCOUNTS["orbitrig-service-abort"]) if abort else None
    creds = BrokerSettings.from_url(
        broker.url, username="orbitrig-service", password=ACCOUNTS["orbitrig-service"], abort=account
    )
    return RigService(settings, creds, engine_factory=None, load_matrix=None)


def _errors(caplog, logger: str) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == logger and r.levelno >= logging.ERROR]


async def test_a_prefix_the_acl_does_not_cover_is_an_error(broker, tmp_path, caplog, short_checks):
    caplog.set_level(logging.INFO)
    service = _service(broker, tmp_path, "rig1", prefix="lab/rig1")
    async with serving(service):
        await until(
            lambda: any("topic read lab/rig1/cmd" in e for e in _errors(caplog, "orbitrig.service.link")),
            30,
            "an error: the service's own status did not come back",
        )
        errors = _errors(caplog, "orbitrig.service.link")
        deaf = next(e for e in errors if "topic read lab/rig1/cmd" in e)
        assert "'orbitrig-service'" in deaf and "did not come back on lab/rig1/status" in deaf, deaf
        assert "topic read lab/rig1/abort" in deaf and "user orbitrig-service" in deaf, deaf
        refused = [e for e in errors if "a message on lab/rig1/status" in e]  # the broker's PUBACK 135
        assert refused and "135" in refused[0] and "topic readwrite lab/rig1/status" in refused[0], errors
        assert not service.link.delivery.verified
        assert "did not come back" in (service.link.delivery.problem or "")


async def test_an_abort_account_denied_its_topic_is_an_error(no_abort_acl, tmp_path, caplog, short_checks):
    caplog.set_level(logging.INFO)
    service = _service(no_abort_acl, tmp_path, "deaf-rig", abort=True)
    watch = Watcher(no_abort_acl, "orbitrig/deaf-rig/reply")
    try:
        async with serving(service):
            await until(lambda: service.abort_link.up, 30, "the abort connection subscribed")
            assert service.abort_link.refused is None  # (the broker granted the subscription)
            done = await asyncio.to_thread(
                no_abort_acl.pub, "orbitrig/deaf-rig/abort", json.dumps({"cmd": "abort", "id": "a1"})
            )
            assert done.returncode == 0, done.stderr
            await until(lambda: len(watch.messages) >= 1, 15, "the abort answered (through the main connection)")
            await until(
                lambda: _errors(caplog, "orbitrig.service.abort_link"), 20, "an error: the abort connection is deaf"
            )
            error = _errors(caplog, "orbitrig.service.abort_link")[0]
            assert "'orbitrig-service-abort'" in error and "user orbitrig-service-abort" in error, error
            assert "topic read orbitrig/deaf-rig/abort" in error, error
            assert not service.abort_link.up  # it takes no abort: the main connection is not held for it
            assert "did not come on the abort connection" in (service.abort_link.delivery.problem or "")
            await asyncio.sleep(1.0)
            assert [m.json()["id"] for m in watch.messages] == ["a1"]
    finally:
        watch.close()


async def test_the_shipped_acl_passes_both_checks(broker, tmp_path, caplog, short_checks):
    caplog.set_level(logging.INFO)
    service = _service(broker, tmp_path, "fine-rig", abort=True)
    watch = Watcher(broker, "orbitrig/fine-rig/reply")
    try:
        async with serving(service):
            await until(lambda: service.abort_link.up, 30, "the abort connection subscribed")
            await until(lambda: service.link.delivery.verified, 30, "the main connection's own status came back")
            done = await asyncio.to_thread(
                broker.pub, "orbitrig/fine-rig/abort", json.dumps({"cmd": "abort", "id": "a1"})
            )
            assert done.returncode == 0, done.stderr
            await until(lambda: len(watch.messages) >= 1, 15, "the abort answered")
            await asyncio.sleep(abort_link.MISSING_S + 2.0)
            assert service.abort_link.up and service.abort_link.delivery.verified
            assert service.abort_link.delivery.problem is None and service.link.delivery.problem is None
            errors = _errors(caplog, "orbitrig.service.link") + _errors(caplog, "orbitrig.service.abort_link")
            assert not errors, errors
            assert [m.json()["id"] for m in watch.messages] == ["a1"]
    finally:
        watch.close()
