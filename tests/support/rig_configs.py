"""Rig configurations of tests that run the service or a sweep on the simulator."""

from __future__ import annotations

from pathlib import Path

from support.paths import ROOT


def patient_rig_config(folder: Path) -> Path:
    """The shipped rig.toml with a patient Modbus link (1 s per request, so a command fails after
    2 s with its one retry; lost after 5 failed polls, 5.5 s) and a 10 s drive watchdog (written
    to the drives at the run's start), in `folder`.

    For tests whose subject is not the link's loss but that run where the simulator or the
    service may stall for longer than the rig's 0.15 s x 3 polls: under strace (every traced
    system call stops the process for a while), under a flood of MQTT commands, or with both
    cores kept busy (tools/cpu-hog: a simulator process starting a resumed sweep there once
    left a speed command unanswered for over 1 s, the 0.5 s request and its retry)."""
    text = (ROOT / "config" / "rig.toml").read_text()
    for old, new in (
        ("timeout_s = 0.15", "timeout_s = 1.0"),
        ("link_loss_polls = 3", "link_loss_polls = 5"),
        ("comm_loss_timeout_s = 1.0", "comm_loss_timeout_s = 10.0"),
    ):
        assert old in text, old
        text = text.replace(old, new)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "rig.toml"
    path.write_text(text)
    return path


def patient_lab(folder: Path) -> Path:
    """A lab configuration in `folder` as `orbitrig init` writes it (matrices, designs,
    calibration, broker files), its rig.toml that of `patient_rig_config`; returns `folder`."""
    from orbitrig.config import write_lab

    write_lab(folder)
    patient_rig_config(folder)
    return folder
