"""The run directory: `run.h5` + `coefficients.csv` + `run.log` (docs/storage.md).

Crash safety by open/flush/close discipline: the HDF5 file is open only while
one block (or one point's results) is written, then flushed and closed, so a
kill -9 or a power cut during acquisition (nearly all of a run's time) finds a
closed, consistent file. Every group's ``complete`` attribute is written LAST;
`resume` deletes every incomplete point group, so a point is never stored
twice nor marked complete when it is not. `coefficients.csv` is rebuilt from
the complete points of run.h5 and replaced atomically (write + rename).
"""

from __future__ import annotations

import contextlib
import csv
import datetime as _dt
import json
import os
import threading
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from orbitrig import __version__
from orbitrig.errors import OrbitrigError
from orbitrig.run.plan import Block, OperatingPoint

FORMAT = "orbitrig-run/1"
RUN_FILE, CSV_FILE, LOG_FILE = "run.h5", "coefficients.csv", "run.log"
CSV_HEAD = [
    "point", "label", "spin_rpm", "recess_pressure_mpa", "pressure_ratio", "static_eccentricity",
    "dynamic_eccentricity", "lms", "model", "freq_dep", "method", "n_frequencies", "condition_number",
    "residual_rms", "error",
]  # fmt: skip
_STR = h5py.string_dtype()
EVENT_DTYPE = np.dtype([("t", "f8"), ("state", _STR), ("message", _STR)])
CAN_FIELDS = ("t_recess", "t_groove", "t_supply", "flow", "p_supply", "p_recess1", "p_recess2", "p_recess3",
              "p_recess4", "beta", "sensor_fault", "pump_off", "node_lost")  # fmt: skip
CAN_DTYPE = np.dtype([("t", "f8")] + [(f, "f8") for f in CAN_FIELDS])
DRIVE_FIELDS = ("spin_ref", "spin_act", "orbit_ref", "orbit_act", "spin_status", "orbit_status",
                "spin_fault", "orbit_fault", "spin_torque", "orbit_torque")  # fmt: skip
DRIVE_DTYPE = np.dtype([("t", "f8")] + [(f, "f8") for f in DRIVE_FIELDS])


class StorageError(OrbitrigError):
    """The run directory cannot be created, resumed or written."""


def now_iso() -> str:
    return _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")


@dataclass
class BlockRecord:
    """Everything stored for one orbit frequency and direction."""

    block: Block
    measured_orbit_speed: float  # rad/s, |Omega| from trigger timestamps
    raw_counts: np.ndarray  # int16 (N, C, S)
    slots: np.ndarray  # (C, S)
    gains: np.ndarray
    offsets: np.ndarray
    mean: np.ndarray  # (C, S) engineering units
    record_phasors: np.ndarray  # (N, C)
    phasors: np.ndarray  # (C,)
    dc: np.ndarray  # (C,)
    rms_residual: np.ndarray  # (C,)
    coherence: np.ndarray  # (2, 4) piezo|strain x (xfx, yfx, xfy, yfy)
    stats: dict = field(default_factory=dict)


@dataclass
class PointResults:
    tables: dict  # lms -> reduction.table.OrbitTable
    identifications: dict  # (lms, ModelSpec.key) -> {"spec": ModelSpec, "json": dict | "error": str}
    lms_comparison: dict
    truth: dict | None = None


