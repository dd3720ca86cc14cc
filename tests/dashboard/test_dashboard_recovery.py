"""The page shows "offline" while the rig service or the broker is gone and
recovers by itself when they are back (no new sign-in)."""

from __future__ import annotations

import signal

from support.dash_helpers import Page
from support.mqtt_helpers import ACCOUNTS


def test_service_restart_and_broker_restart(broker, service, dashboard, browsers):
    page = Page(browsers(), dashboard.url, dashboard)
    page.sign_in("operator", ACCOUNTS["operator"])
    page.signed_in()
    page.wait_state("idle", 60)

    service.proc.kill(signal.SIGKILL)  # no goodbye: the broker publishes the service's last will
    page.wait_state("offline", 30)
    page.wait_text("offline-banner", "offline: the rig service is not connected", 5)
    assert page.el("btn-pause").get_attribute("title").startswith("not now: the rig service is offline")
    assert page.send("pause", "pause:") == "pause: not sent: the rig service is offline"
    service.restart()
    page.wait_state("idle", 60)
    page.wait(lambda: not page.el("offline-banner").is_displayed(), 5, "the banner to go")

    broker.stop()
    page.wait_text("link", "broker unreachable", 30)
    page.wait_text("offline-banner", "offline: broker unreachable — reconnecting", 5)
    broker.start()  # same port; no persistence: the service republishes its retained status
    page.wait_text("link", "online", 30)
    page.wait_state("idle", 60)
    page.wait(lambda: not page.el("offline-banner").is_displayed(), 10, "the banner to go")
    # commands go through again: the service answers (a matrix it does not have)
    page.el("matrix").clear()
    page.el("matrix").send_keys("nosuch")
    assert "no matrix 'nosuch' in the matrix folder" in page.command("btn-start", "start:")
