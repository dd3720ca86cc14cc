"""The page's closed sets of words (static/words.js) against their Python homes, and the page's
scripts using those tables instead of spelling the words out."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import orbitrig.dashboard
from orbitrig.dashboard import commands, link_lost
from orbitrig.dashboard.alarms import PAUSE_REQUESTED, SUSPENDED, Condition
from orbitrig.dashboard.feed import BrokerLink, FeedType
from orbitrig.dashboard.session import PAGE_COMMANDS
from orbitrig.run.progress import ETA_HELD
from orbitrig.run.states import RunCommand
from orbitrig.run.states import Outcome, RunState
from orbitrig.service import protocol
from orbitrig.store.status import RunStatus

STATIC = Path(orbitrig.dashboard.__file__).parent / "static"
_TABLE = re.compile(r"const (\w+) = Object\.freeze\(\{(.*?)\}\);", re.DOTALL)
_ENTRY = re.compile(r'(\w+): "([^"]*)"')


def _tables() -> dict[str, dict[str, str]]:
    text = (STATIC / "words.js").read_text(encoding="utf-8")
    return {name: dict(_ENTRY.findall(body)) for name, body in _TABLE.findall(text)}


def _members(enum) -> dict[str, str]:
    return {m.name: m.value for m in enum}


def test_each_table_of_the_page_is_its_python_enum():
    tables = _tables()
    assert set(tables) == {
        "RunState",
        "Outcome",
        "StoredStatus",
        "Condition",
        "EtaHeld",
        "Command",
        "BrokerLink",
        "FeedType",
        "StatusSaid",
        "Refusal",
    }
    assert tables["RunState"] == {**_members(RunState), "OFFLINE": protocol.OFFLINE}
    assert set(tables["RunState"].values()) == set(protocol.STATES)  # the states of <prefix>/status
    assert tables["Outcome"] == _members(Outcome)
    assert tables["StoredStatus"] == _members(RunStatus)  # the outcome of the ready status's last_run
    assert tables["Condition"] == _members(Condition)  # an alarm's condition
    assert tables["EtaHeld"] == {state.name: words for state, words in ETA_HELD.items()}  # as the terminal says it
    assert tables["Command"] == _members(RunCommand)
    assert set(tables["Command"].values()) <= set(PAGE_COMMANDS)  # the server lets the page send each
    assert tables["BrokerLink"] == _members(BrokerLink)
    assert tables["FeedType"] == _members(FeedType)
    # a suspension's status and a pause pending in a held status, as the alarms read them and the run says them
    assert tables["StatusSaid"] == {
        "SUSPENDED": SUSPENDED,
        "PAUSE_REQUESTED": PAUSE_REQUESTED,
        "GROUPED_WARNING": protocol.GROUPED_WARNING,  # a closing status's grouped warnings, as the server splits them
    }


#: the words of the dashboard server's refusals and outcomes the page says too (static/words.js Refusal)
REFUSAL_WORDS = ("SERVICE_OFFLINE", "EMERGENCY_STOP", "EMERGENCY", "CHECK_STATE", "OUTCOME_UNKNOWN", "NO_BROKER")


def test_the_pages_refusal_words_are_the_servers_and_no_script_spells_them_out():
    """What the page says of a rig service offline, of a command it cannot send or whose outcome is not known,
    is in the dashboard server's words (orbitrig.dashboard.commands); the page's scripts use the table (before,
    buttons.js and app.js each wrote 'the rig service is offline' and the server's advice out)."""
    assert _tables()["Refusal"] == {name: getattr(commands, name) for name in REFUSAL_WORDS}
    assert commands.service_words(False) == commands.SERVICE_OFFLINE
    assert commands.NOT_SENT_OFFLINE == "not sent: " + commands.SERVICE_OFFLINE
    assert commands.unknown("abort", "no reply", None) == (
        f"no reply: {commands.OUTCOME_UNKNOWN} — {commands.CHECK_STATE}; {commands.EMERGENCY}"
    )
    for script in sorted(p for p in STATIC.glob("*.js") if p.name != "words.js"):
        text = script.read_text(encoding="utf-8")
        assert [w for w in _tables()["Refusal"].values() if w in text] == [], script.name


def test_the_pages_link_lost_words_are_the_servers_and_its_reading_too():
    """What the page says of an offline whose truth is not known is the dashboard server's (its refusals say the
    same: link_lost), and whether a status is read so is the server's too, sent with it: the page keeps no window
    around an outage of its own (it had one, which a page loaded after the outage did not know)."""
    words = (STATIC / "words.js").read_text(encoding="utf-8")
    app = (STATIC / "app.js").read_text(encoding="utf-8")
    assert re.findall(r'const LINK_LOST = "([^"]*)";', words) == [link_lost.LINK_LOST]
    said = dict(re.findall(r'const (LOST_IN_OUTAGE|RUN_MAY_GO_ON) = "([^"]*)";', words))
    assert said == {"LOST_IN_OUTAGE": link_lost.LOST_IN_OUTAGE, "RUN_MAY_GO_ON": link_lost.RUN_MAY_GO_ON}
    service = re.findall(r'const SERVICE_LINK_LOST = "([^"]*)" \+ LINK_LOST;', words)
    assert [s + link_lost.LINK_LOST for s in service] == [link_lost.SERVICE_LINK_LOST]
    assert "WILL_NEAR_OUTAGE" not in app and "statusAt" not in app and "rigsAt" not in app
    assert "showStatus(msg.data, msg.texts, !!msg.link_lost)" in app


def test_the_page_handles_every_feed_message_type():
    app = (STATIC / "app.js").read_text(encoding="utf-8")
    assert set(re.findall(r"case FeedType\.(\w+):", app)) == set(_members(FeedType))


def test_every_status_state_has_its_badge_colour():
    css = (STATIC / "style.css").read_text(encoding="utf-8")
    assert {s for s in protocol.STATES if not re.search(rf"\.s-{s}\b", css)} == set()


@pytest.mark.parametrize("script", sorted(p.name for p in STATIC.glob("*.js") if p.name != "words.js"))
def test_no_script_spells_out_a_word_of_the_tables(script):
    """A comparison, a case or a command sent with a bare word of a table is one the tables do not
    keep in step with Python."""
    words = {w for table in _tables().values() for w in table.values()}
    text = (STATIC / script).read_text(encoding="utf-8")
    spelled = re.findall(r'(?:[!=]==|case|send\()\s*"([^"]*)"', text)
    assert sorted(w for w in spelled if w in words) == []


def test_the_operator_reads_micrometres_as_the_page_writes_them():
    """The service's prompt for the manual settings (SetManual, the radius check) and the page's
    panel of those settings spell the micrometre alike: rigunits.MICROMETRE, the micro sign."""
    from support.units import UREG

    from orbitrig.run.steps import SetManual
    from rigunits import MICROMETRE, UM, micrometres

    app = (STATIC / "app.js").read_text(encoding="utf-8")
    label = re.search(r'orbit_radius: \["orbit radius", "([^"]*)", \d\]', app)
    assert label and label[1] == MICROMETRE == "\u00b5m"
    units = (STATIC / "units.js").read_text(encoding="utf-8")  # its conversion: tests/dashboard/test_dashboard_units.py
    assert f'"{MICROMETRE}": v => v * 1e6' in units and 1 / UM == 1e6
    prompt = SetManual(3, 0.0, 5.76e-6, 0.1, 0.4826e6, 0.25, True).describe()
    assert "orbit radius 5.76 \u00b5m," in prompt and " um" not in prompt
    assert micrometres(60e-6, ".3g") == "60 \u00b5m"
    assert UREG.Quantity(5.76, MICROMETRE).to("m").magnitude == 5.76e-6
