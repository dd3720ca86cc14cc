"""Rig configurations of tests that run the service or a sweep on the simulator."""

from __future__ import annotations

from pathlib import Path

from .paths import ROOT


def patient_rig_config(folder: Path) -> Path:
    """The shipped rig.toml with a patient Modbus link (1 s per request, so a command fails after
    2 s with its one retry; lost after 5 failed polls, 5.5 s) and a 10 s drive watchdog (written
    to the drives at the run's start), in `folder`.

    For tests whose subject is not the link's loss but that run where the simulator or the
    service may stall for longer than the rig's 0.15 s x 3 polls: under strace (every traced
    system call stops the process for a while), under a flood of MQTT commands, or with both
    cores kept busy (tools/cpu-hog: a simulator process starting a resumed sweep there once
    left a speed command unanswered for over 1 s, the 0.5 s request and its retry)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "rig.toml"
    path.write_text(patient_link((ROOT / "config" / "rig.toml").read_text()))
    return path


#: the patient drive link: ([drives] key, the shipped value's text, the patient value)
PATIENT_LINK = (("timeout_s", "0.15", 1.0), ("link_loss_polls", "3", 5), ("comm_loss_timeout_s", "1.0", 10.0))


def patient_link(text: str) -> str:
    """The rig.toml `text` (the shipped timing) with the patient link of `patient_rig_config`."""
    for key, shipped, patient in PATIENT_LINK:
        old = f"{key} = {shipped}"
        assert old in text, old
        text = text.replace(old, f"{key} = {patient}")
    return text


def drive_lines(text: str, changes: tuple[tuple[str, str], ...]) -> str:
    """The rig.toml `text` with each whole line `old` of `changes` (one of [drives]' timing lines,
    e.g. 'timeout_s = 1.0') replaced by `new`; each must stand there exactly once."""
    for old, new in changes:
        assert text.count(f"\n{old}") == 1, old
        text = text.replace(f"\n{old}", f"\n{new}")
    return text


def patient_rig():
    """config/rig.toml loaded, with the patient link of `patient_rig_config`: for in-process runs
    whose subject is not the link, so that a test process starved with both cores busy does not
    trip the drives' 1 s watchdog."""
    from orbitrig.config import load_rig

    rig = load_rig()
    patient = {key: value for key, _, value in PATIENT_LINK}
    return rig.model_copy(update={"drives": rig.drives.model_copy(update=patient)})


def patient_lab(folder: Path) -> Path:
    """A lab configuration in `folder` as `orbitrig init` writes it (matrices, designs,
    calibration, broker files), its rig.toml that of `patient_rig_config`, which names the shipped
    initial record: in calibration/ in place of the one init dated when it wrote it; returns `folder`."""
    import shutil

    from orbitrig.config import write_lab

    for written in write_lab(folder):
        if written.name.endswith("-initial.toml"):
            written.unlink()
    for record in (ROOT / "config" / "calibration").glob("*.toml"):
        shutil.copyfile(record, folder / "calibration" / record.name)
    patient_rig_config(folder)
    return folder


#: the rig.toml lines of a rig without a CAN sensor node: neither interlock that counts on it
NO_CAN_NODE = (
    ("check_supply_pressure = true", "check_supply_pressure = false"),
    ("check_can_heartbeat = true", "check_can_heartbeat = false"),
)


def without_can_node(text: str) -> str:
    """The rig.toml `text` of a rig without a CAN sensor node (NO_CAN_NODE)."""
    for on, off in NO_CAN_NODE:
        assert on in text, on
        text = text.replace(on, off)
    return text


def modbus_only_lab(folder: Path) -> Path:
    """A lab as `patient_lab` whose rig has no CAN sensor node ([interlocks] check_supply_pressure
    and check_can_heartbeat off): for `orbitrig drives run` against the simulator's drives alone
    (a Modbus server, no CAN bus), which otherwise opens the node to watch the lubricant supply and
    refuses to start without it; returns `folder`."""
    patient_lab(folder)
    path = folder / "rig.toml"
    path.write_text(without_can_node(path.read_text()))
    return folder


