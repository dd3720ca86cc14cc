"""`orbitrig drives run --hold` and the drive status lines of `orbitrig drives`."""

from __future__ import annotations

import typer


def _drive_line(d: dict) -> str:
    flags = ", at setpoint" if d["at_setpoint"] else ""
    return (
        f"{d['state']}{flags}; REF {d['reference_rpm']:.1f} rpm, ACT {d['actual_rpm']:.1f} rpm, "
        f"torque {d['torque_pct']:.1f} %, fault {d['fault_code']} ({d['fault']}), "
        f"CW {d['control_word']}, SW {d['status_word']}"
    )


def _state_lines(state) -> None:
    for s in (state.spin, state.orbit):
        typer.echo(f"{s.name:5s} (id {s.device_id}): {_drive_line(s.to_dict())}")


def _hold_line(state, held: float) -> str:
    parts = []
    for s in (state.spin, state.orbit):
        if s is not None:
            d = s.to_dict()
            flag = "at setpoint" if d["at_setpoint"] else d["state"]
            parts.append(f"{s.name} {d['actual_rpm']:.1f} rpm ({flag})")
    link = "link ok" if state.link_ok else f"LINK DOWN ({state.link_error})"
    return f"holding {held:.0f} s: {', '.join(parts)}; {link}, polls {state.polls}, poll failures {state.poll_failures}"


def stopped_elsewhere(state, refs: tuple[int, int]) -> str | None:
    """Which drive no longer follows what `run` commanded (raw REFs `refs`):
    not running any more, or given another reference (another client stopped
    or moved it). None while both follow."""
    found = []
    for s, ref in zip((state.spin, state.orbit), refs):
        if s is None:
            continue
        if not s.running:
            found.append(f"the {s.name} drive (id {s.device_id}) is no longer running ({s.state})")
        elif s.reference_raw != ref:
            found.append(
                f"the {s.name} drive (id {s.device_id}) was given another reference "
                f"({s.to_dict()['reference_rpm']:.1f} rpm)"
            )
    return "; ".join(found) or None


async def _hold(rig, refs: tuple[int, int], status_every: float, interrupt) -> int:
    """`run --hold`: poll at the setpoint until SIGINT/SIGTERM/SIGHUP (exit 0) or until
    another client stops or moves a drive (exit 2); both end with both drives
    ramped to zero and at standstill. A second signal during that ramp makes it an
    emergency stop (exit 4)."""
    import asyncio
    import time

    from drives.errors import DriveLinkError
    from orbitrig.run.safe_stop import stop_drives

    typer.echo(
        "holding at the setpoint; Ctrl-C, SIGTERM or SIGHUP ramps both drives to zero (a second one: emergency stop)",
        err=True,
    )
    interrupt.holding = True
    t0 = last = time.monotonic()
    elsewhere = None
    while not interrupt.event.is_set() and elsewhere is None:
        try:
            await asyncio.wait_for(interrupt.event.wait(), rig.poll_interval)
        except asyncio.TimeoutError:
            pass
        state = rig.check()  # a trip found by the poll (both already stopping)
        if not state.link_ok:
            raise DriveLinkError(
                f"link lost while holding ({state.link_error}); the drives' comm-loss watchdog stops them"
            )
        elsewhere = stopped_elsewhere(state, refs)
        now = time.monotonic()
        if now - last >= status_every and not interrupt.event.is_set() and elsewhere is None:
            last = now
            typer.echo(_hold_line(state, now - t0))
    held = time.monotonic() - t0
    if elsewhere is not None:
        typer.echo(
            f"orbitrig drives run: after {held:.0f} s at the setpoint {elsewhere}: "
            "stopped or changed by another client; ramping both drives to zero",
            err=True,
        )
    else:
        typer.echo(f"{interrupt.received[-1].name}: ramping both drives to zero", err=True)
    interrupt.holding, interrupt.ramping = False, True
    escalated, line = await stop_drives(rig, interrupt.abort, emergency=False, timeout=None)
    interrupt.ramping = False
    _state_lines(rig.state)
    ramp = time.monotonic() - t0 - held
    typer.echo(
        f"held the setpoint for {held:.0f} s; both drives stopped (standstill {ramp:.1f} s later)"
        + ("; the hold was ended by another client" if elsewhere else "")
    )
    if escalated:
        typer.echo(f"{interrupt.received[-1].name} again during the ramp: {line}", err=True)
        return 4
    return 2 if elsewhere else 0
