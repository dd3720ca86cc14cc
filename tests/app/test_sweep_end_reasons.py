"""The stored run of `orbitrig sweep --sim` says truthfully why it ended and who asked: run.log,
run.h5's status_message and /logs/commands name the operator and the signal or cause; a stop
says that `--resume` measures the point it left incomplete again from its start (its blocks
kept in aside/), and the resume does so. The real signals sent to a real subprocess."""

import json
import re
import signal
import subprocess
from pathlib import Path

import h5py
import pytest

from orbitrig import config as cfg
from orbitrig.run.provenance import software_version
from support.store_checks import small_matrix
from support.sweep_process import SweepProcess, sweeps

pytestmark = pytest.mark.timeout(150)

MATRIX = small_matrix("reasons", 20, spin_rpm=(1000.0,))
RESUME_NOTE = "orbitrig sweep --resume measures it again from its start (its blocks so far kept in aside/)"


class Sweep(SweepProcess):
    """`orbitrig sweep --sim --operator ada` of MATRIX in a subprocess (SweepProcess)."""

    def __init__(self, work: Path, *extra: str):
        (work / "m.toml").write_text(MATRIX)
        super().__init__(work / "run", "--matrix", str(work / "m.toml"), *extra)

    def start(self, *args: str, speedup: int = 5) -> subprocess.Popen:
        return super().start("--operator", "ada", "--speedup", str(speedup), *args)

    def answer(self, line: str) -> None:
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()

    def finish(self, timeout: float = 60.0) -> tuple[int, str]:
        code = self.proc.wait(timeout)  # standard input stays open: nobody closed the terminal
        err = self.proc.stderr.read()
        self.proc.stdin.close()
        return code, " ".join(err.split())  # the closing line as one line, however the terminal wrapped it

    def stored(self) -> tuple[str, str, list[tuple[str, str, str]]]:
        """run.h5's status, status_message and /logs/commands (command, by, detail)."""
        with h5py.File(self.out / "run.h5", "r") as f:
            rows = [(c["command"].decode(), c["by"].decode(), c["detail"].decode()) for c in f["logs/commands"][()]]
            return str(f.attrs["status"]), str(f.attrs["status_message"]), rows


@pytest.fixture
def sweep(tmp_path):
    with sweeps(lambda *extra: Sweep(tmp_path, *extra)) as start:
        yield start


def test_a_closed_terminal_at_the_pause_prompt_is_recorded_as_that_signal(sweep):
    s = sweep()
    s.wait_log("[running] speeds set: spin 1000 rpm")
    s.proc.send_signal(signal.SIGINT)
    s.wait_log("[paused] paused at a safe point")
    s.proc.send_signal(signal.SIGHUP)  # the terminal closed while the prompt waits
    code, err = s.finish()
    assert code == 4, err
    why = "aborted by ada (SIGHUP: the terminal was closed; a second signal)"
    assert f"run aborted: {why}" in err, err
    status, message, commands = s.stored()
    assert status == "aborted" and message.startswith(why), message
    assert commands[-1] == ("abort", "ada (SIGHUP: the terminal was closed; a second signal)", ""), commands
    log = s.text()
    assert "command abort by ada (SIGHUP: the terminal was closed; a second signal)" in log
    assert f"ended: aborted: {why}" in log and "by the operator" not in log, log


def test_a_stop_at_the_prompt_says_resume_measures_the_point_again_and_it_does(sweep):
    s = sweep()
    s.wait_log("point 0000: stored")  # one block of the point is stored
    s.proc.send_signal(signal.SIGINT)
    s.wait_log("[paused] paused at a safe point")
    s.answer("s")
    code, err = s.finish()
    assert code == 3, err
    stored = sorted(p.name for p in (s.out / "points" / "0000").glob("*.h5") if p.name != "results.h5")
    n = len(stored)
    assert 1 <= n < 3, stored
    blocks = f"{n} of 6 blocks stored"  # of the point's 6 (small_matrix: 3 orbit ratios, both whirls)
    closing = f"run stopped: stopped by ada; point 0000 ({blocks}) is incomplete: {RESUME_NOTE}"
    assert closing in err, err
    status, message, commands = s.stored()
    assert status == "stopped" and message == closing.removeprefix("run stopped: "), message
    assert commands[-1] == ("stop", "ada", ""), commands
    log = s.text()
    assert "[stopping] stop requested by ada: finishing the current orbit frequency" in log
    assert (
        "a point left incomplete is measured again from its start by orbitrig sweep --resume (its blocks so far kept in aside/)"
        in log
    )
    # what the messages said is what --resume does: the point set aside with its blocks, measured again;
    # resumed by another operator with another software version (the run as an older release left it)
    header = json.loads((s.out / "run.json").read_text())
    assert header["provenance"]["operator"] == "ada"
    assert header["provenance"]["calibration_record_seal"] == "as written"  # the record's SHA-256 line matches
    assert re.search(r"provenance: .* calibration record \S+ \(sha256 [0-9a-f]{12}, as written\)\n", log), log
    header["provenance"]["software_version"] = "orbitrig 0.0.1"
    (s.out / "run.json").write_text(json.dumps(header))
    s.proc = s.start("--resume", "--operator", "bob", speedup=20)
    code, err = s.finish(120)
    assert code == 0, err
    now = software_version()  # the version number and the source revision
    log = s.text()
    assert f"resume provenance: operator bob, {now}, rig " in log, log
    warning = f"warning: resumed with {now}; the run started with orbitrig 0.0.1"
    assert warning in log and warning in err, err
    starts = [(by, detail.endswith(", resumed")) for cmd, by, detail in s.stored()[2] if cmd == "start"]
    assert starts == [("ada", False), ("bob", True)], starts
    aside = s.out / "aside" / "0000.incomplete.1"
    assert sorted(p.name for p in aside.glob("*.h5")) == stored, list(aside.iterdir())
    assert (s.out / "points" / "0000" / "complete.json").is_file()


def test_a_pause_nobody_answers_is_recorded_as_stopped_by_orbitrig(sweep, tmp_path):
    """Standard input not a terminal: nobody can answer the pause; the run stops itself after
    [interlocks] unanswered_pause_s (1 s here), and says so instead of naming the operator."""
    rig = tmp_path / "rig.toml"
    text = cfg.default_rig_path().read_text()
    old = f"unanswered_pause_s = {cfg.load_rig().interlocks.unanswered_pause_s!r}"
    assert old in text, old
    rig.write_text(text.replace(old, "unanswered_pause_s = 1.0"))
    s = sweep("--config", str(rig))
    s.wait_log("[running] speeds set: spin 1000 rpm")
    s.proc.send_signal(signal.SIGINT)
    code, err = s.finish()
    assert code == 3, err
    who = "orbitrig (nobody can answer: paused for 1 s, no terminal and no MQTT)"
    status, message, commands = s.stored()
    assert status == "stopped" and message.startswith(f"stopped by {who}"), message
    assert commands[-1] == ("stop", who, ""), commands
    assert f"run stopped: stopped by {who}" in err, err
    assert "by the operator" not in s.text()