#: the name tests give a lab's own calibration record (`lab_record_config`)
LAB_RECORD = "2026-12-01T000000Z-loads"


def sealed(text: str) -> str:
    """A record's `text` as a step writes it: holding the SHA-256 of its own text (its `sha256`
    line replaced, or added after its first line of `previous`; orbitrig.config.record_seal)."""
    import re

    from orbitrig.config.record_seal import NOTE, PLACEHOLDER, seal

    line = f'sha256 = "{PLACEHOLDER}"  # {NOTE}'
    text, n = re.subn(r"^sha256 = .*$", line, text, count=1, flags=re.M)
    if not n:
        text, n = re.subn(r"^(previous = .*)$", rf"\1\n{line}", text, count=1, flags=re.M)
    assert n == 1, text
    return seal(text)


def loads_record(gain: float) -> str:
    """A `loads` record of the shipped rig (its strain gauges' gain `gain` on both axes), made
    after the shipped initial record, as a step writes it (sealed)."""
    return sealed(f"""date = "2026-12-01T00:00:00+00:00"
operator = "test"
rig = "double-spool rig"
step = "loads"
previous = "2026-11-26T214732Z-initial"
[reference]
id = "dead-weights"
uncertainty_pct = 0.1
[loads.strain]
gain = [[{gain}, 0.0], [0.0, {gain}]]
gain_u = [[0.001, 0.0], [0.0, 0.001]]
""")


def lab_record_config(folder: Path, record: str | None = None, edits: dict[str, str] | None = None) -> Path:
    """A copy of the tests' lab rig.toml (ORBITRIG_HOME) with its calibration records in
    `folder`; `record`: the text of a record only this copy has (LAB_RECORD), made the active
    one; `edits`: a line starting with each key replaced by its value. Returns the rig.toml."""
    import shutil

    from orbitrig.config import default_rig_path

    started = default_rig_path()
    shutil.copytree(started.parent / "calibration", folder / "calibration")
    text = started.read_text()
    changes = dict(edits or {})
    if record is not None:
        (folder / "calibration" / f"{LAB_RECORD}.toml").write_text(record)
        changes["calibration_record"] = f'calibration_record = "{LAB_RECORD}"'
    for key, line in changes.items():
        old = next(ln for ln in text.splitlines() if ln.startswith(key))
        text = text.replace(old, line)
    (folder / "rig.toml").write_text(text)
    return folder / "rig.toml"


def interlocked_rig(**interlock_keys):
    """The shipped config/rig.toml with some [interlocks] keys changed (the file must name them)."""
    from orbitrig import config as cfg

    text = cfg.default_rig_path().read_text()
    shipped = cfg.load_rig().interlocks.model_dump()
    for key, value in interlock_keys.items():
        old = f"{key} = {shipped[key]!r}"
        assert old in text, old
        text = text.replace(old, f"{key} = {value!r}")
    return cfg.rig_from_text(text, "rig.toml")


def rig_without_answer(tmp_path):
    """(path, {key: value}): config/rig.toml in `tmp_path` with every transport pointed at a port
    nothing listens on."""
    import re

    from .ports import free_port

    adc, modbus, can = free_port(), free_port(), free_port()  # nothing listens there
    text = (ROOT / "config" / "rig.toml").read_text()
    subs = {
        "adc_url": f"socket://127.0.0.1:{adc}",
        "modbus_url": f"tcp://127.0.0.1:{modbus}",
        "can_channel": f"socket://127.0.0.1:{can}",
        "can_interface": "serial",
    }
    for key, value in subs.items():
        text, n = re.subn(rf'(?m)^{key}\s*=\s*"[^"]*"', f'{key} = "{value}"', text)
        assert n == 1, key
    path = tmp_path / "rig.toml"
    path.write_text(text)
    return path, subs
