"""The stored run status: one closed set owned by the store, the engine's outcomes map onto it."""

from orbitrig.run.states import Outcome, stored_status
from orbitrig.store.journal import read_journal, status_line
from orbitrig.store.status import RunStatus


def test_every_outcome_is_a_final_stored_status_with_the_same_word():
    for outcome in Outcome:
        status = stored_status(outcome)
        assert status.final and status == outcome.value
    assert {stored_status(o) for o in Outcome} == {s for s in RunStatus if s.final}
    assert not RunStatus.RUNNING.final and not RunStatus.UNKNOWN.final


def test_the_journal_reads_the_word_it_wrote_and_unknown_for_a_foreign_word(tmp_path):
    path = tmp_path / "journal.jsonl"
    path.write_text(
        status_line(RunStatus.RUNNING, "") + "\n" + status_line(RunStatus.ABORTED, "by the operator") + "\n"
    )
    j = read_journal(path)
    assert j.status is RunStatus.ABORTED and j.status_message == "by the operator"
    assert '"status":"aborted"' in path.read_text()  # the file keeps the bare word
    path.write_text(path.read_text().replace("aborted", "exploded"))
    assert read_journal(path).status is RunStatus.UNKNOWN
    assert RunStatus.read(None) is RunStatus.UNKNOWN and RunStatus.read(b"x") is RunStatus.UNKNOWN
    assert repr(RunStatus.FAILED) == "'failed'" and f"{RunStatus.STOPPED}" == "stopped"