class LogBuffer:
    """Rows gathered between writes (appended with the next write); thread-safe."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._rows: dict[str, list] = {"events": [], "can": [], "drives": []}

    def add(self, log: str, row: tuple) -> None:
        with self._lock:
            self._rows[log].append(row)

    def take(self) -> tuple[list, list, list]:
        with self._lock:
            rows, self._rows = self._rows, {"events": [], "can": [], "drives": []}
        return rows["events"], rows["can"], rows["drives"]


class RunStore:
    """Writer of one run directory. Every method opens, writes, flushes and closes."""

    def __init__(self, out_dir: Path | str):
        self.dir = Path(out_dir)
        self.path = self.dir / RUN_FILE
        self.csv_path = self.dir / CSV_FILE
        self.log_path = self.dir / LOG_FILE
        self.logs = LogBuffer()

    # ---------------------------------------------------------- life cycle
    @classmethod
    def create(cls, out_dir, *, rig_text: str, matrix_text: str, matrix_name: str, sim: bool) -> "RunStore":
        self = cls(out_dir)
        if self.path.exists():
            raise StorageError(f"{self.path} already exists: use --resume to continue that run, or another --out")
        self.dir.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_suffix(".h5.tmp")
        with h5py.File(tmp, "w") as f:
            a = f.attrs
            a["format"] = FORMAT
            a["software_version"] = _versions()
            a["created"] = now_iso()
            a["status"] = "running"
            a["status_message"] = ""
            a["sim"] = bool(sim)
            a["rig_config"] = rig_text
            a["matrix_config"] = matrix_text
            a["matrix_name"] = matrix_name
            f.create_group("points")
            logs = f.create_group("logs")
            for name, dt in (("events", EVENT_DTYPE), ("can", CAN_DTYPE), ("drives", DRIVE_DTYPE)):
                logs.create_dataset(name, shape=(0,), maxshape=(None,), dtype=dt, chunks=(256,))
        os.replace(tmp, self.path)
        self.write_csv()
        return self

    @classmethod
    def open_existing(cls, out_dir) -> "RunStore":
        self = cls(out_dir)
        if not self.path.exists():
            raise StorageError(f"{self.path} does not exist: nothing to resume")
        try:
            with h5py.File(self.path, "r") as f:
                if f.attrs.get("format") != FORMAT:
                    raise StorageError(f"{self.path} is not an orbitrig run (format {f.attrs.get('format')!r})")
        except OSError as err:
            raise StorageError(f"{self.path} cannot be opened ({err}); it may have been cut mid-write") from err
        return self

    def stored_configs(self) -> tuple[str, str, bool]:
        """(rig TOML text, matrix TOML text, sim) of the stored run."""
        with h5py.File(self.path, "r") as f:
            a = f.attrs
            return str(a["rig_config"]), str(a["matrix_config"]), bool(a["sim"])

    def prepare_resume(self) -> list[int]:
        """Delete incomplete point groups; return the complete point indexes."""
        with self._open() as f:
            pts = f["points"]
            done, dropped = [], []
            for name in list(pts):
                if bool(pts[name].attrs.get("complete", False)):
                    done.append(int(name))
                else:
                    del pts[name]
                    dropped.append(name)
            f.attrs["status"] = "running"
            f.attrs["status_message"] = ""
        self.write_csv()
        if dropped:
            self.log(f"resume: removed incomplete point(s) {', '.join(dropped)}")
        return sorted(done)

    @contextlib.contextmanager
    def _open(self):
        f = h5py.File(self.path, "r+")
        try:
            yield f
            f.flush()
        finally:
            f.close()

    # ------------------------------------------------------------- writing
    def begin_point(self, point: OperatingPoint) -> None:
        with self._open() as f:
            pts = f["points"]
            name = f"{point.index:04d}"
            if name in pts:
                if pts[name].attrs.get("complete", False):
                    raise StorageError(f"point {name} is already complete in {self.path}")
                del pts[name]
            g = pts.create_group(name)
            a = g.attrs
            a["index"] = point.index
            a["complete"] = False
            a["spin"] = point.spin
            a["spin_rpm"] = point.spin_rpm
            a["recess_pressure"] = point.recess_pressure
            a["pressure_ratio"] = point.pressure_ratio
            a["static_eccentricity"] = point.static_eccentricity
            a["dynamic_eccentricity"] = point.dynamic_eccentricity
            a["orbit_radius"] = point.orbit_radius
            a["label"] = point.label
            g.create_group("frequencies")
            self._append_logs(f)

    def write_block(self, point: int, rec: BlockRecord) -> None:
        with self._open() as f:
            freqs = f[f"points/{point:04d}/frequencies"]
            b = rec.block
            if b.tag in freqs:
                del freqs[b.tag]
            g = freqs.create_group(b.tag)
            a = g.attrs
            a["complete"] = False
            a["orbit"] = b.orbit
            a["orbit_hz"] = b.orbit_hz
            a["direction"] = b.direction
            a["measured_orbit_speed"] = rec.measured_orbit_speed
            g.create_dataset("raw_counts", data=np.asarray(rec.raw_counts, dtype=np.int16))
            g.create_dataset("slots", data=np.asarray(rec.slots, dtype=np.int16))
            for name in ("gains", "offsets", "mean", "dc", "rms_residual", "coherence"):
                g.create_dataset(name, data=np.asarray(getattr(rec, name), dtype=np.float64))
            for name in ("record_phasors", "phasors"):
                g.create_dataset(name, data=np.asarray(getattr(rec, name), dtype=np.complex128))
            g["mean"].attrs["units"] = "N (forces), m (displacements)"
            st = g.create_group("stats")
            for k, v in rec.stats.items():
                st.attrs[k] = json.dumps(v) if isinstance(v, dict) else v
            self._append_logs(f)
            a["complete"] = True

    def write_results(self, point: int, res: PointResults) -> None:
        with self._open() as f:
            g = f[f"points/{point:04d}"]
            for sub in ("table", "identification", "truth", "lms_comparison"):
                if sub in g:
                    del g[sub]
            tg = g.create_group("table")
            for lms, t in res.tables.items():
                h = tg.create_group(lms)
                h.attrs["spin"] = t.spin
                h.create_dataset("orbit", data=np.asarray(t.orbit, dtype=np.float64))
                for name in ("x", "y", "fx", "fy"):
                    h.create_dataset(name, data=np.asarray(getattr(t, name), dtype=np.complex128))
                if t.gamma2 is not None:
                    h.create_dataset("gamma2", data=np.asarray(t.gamma2, dtype=np.float64))
            ig = g.create_group("identification")
            for (lms, key), entry in res.identifications.items():
                h = ig.create_group(f"{lms}__{key}")
                spec = entry["spec"]
                h.attrs["model"], h.attrs["freq_dep"], h.attrs["method"] = spec.model, spec.freq_dep, spec.method
                if "json" in entry:
                    h.attrs["json"] = json.dumps(entry["json"])
                else:
                    h.attrs["error"] = entry["error"]
            if res.truth is not None:
                g.create_group("truth").attrs["json"] = json.dumps(res.truth)
            g.create_group("lms_comparison").attrs["json"] = json.dumps(res.lms_comparison)
            self._append_logs(f)

    def complete_point(self, point: int) -> None:
        with self._open() as f:
            self._append_logs(f)
            f[f"points/{point:04d}"].attrs["complete"] = True
        self.write_csv()

    def set_status(self, status: str, message: str = "") -> None:
        with self._open() as f:
            self._append_logs(f)
            f.attrs["status"] = status
            f.attrs["status_message"] = message

    def flush_logs(self) -> None:
        with self._open() as f:
            self._append_logs(f)

    def _append_logs(self, f: h5py.File) -> None:
        events, can, drives = self.logs.take()
        for name, rows, dt in (("events", events, EVENT_DTYPE), ("can", can, CAN_DTYPE), ("drives", drives, DRIVE_DTYPE)):
            if not rows:
                continue
            ds = f["logs"][name]
            n = ds.shape[0]
            ds.resize((n + len(rows),))
            ds[n:] = np.array([tuple(r) for r in rows], dtype=dt)

    # -------------------------------------------------------------- run.log
    def log(self, message: str) -> None:
        stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%fZ")
        with open(self.log_path, "a", encoding="utf-8") as fh:
            fh.write(f"{stamp} {message}\n")
            fh.flush()

    # --------------------------------------------------------------- reading
    def completed_points(self) -> list[int]:
        with h5py.File(self.path, "r") as f:
            return sorted(int(n) for n, g in f["points"].items() if g.attrs.get("complete", False))

    def csv_rows(self) -> list[dict]:
        rows = []
        with h5py.File(self.path, "r") as f:
            sim = bool(f.attrs.get("sim", False))
            for _name, g in sorted(f["points"].items()):
                if not g.attrs.get("complete", False):
                    continue
                rows += point_csv_rows(g, sim)
        return rows

    def write_csv(self) -> None:
        rows = self.csv_rows()
        keys: list[str] = []
        for r in rows:
            keys += [k for k in r if k not in CSV_HEAD and k not in keys]
        coef = sorted((k for k in keys if not k.startswith("true_") and not k.endswith("_std")), key=coef_order)
        cols = CSV_HEAD + [c for k in coef for c in (k, f"{k}_std")]
        cols += sorted((k for k in keys if k.startswith("true_")), key=lambda k: coef_order(k[5:]))
        tmp = self.csv_path.with_suffix(".csv.tmp")
        with open(tmp, "w", newline="", encoding="utf-8") as fh:
            w = csv.DictWriter(fh, fieldnames=cols, restval="")
            w.writeheader()
            w.writerows(rows)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, self.csv_path)


def coef_order(key: str) -> tuple:
    """Kxx, Kxy, Kyx, Kyy, Cxx, ..., Dyy, then the Omega^r terms (Kxx_1, ...)."""
    base, _, r = key.partition("_")
    return (int(r) if r.isdigit() else 0, "KCD".find(base[:1]), base[1:], key)


def point_csv_rows(g: h5py.Group, sim: bool) -> list[dict]:
    a = g.attrs
    settings = {
        "point": int(a["index"]),
        "label": str(a["label"]),
        "spin_rpm": f"{float(a['spin_rpm']):.6g}",
        "recess_pressure_mpa": f"{float(a['recess_pressure']) / 1e6:.6g}",
        "pressure_ratio": f"{float(a['pressure_ratio']):.6g}",
        "static_eccentricity": f"{float(a['static_eccentricity']):.6g}",
        "dynamic_eccentricity": f"{float(a['dynamic_eccentricity']):.6g}",
    }
    truth = json.loads(g["truth"].attrs["json"]) if sim and "truth" in g else None
    rows = []
    for name, h in g["identification"].items():
        row = dict(settings, lms=name.split("__")[0], model=str(h.attrs["model"]))
        if "json" in h.attrs:
            d = json.loads(h.attrs["json"])
            row.update(freq_dep=d["freq_dep"], method=d["method"], n_frequencies=d["n_frequencies"],
                       condition_number=_num(d["condition_number"], ".6g"),
                       residual_rms=_num(d["residual_rms"], ".6g"), error="")  # fmt: skip
            for k, v in d["coefficients"].items():
                row[k] = _num(v, ".8g")
                row[f"{k}_std"] = _num((d.get("std_errors") or {}).get(k), ".6g")
            keys = [k for k in d["coefficients"] if "_" not in k]
        else:
            row.update(freq_dep=str(h.attrs["freq_dep"]), method=str(h.attrs.get("method", "")),
                       error=str(h.attrs["error"]))
            keys = []
        if truth is not None:
            for k in keys:
                row[f"true_{k}"] = f"{true_entry(truth, k):.8g}"
        rows.append(row)
    return rows


def _num(v, fmt: str) -> str:
    """A CSV cell: the number in `fmt`, empty for null (the identify JSON's non-finite values)."""
    return "" if v is None else format(float(v), fmt)


def true_entry(truth: dict, key: str) -> float:
    """True constant-term value of coefficient `key` ('Kxy' ...) at the lowest |Omega|."""
    mat = truth[key[0] + "0"]
    return float(mat["xy".index(key[1])]["xy".index(key[2])])


def _versions() -> str:
    import importlib.metadata as md

    parts = [f"orbitrig {__version__}"]
    for pkg in ("numpy", "scipy", "h5py", "pymodbus", "python-can", "pydantic"):
        with contextlib.suppress(md.PackageNotFoundError):
            parts.append(f"{pkg} {md.version(pkg)}")
    return ", ".join(parts)
