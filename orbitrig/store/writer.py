"""The run directory's writer: every unit of measured data durable in one atomic step.

A block (one orbit frequency) and a point's results each become one file written to a
temporary name, fsync'ed and renamed into place (orbitrig.store.durable); the point is
committed last by its commit record, which names every file with its digest; the
journal is append-only. A kill at any instant therefore leaves every completed block
and point readable, and `prepare_resume` sets aside (under DIR/aside, never deleted)
whatever is incomplete or damaged. HDF5 never writes to the disk directly, so a full
disk raises StorageFullError and leaves nothing in a broken state. The single-file
run.h5 is consolidated from the pieces when the run ends (`finalize`). Layout:
orbitrig.store.layout and docs/storage.md.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
from pathlib import Path
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from orbitrig.store import csvfile, journal, pieces
from orbitrig.store.consolidate import Copied, RunImage, read_header
from orbitrig.store.csvfile import CSV_HEAD, coef_order, true_entry  # noqa: F401  (the CSV's public names)
from orbitrig.store.estimate import final_bytes
from orbitrig.store.hold import RunHold
from orbitrig.store.durable import fsync_dir, h5_image, write_atomic
from orbitrig.store.identity import claim_created, header_software, software_versions
from orbitrig.store.journal_file import JournalFile
from orbitrig.store.errors import FULL_AT_CREATE_ADVICE, RunDirError, StorageError, StorageFullError, UnusableRunDir
from orbitrig.store.errors import RUN_EXISTS, storage_error
from orbitrig.store.index import CompletePoints, commit_record, point_state
from orbitrig.store.layout import FORMAT, RunLayout, point_name
from orbitrig.store.reader import read_point
from orbitrig.store.resume import REMOVED_BEFORE, REMOVED_RUN_FILE, RunResume  # noqa: F401  (said by a resume)
from orbitrig.store.records import BlockRecord, LogBuffer, PointResults
from orbitrig.store.run_log import RunLog
from orbitrig.store.status import RunStatus
from orbitrig.store.stored_header import StoredHeader

if TYPE_CHECKING:  # annotation only: the store does not import the run wing
    from orbitrig.run.plan import OperatingPoint

log = logging.getLogger(__name__)
#: what a point committed and altered since means for the run (said when run.h5 is consolidated)
LOST = "run.h5 holds it as incomplete, coefficients.csv leaves it out; sweep --resume measures it again"


class RunStore(StoredHeader, RunResume):
    """Writer of one run directory. Every method raises StorageError (never OSError)."""

    def __init__(self, out_dir: Path | str):
        self.layout = RunLayout(Path(out_dir))
        self.dir = self.layout.dir
        self.path = self.layout.run_file
        self.csv_path = self.layout.csv
        self.log_path = self.layout.log
        self.logs = LogBuffer()
        self.set_aside: list[str] = []  # what prepare_resume set aside or removed, one message each
        # prepare_resume: a run.h5 removed, no journal; the software measuring the points from now on
        self.removed_run_file, self.journal_missing, self.software = False, "", ""
        self._header: dict[str, Any] = {}  # run.json
        self._csv_points: dict[int, csvfile.PointCsv] = {}  # complete point -> its rows, kept compact
        self._complete = CompletePoints(self.layout)  # the one record of which points are complete
        self._written: dict[int, dict[str, dict[str, Any]]] = {}  # point -> file name -> size, digest
        self._unfinished: dict[int, int] = {}  # point begun, not yet copied into run.h5 -> bytes written
        self._image = RunImage(self.layout)  # run.h5.tmp on disk, filled as points commit
        self._journal_file = JournalFile(self.layout.journal, self.run_seconds, self._warn)
        self.run_log = RunLog(self.log_path, self._journal_file)  # written off the caller's thread
        self.copied: Copied | None = None  # told each point the consolidation of run.h5 copies
        #: told each warning of the store's own (on the thread that wrote: the caller's, run.log's);
        #: the run engine hands them to its subscribers (orbitrig.run.store_notes); None: logged as warnings
        self.warned: Callable[[str], None] | None = None
        self._hold = RunHold(self.layout.dir)

    # ---------------------------------------------------------- life cycle
    @classmethod
    def create(
        cls,
        out_dir: Path | str,
        *,
        rig_text: str,
        matrix_text: str,
        matrix_name: str,
        sim: bool,
        scenario_name: str = "",
        scenario_text: str = "",
        provenance: dict[str, str] | None = None,
        record_text: str = "",
        point_order: list[int] | None = None,
        channels: Sequence[tuple[str, str]] = (),
    ) -> RunStore:
        """A new run directory; `scenario_name` / `scenario_text`: the simulator scenario of a
        --sim run (name and TOML text, recorded so that a resume runs the same one);
        `provenance` (orbitrig.run.provenance) and the active calibration record's text;
        `point_order`: per point run, its index in the matrix's written order (a resume keeps it);
        `channels`: (name, unit) of each A/D channel in board order, as the rig configuration in use
        names them (its active calibration record included)."""
        self = cls(out_dir)
        lay = self.layout
        for existing in (lay.header, lay.run_file, lay.journal):
            if existing.exists():
                raise UnusableRunDir(existing, RUN_EXISTS)
        try:
            lay.points.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise storage_error(lay.points, "create the run directory", err) from err
        self._header = {
            "format": FORMAT,
            "software_version": software_versions(),
            "created": "",  # claimed below
            "sim": bool(sim),
            "matrix_name": matrix_name,
            "channels": [str(name) for name, _ in channels],
            "channel_units": [str(unit) for _, unit in channels],
            "rig_config": rig_text,
            "matrix_config": matrix_text,
        }
        if sim:
            self._header["sim_scenario"] = {"name": scenario_name, "text": scenario_text}
        if provenance is not None:
            self._header["provenance"] = provenance
        if record_text:
            self._header["calibration_record_text"] = record_text
        if point_order is not None:
            self._header["point_order"] = [int(i) for i in point_order]
        self._header["software_version"] = header_software(self._header)  # the provenance's code
        try:  # the run's id (rig@created), taken in the folder of run directories: no other run's there
            self._header["created"] = claim_created(
                lay.dir.resolve().parent, str(self.stored_provenance().get("rig_id", ""))
            )
            fsync_dir(lay.dir)
            write_atomic(lay.header, json.dumps(self._header, indent=1).encode("utf-8"))
        except StorageFullError as err:  # no run yet: nothing to resume
            raise err.advising(FULL_AT_CREATE_ADVICE) from err
        self._begin()
        return self

    def _begin(self) -> None:
        """The new run's journal says running and its coefficients.csv is written; a CSV that cannot
        be written ends the run there (failed, with the cause), not "running" with no end."""
        self._journal([self._journal_file.status_line(RunStatus.RUNNING, "")])
        try:
            self.write_csv()
        except StorageError as err:
            self._journal([self._journal_file.status_line(RunStatus.FAILED, f"the run could not be created: {err}")])
            raise

    @classmethod
    def open_existing(cls, out_dir: Path | str) -> RunStore:
        self = cls(out_dir)
        lay = self.layout
        if not lay.has_pieces():
            if lay.run_file.exists():
                raise UnusableRunDir(
                    lay.run_file,
                    "holds a finished copy of a run but not its pieces "
                    f"({lay.header.name}, {lay.points.name}/): it cannot be resumed",
                )
            raise UnusableRunDir(lay.header, "does not exist: nothing to resume")
        self._header = read_header(lay)
        missing = [k for k in ("rig_config", "matrix_config", "sim") if k not in self._header]
        if missing:
            raise UnusableRunDir(lay.header, f"no {', '.join(map(repr, missing))} field: the run cannot be resumed")
        self._journal_file.expect()  # one deleted from here on is noticed
        return self

    def hold(self) -> None:
        """Hold the run until `release` (orbitrig.store.hold): another run or resume of it is refused."""
        self._hold.take()

    def release(self) -> None:
        """Let go of the run held by `hold`."""
        self._hold.release()

    def command(self, command: str, by: str, detail: str = "") -> None:
        """A command that changed the run, who sent it and when: a journal line (run.h5's
        /logs/commands) and a run.log line, written in the background (orbitrig.store.run_log)."""
        self.run_log.command(command, by, detail)

    # ------------------------------------------------------------- writing
    def begin_point(self, point: OperatingPoint) -> None:
        i = point.index
        d = self.layout.point_dir(i)
        if d.exists():
            if point_state(self.layout, i).complete:
                raise StorageError(d, f"point {point_name(i)} is already complete")
            self._put_aside(i, "restarted", "an earlier attempt that did not complete")
        try:
            d.mkdir(parents=True)
        except OSError as err:
            raise storage_error(d, "create the point directory", err) from err
        fsync_dir(self.layout.points)
        path = self.layout.point_file(i)
        settings = pieces.to_json(pieces.point_settings(point, self.software)).encode()
        self._written[i] = {path.name: write_atomic(path, settings)}
        self._journal([journal.line("point", point=i, action="begin")])

    def write_block(self, point: int, rec: BlockRecord) -> None:
        channels, units = self._header.get("channels", []), self._header.get("channel_units", [])
        data = h5_image(lambda f: pieces.write_block(f, rec, channels, units))
        path = self.layout.block_file(point, rec.block.tag)
        self._written.setdefault(point, {})[path.name] = write_atomic(path, data)
        self._unfinished[point] = self._unfinished.get(point, 0) + len(data)
        self._journal([journal.line("block", point=point, tag=rec.block.tag, bytes=len(data))])

    def write_results(self, point: int, res: PointResults) -> None:
        data = h5_image(lambda f: pieces.write_results(f, res))
        path = self.layout.results_file(point)
        self._written.setdefault(point, {})[path.name] = write_atomic(path, data)
        self._unfinished[point] = self._unfinished.get(point, 0) + len(data)
        self._journal([])

    def complete_point(self, point: int) -> None:
        """Commit the point: its commit record names every file with size and digest."""
        rec = commit_record(self.layout, point, self._written.pop(point, None))
        write_atomic(self.layout.commit_file(point), json.dumps(rec, indent=1).encode())
        self._complete.add(point)  # complete as written: not read again until the run is consolidated
        self._journal(
            [
                *self.run_log.close_interval(f"point {point_name(point)}"),
                journal.line("point", point=point, action="complete"),
            ]
        )
        self._image.add_point(point)
        self._unfinished.pop(point, None)  # its copy is made: nothing of it is still to write
        self.write_csv()

    def set_status(self, status: RunStatus, message: str = "") -> str:
        """Record the run's status; a final status also consolidates run.h5. If that fails the journal says
        failed and StorageError is raised; a stopped run with no room for it stays stopped (the pieces keep
        its points): returned, what it adds to `message` (else "")."""
        status = RunStatus(status)  # also an Outcome of orbitrig.run.states: the same words
        if not status.final:
            self._journal([self._journal_file.status_line(status, message)])
            return ""
        self._journal([*self.run_log.close_interval("the run's end"), self._journal_file.status_line(status, message)])
        try:
            self.finalize()
        except StorageError as err:
            if status == RunStatus.STOPPED and isinstance(err, StorageFullError):  # a resume consolidates it
                note = f"run.h5 not written ({err.path}: {err.problem}){self.gone()}; the points are kept: resume the run once there is room"
                with contextlib.suppress(StorageError):
                    self._journal([self._journal_file.status_line(status, f"{message}; {note}")])
                return note
            with contextlib.suppress(StorageError):
                failed = f"run.h5 could not be written: {err}{self.gone()}"
                self._journal([self._journal_file.status_line(RunStatus.FAILED, failed)])
            raise
        return ""

    def gone(self) -> str:
        """'; REMOVED_BEFORE' when prepare_resume removed run.h5 and none is written since (else "")."""
        return f"; {REMOVED_BEFORE}" if self.removed_run_file and not self.path.exists() else ""

    def flush_logs(self) -> None:
        """Write what is said and gathered so far: run.log's lines, the commands, the log rows."""
        self.run_log.flush()
        self._journal([])

    def finalize(self) -> Path:
        """Consolidate DIR/run.h5 from the pieces, each point verified in full first (one altered since: said)."""
        states, lost = self._complete.verify()
        said = [f"warning: point {point_name(st.index)} is no longer complete ({st.problem}): {LOST}" for st in lost]
        for msg in said:
            log.warning("%s", msg)
            self.log(msg)
        if said:  # run.h5's /logs/events too, journaled before run.h5 copies the journal
            self._journal([self._journal_file.event(msg) for msg in said])
        copied = self._image.copied()  # the others are copied now, with the logs and the header
        left = [s.index for s in states if s.complete and s.index not in copied]
        self.check_free_space(final_bytes(self.layout, left))
        return self._image.write(states, self.copied)

    def unfinished_bytes(self) -> dict[int, int]:
        """Each point being written, not yet copied into run.h5 -> bytes of its pieces so far (any thread)."""
        return dict(self._unfinished)

    def _journal(self, lines: list[str]) -> None:
        """Append `lines` and the gathered log rows to the journal in one durable write."""
        events, can, drives = self.logs.take()
        try:
            self._journal_file.append(lines + journal.log_lines(events, can, drives))
        except StorageError:
            self.logs.put_back(events, can, drives)
            raise

    def _warn(self, warning: str) -> None:
        """A warning of the store's own: in run.log, and told `warned` (else on the terminal: logging)."""
        self.log(f"warning: {warning}")
        if (warned := self.warned) is None:
            log.warning("warning: %s", warning)
            return
        log.info("warning: %s", warning)  # the service's log; whoever `warned` tells says it as a warning
        try:
            warned(warning)
        except Exception:  # the write it follows has succeeded: a listener's failure is no storage failure
            log.exception("the store's warning listener failed")

    # -------------------------------------------------------------- space
    def free_bytes(self) -> int:
        """Free bytes on the run directory's file system (for an unprivileged writer)."""
        try:
            st = os.statvfs(self.dir if self.dir.exists() else self.dir.parent)
        except OSError as err:
            raise storage_error(self.dir, "read the free space", err) from err
        return st.f_bavail * st.f_frsize

    def check_free_space(self, n_bytes: int) -> None:
        """Raise StorageFullError when fewer than `n_bytes` are free for the run directory."""
        free = self.free_bytes()
        if free < n_bytes:
            raise StorageFullError.short_of(self.dir, n_bytes, free)

    # -------------------------------------------------------------- run.log
    def log(self, message: str) -> None:
        """A line of the human-readable run.log, stamped now and written in the background
        (orbitrig.store.run_log: best effort, bounded between two completed points)."""
        self.run_log.line(message)

    # --------------------------------------------------------------- reading
    def completed_points(self) -> list[int]:
        """The complete points (orbitrig.store.index.CompletePoints: verified in full when first asked,
        by `prepare_resume` and before run.h5 is consolidated; no point is read again per commit)."""
        return self._complete.points()

    def csv_points(self) -> list[csvfile.PointCsv]:
        """The rows of coefficients.csv, per complete point (each read once, then kept as CSV text)."""
        sim = bool(self._header.get("sim", False))
        points = []
        for i in self.completed_points():
            if i not in self._csv_points:
                try:
                    point = read_point(self.layout, i, complete=True, blocks=False)
                except RunDirError as err:
                    raise StorageError(err.file, f"cannot read the stored results: {err.reason}") from err
                self._csv_points[i] = csvfile.PointCsv.of(csvfile.point_rows(point, sim))
            points.append(self._csv_points[i])
        return points

    def write_csv(self) -> None:
        write_atomic(self.csv_path, csvfile.render_points(self.csv_points()))
