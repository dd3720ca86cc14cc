"""The run directory as the engine uses it: opened new or for a resume, room for each
point, and the records of the run's end.

A new run records its configurations (the matrix with the design it uses), provenance,
simulator scenario and point order; a resumed one must be given the matrix it was started
with (or none), measures with the design it stored and sets aside its incomplete points
(orbitrig.store.writer). The end records are written whatever happened:
a failure to write one is reported through ``failed`` and the others are still written.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

from orbitrig.config import ConfigError, RigConfig, matrix_differs
from orbitrig.run.events import RunOutcome
from orbitrig.run.plan import OperatingPoint, Plan, make_plan
from orbitrig.run.provenance import UNNAMED, Provenance, software_version
from orbitrig.run.rig_io import RigAccess
from orbitrig.run.scenario import Scenario
from orbitrig.run.states import ALL_COMPLETED, COMPLETED, FAILED, Outcome, RunCommand, stored_status
from orbitrig.run.steps import Acquire, ChooseBlocks
from orbitrig.store.estimate import point_room
from orbitrig.store.errors import StorageError, StorageFullError
from orbitrig.store.writer import RunStore
from rigunits import seconds_since

log = logging.getLogger(__name__)


def open_store(
    plan: Plan,
    rig: RigConfig,
    access: RigAccess,
    operator: str,
    out_dir: Path,
    resume: bool,
    opened: RunStore | None = None,
) -> tuple[RunStore, list[int]]:
    """The run's directory in ``out_dir`` and the points it holds complete ([] for a new run);
    ``opened``: the run's store a resume opened already (its run.json read once, by its caller).
    Raises ConfigError when a resume is given another matrix than the stored one."""
    if not resume:
        sc = access.scenario or Scenario("")
        prov = Provenance.of_run(rig, operator, plan.matrix.text)  # the file's text: no design appended
        store = RunStore.create(
            out_dir,
            rig_text=rig.text,
            matrix_text=plan.matrix.run_text,  # with the design it uses: a resume measures with it
            matrix_name=plan.name,
            sim=access.simulated,
            scenario_name=sc.name,
            scenario_text=sc.text,
            provenance=prov.to_dict(),
            record_text=rig.record_text,
            point_order=list(plan.order),
            channels=[(c.name, c.unit) for c in rig.ordered_channels],
        )
        store.hold()
        store.log(prov.summary())
        store.software = prov.software_version  # each point's point.json names it
        return store, []
    store = opened or RunStore.open_existing(out_dir)
    store.software = software_version()  # a resume's points: this software's, whatever started the run
    _, matrix_text, _ = store.stored_configs()
    if plan.matrix.text and matrix_text not in (plan.matrix.text, plan.matrix.run_text):
        raise ConfigError(
            plan.matrix.file,
            [f"{matrix_differs(store.dir, matrix_text, plan.matrix.text)}; resume with the stored matrix"],
        )
    store.hold()  # before anything is set aside or written: not while another process runs it
    note = plan.matrix.resume_note() if plan.matrix.text == matrix_text else None  # else: read now, the same
    if note:
        store.log(note)
        log.warning("%s", note)  # on the terminal too
    return store, store.prepare_resume()


def consolidate_resumed(store: RunStore, rig: RigConfig, operator: str, points: int) -> RunOutcome:
    """A resume of a run whose every point (``points`` in its plan) is complete but whose run.h5
    is missing (cut off after its last point, or a full disk at its end): run.h5 consolidated
    from the stored pieces and the run recorded completed, without the rig, the simulator or the
    drives. A run.h5 that cannot be written ends it failed (the pieces kept: resume again)."""
    store.hold()  # not while the run's own process still consolidates it
    try:
        store.prepare_resume()  # leftover temporary files (a cut-off run.h5.tmp) removed
        store.command(RunCommand.START, operator or UNNAMED, f"run {store.run_id}, resumed to consolidate run.h5")
        store.log(f"resume {Provenance.of_run(rig, operator).summary()}")
        said = f"resumed to consolidate run.h5 from the stored pieces (all {points} points were complete)"
        store.log(f"{said}; nothing measured (the rig and its drives were not opened)")

        def failed(what: str, err: BaseException) -> None:
            log.error("cannot %s: %s", what, err)

        lost = f"; warning: {store.journal_missing}" if store.journal_missing else ""  # in run.h5's status too
        status, message = record_end(store, store.run_id, COMPLETED, f"{ALL_COMPLETED}; {said}{lost}", failed)
        store.run_log.flush()
    finally:
        store.release()
    done = completed_points(store)  # as checked before run.h5
    return RunOutcome(status, message, store.run_id, store.dir, done, points)


def resume_events(store: RunStore, rig: RigConfig, operator: str) -> list[str]:
    """The run's events of a resume: the points it set aside, who resumes it with what and
    where, and a warning when the software differs from the one the run started with (its
    points then come from two)."""
    now = Provenance.of_run(rig, operator)
    lines = [*store.set_aside, f"resume {now.summary()}"]
    before = store.stored_provenance().get("software_version")
    if before and before != now.software_version:
        lines.append(
            f"warning: resumed with {now.software_version}; the run started with {before}: "
            "the points measured from here on come from another software version"
        )
        log.warning("%s", lines[-1])  # on the terminal too
    return lines


def run_age(store: RunStore) -> float:
    """Seconds since the stored run started (its provenance; 0 when it has none): the time axis
    of a resumed run's logs goes on from the first session's."""
    age = seconds_since(str(store.stored_provenance().get("started", "")))
    return max(age, 0.0) if age is not None else 0.0


def no_room(store: RunStore, rig: RigConfig, plan: Plan, point: OperatingPoint) -> str | None:
    """Why the disk cannot take ``point`` (None: it can): its pieces and their copy into run.h5,
    and what the points still in flight (identified, stored, copied in the background) add yet."""
    points = {p.index: p for p in plan.points}
    need = _room(rig, plan, point)
    for i, written in store.unfinished_bytes().items():
        if i != point.index and i in points:
            need += max(0, _room(rig, plan, points[i]) - written)
    try:
        store.check_free_space(need)
    except StorageFullError as err:
        return f"not enough free disk space: {err}"
    return None


def _room(rig: RigConfig, plan: Plan, point: OperatingPoint) -> int:
    """Bytes `point` writes: its pieces and their copy into run.h5 (orbitrig.store.estimate)."""
    steps = plan.point_steps(point.index)
    counts = [s.revolutions for s in steps if isinstance(s, (Acquire, ChooseBlocks))]  # most per block
    return point_room(rig, point, counts, len(plan.matrix.models))


def record_end(
    store: RunStore, run_id: str | None, status: Outcome, message: str, failed: Callable[[str, BaseException], None]
) -> tuple[Outcome, str]:
    """The run's status, run.h5, coefficients.csv and run.log's last line. A run whose
    status or run.h5 cannot be written ends failed, whatever it was (the reason said); a
    stopped run whose run.h5 does not fit stays stopped: its pieces hold every complete point,
    and its resume consolidates run.h5. Either way a resume that removed the run.h5 written before
    it says so (RunStore.gone)."""
    try:
        if note := store.set_status(stored_status(status), message):  # stopped, no room for run.h5
            message = f"{message}; {note}"
            log.warning("%s", message)
    except Exception as err:  # noqa: BLE001 - the other records are still written
        failed("write the run status and run.h5", err)
        if status != FAILED:  # a failed run keeps its first cause
            status, message = FAILED, f"storage failed: the run's status and run.h5 could not be written: {err}"
        message += store.gone()  # a resume that removed the earlier run.h5 and wrote none says so
    last_line = f"run {run_id} ended: {status}: {message}"
    for what, action in (
        ("write coefficients.csv", store.write_csv),
        ("close the run log", lambda: store.log(last_line)),
    ):
        try:
            action()
        except Exception as err:  # noqa: BLE001
            failed(what, err)
    return status, message


def completed_points(store: RunStore) -> list[int]:
    """The points the run file marks complete ([] if it cannot be read after a storage failure)."""
    try:
        return store.completed_points()
    except (StorageError, OSError) as err:
        log.error("cannot read the completed points: %s", err)
        return []


def started_order(plan: Plan, store: RunStore) -> Plan:
    """A resumed run keeps the order of the operating points it started with (the rig's
    changeover times may have been edited since); a run that recorded none ran them as written."""
    order = store.stored_point_order() or list(range(len(plan.points)))
    if sorted(order) != list(range(len(plan.points))):
        raise ConfigError(
            f"{store.layout.header}:point_order",
            [f"{order} is not an order of the stored matrix's {len(plan.points)} operating points"],
        )
    return plan if list(plan.order) == order else make_plan(plan.matrix, plan.rig, order)
