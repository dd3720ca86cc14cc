"""Crash safety: a sweep killed with SIGKILL mid-run, then resumed: every point present once."""

import csv
import os
import re
import signal
import subprocess
import time

import h5py
import numpy as np
import pytest

from orbitrig.store.reader import read_run

from support.cli_helpers import orbitrig, orbitrig_started, reaped

# four points; the spin speeds close together, so that the ramps between points are short
MATRIX = """
name = "crash"
revolutions = 10
[operating]
spin_rpm = [1000.0, 1200.0]
recess_pressure_mpa = [0.4826]
pressure_ratio = [0.4]
static_eccentricity = [0.0, 0.15]
dynamic_eccentricity = [0.096]
[orbit]
ratios = [0.3, 0.6, 0.9]
[[models]]
model = "kc8"
"""


def _cut_point(log) -> bool:
    """True once run.log shows a completed point and a stored block of a point not completed."""
    text = log.read_text() if log.exists() else ""
    complete = set(re.findall(r"point (\d{4}) \S+: complete", text))
    stored = set(re.findall(r"point (\d{4}): stored", text))
    return bool(complete) and bool(stored - complete)


@pytest.mark.timeout(150)
def test_kill_9_mid_run_then_resume(tmp_path):
    matrix = tmp_path / "crash.toml"
    matrix.write_text(MATRIX)
    out = tmp_path / "run"
    log = out / "run.log"
    args = ("sweep", "--sim", "--sim-config", "config/sim/clean.toml", "--matrix", str(matrix), "--out", str(out))
    with reaped(orbitrig_started(*args, stdin=None, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)) as proc:
        # kill once a point is complete and a later one has stored a block (identification and
        # storage run in the background, so which points these are depends on the machine's load)
        deadline = time.monotonic() + 60
        while not _cut_point(log):
            assert proc.poll() is None, "the sweep ended before it could be killed"
            assert time.monotonic() < deadline, "the sweep made no progress"
            time.sleep(0.005)
        os.kill(proc.pid, signal.SIGKILL)
        assert proc.wait(10) == -signal.SIGKILL
    assert not (out / "run.h5").exists()  # consolidated only when a run ends
    cut = read_run(out)  # the durable pieces
    assert cut.status == "running"  # cut off: never marked as ended
    done = [p.name for p in cut.points if p.complete]
    partial = [p.name for p in cut.points if not p.complete]
    assert done and partial, (done, partial)
    assert sorted({r["point"] for r in csv.DictReader(open(out / "coefficients.csv"))}) == [str(int(n)) for n in done]

    p = orbitrig("sweep", "--sim", "--resume", str(out), timeout=120, columns=None)
    assert p.returncode == 0, p.stdout + p.stderr
    assert "simulator scenario of the run: config/sim/clean.toml" in p.stderr  # stored, not given again
    for point in read_run(out).points:  # the clean bearing (Z exactly constant K, C, D) at every point
        t = point.truth
        w, c = np.abs(np.asarray(t["orbit"]))[:, None, None], t["fits"]["constant"]
        fit = np.asarray(c["K"]) + 1j * w * np.asarray(c["C"]) - w**2 * np.asarray(c["D"])
        z = np.asarray(t["Z_re"]) + 1j * np.asarray(t["Z_im"])
        assert np.abs(fit - z).max() < 1e-6 * np.abs(z).max(), point.name
    text = log.read_text()
    for name in partial:
        assert f"resume: point {name} set aside as aside/{name}.incomplete.1" in text
        assert f"point {name} set aside as" in p.stderr  # and on the terminal
    assert f"{4 - len(done)} of 4 points to run" in text
    # the resume counts the run's points, those measured before it included (as its progress and bars do)
    first = rf"measuring point {len(done) + 1} of 4 \({len(done)} measured before the resume\)"
    assert re.search(rf"\] {first}: \S+ \(point \d{{4}}\)$", text, re.M), text
    assert re.search(r"\] measuring point 1 of 4: \S+ \(point 0000\)$", text, re.M), text  # the first session's
    with h5py.File(out / "run.h5", "r") as f:
        assert f.attrs["status"] == "completed"
        for name in ("events", "drives", "can"):  # one time axis: s since the run started, both sessions
            t = np.asarray(f[f"logs/{name}"]["t"])
            assert t.size > 2 and np.all(np.diff(t) >= 0), (name, t[np.flatnonzero(np.diff(t) < 0)[:3]])
        assert list(f["points"]) == ["0000", "0001", "0002", "0003"]
        for name, g in f["points"].items():
            assert g.attrs["complete"], name
            assert sorted(g["frequencies"]) == sorted(f"{k:02d}_{d}" for k in range(3) for d in ("fwd", "bwd"))
            assert all(b.attrs["complete"] for b in g["frequencies"].values())
            assert g["frequencies/00_fwd/raw_counts"].shape[0] == 10
    rows = list(csv.DictReader(open(out / "coefficients.csv")))
    assert sorted((r["point"], r["lms"]) for r in rows) == sorted(
        (str(i), l) for i in range(4) for l in ("piezo", "strain")
    )

    again = orbitrig("sweep", "--sim", "--out", str(out), timeout=60, columns=None)
    assert again.returncode == 2 and "already exists: use --resume" in again.stderr


@pytest.mark.timeout(120)
@pytest.mark.parametrize(
    "answer, code, status", [("ctrl-c", 4, "aborted"), ("s\n", 3, "stopped"), ("r\n", 0, "completed")]
)
def test_ctrl_c_pauses_and_asks_twice_aborts(tmp_path, answer, code, status):
    matrix = tmp_path / "crash.toml"
    matrix.write_text(MATRIX)
    out = tmp_path / "run"
    log = out / "run.log"
    proc = orbitrig_started("sweep", "--sim", "--matrix", str(matrix), "--out", str(out), stdin=subprocess.PIPE)

    def alive(deadline: float) -> None:
        if proc.poll() is not None:  # say why: the sweep's own words
            raise AssertionError(
                f"sweep exited with {proc.returncode}:\n{proc.stderr.read()}\n"
                f"{log.read_text() if log.exists() else '(no run.log)'}"
            )
        assert time.monotonic() < deadline, "timed out"

    with reaped(proc):
        deadline = time.monotonic() + 60
        while not (log.exists() and "stored" in log.read_text()):
            alive(deadline)
            time.sleep(0.005)
        proc.send_signal(signal.SIGINT)
        while "[paused] paused at a safe point" not in log.read_text():
            alive(deadline)
            time.sleep(0.005)
        time.sleep(0.3)
        assert proc.poll() is None  # holds, waiting for the operator
        if answer == "ctrl-c":
            proc.send_signal(signal.SIGINT)
            stdout, stderr = proc.communicate(timeout=30)
        else:
            stdout, stderr = proc.communicate(answer, timeout=60)
    assert proc.returncode == code, stdout + stderr
    assert "[r]esume, [s]top, [a]bort" in stderr
    assert f"run {status}" in stderr
    with h5py.File(out / "run.h5", "r") as f:
        assert f.attrs["status"] == status
