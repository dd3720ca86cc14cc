"""`orbitrig acquire`: average good revolutions from the A/D board and print the fundamentals."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, NoReturn, Optional

import typer

from daq.adc_mode import AdcMode
from orbitrig.cli.config_help import RIG_CONFIG_HELP
from rigunits import in_hz

FIRST_WAIT_S = 10.0  # automatic timeout: wait this long for the orbit's first good revolution
_HINT_TURNING = (
    "is the orbit turning? start it with `orbitrig drives run --spin RPM --orbit RPM --hold` "
    "in another shell, and check the A/D board's trigger and clock"
)
_HINT_LINK = (
    "is the A/D board (or `orbitrig sim`) serving there? set [transports] adc_url in the rig config or pass --adc"
)

_HINT_MODE = "set [transports] adc_mode and the [[channels]] to the board's scan list (or pass --mode, --channels)"
_HINT_STREAM = "is [transports] adc_url (or --adc) the A/D board's frame stream, at the board's baud rate?"


def _timeout_hint(err) -> str:
    """What to look at after a DaqTimeoutError, from what came before it (daq.adc's words)."""
    said = str(err)
    if not err.heard or "the stream stopped" in said:
        return _HINT_TURNING
    if "another A/D mode" in said:
        return _HINT_MODE
    if "no valid frame" in said:
        return _HINT_STREAM
    return "is the orbit speed steady?"


#: the unit of a raw A/D reading (--counts, or no rig config), as pint parses it
RAW_UNIT = "count"


def block_summary(block, labels: dict[int, tuple[str, str]] | None = None) -> dict:
    """The JSON object of `orbitrig acquire --json`: per channel its `name` and `unit` (the rig
    config's: N, m; "count" for raw counts, name "" without a rig config); phase in degrees,
    q(theta) = Re(q_bar e^{i theta}); uncertainty: standard uncertainty of the averaged phasor,
    in the channel's unit."""
    import math

    import numpy as np

    s = block.stats
    orbit_hz = in_hz(float(block.orbit_speed))
    channels = []
    for k, (q, r, u) in enumerate(zip(block.phasors, block.rms_residual, block.uncertainty)):
        name, unit = (labels or {}).get(k, ("", RAW_UNIT))
        channels.append(
            {
                "index": k,
                "name": name,
                "unit": unit,
                "re": float(q.real),
                "im": float(q.imag),
                "amplitude": float(abs(q)),
                "phase_deg": float(np.degrees(np.angle(q))),
                "rms_residual": float(r),
                "uncertainty": float(u) if math.isfinite(u) else None,
            }
        )
    return {
        "revolutions_used": s.revolutions_used,
        "revolutions_dropped": s.revolutions_dropped,
        "frames_bad": s.frames_bad,
        "bytes_skipped": s.bytes_skipped,
        "orbit_hz": None if math.isnan(orbit_hz) else orbit_hz,
        "stop_reason": block.stop_reason,
        "channels": channels,
    }


@dataclass
class _Scan:
    """Where and what to read: URL, scan list, calibration and labels (index -> name, unit)."""

    adc: str
    channels: int
    mode: AdcMode | str | None
    gains: list[float] | None
    offsets: list[float] | None
    labels: dict[int, tuple[str, str]]
    timeout_factor: float = 3.0  # acquisition wait per revolution asked, in orbit periods


def _fail(msg: str) -> NoReturn:
    from orbitrig.cli.failure import fail

    fail(msg)


def _scan(adc, channels, mode, rig: Path | None, counts: bool) -> _Scan:
    """The scan from the options, the rig config (--rig, default config/rig.toml) filling the gaps."""
    from orbitrig.config import default_rig_path, load_rig
    from orbitrig.errors import ConfigError

    path = rig or default_rig_path()
    scan = _Scan(adc, channels, mode, None, None, {})
    if rig is not None or path.is_file():
        try:
            cfg = load_rig(path)
        except ConfigError as err:
            _fail(str(err))
        scan.adc = adc or cfg.transports.adc_url
        scan.mode = mode or cfg.transports.adc_mode
        scan.timeout_factor = cfg.averaging.timeout_factor
        if not counts:
            scan.gains, scan.offsets = cfg.gains, cfg.offsets
            scan.labels = {c.index: (c.name, c.unit) for c in cfg.ordered_channels}
        scan.channels = channels or len(cfg.gains)
    scan.channels = scan.channels or 8
    if scan.adc is None:
        _fail("--adc URL is required (or a rig config with an adc_url)")
    try:
        scan.mode = AdcMode(scan.mode or AdcMode.SEQUENTIAL)
    except ValueError:
        _fail(f"--mode must be {' or '.join(AdcMode)}, not {scan.mode!r}")
    if scan.gains is not None and len(scan.gains) != scan.channels:
        _fail(f"--channels {scan.channels} but the rig config calibrates {len(scan.gains)} channels")
    return scan


def _rule(revolutions: int, target: float | None, min_revolutions: int):
    import math

    from daq.averaging_rule import AveragingRule
    from orbitrig.config import MAX_REVOLUTIONS

    if revolutions > MAX_REVOLUTIONS:
        _fail(
            f"--revolutions {revolutions}: at most {MAX_REVOLUTIONS} (as the rig configuration's [averaging] revolutions)"
        )
    if target is None:
        return AveragingRule.fixed(revolutions)
    if not (math.isfinite(target) and target > 0):
        _fail(f"--target must be a positive percentage, not {target}")
    try:
        return AveragingRule.adaptive(target / 100, min(min_revolutions, revolutions), revolutions)
    except ValueError as err:
        _fail(str(err))


def _acquire(scan: _Scan, rule, timeout: float | None):
    """Run the reader; exit 2 with a hint at the cause on any acquisition failure."""
    import asyncio

    from daq.adc import AdcReader
    from daq.errors import DaqError, DaqLinkError, DaqTimeoutError

    wait, per_rev = (timeout, None) if timeout is not None else (FIRST_WAIT_S, scan.timeout_factor)

    async def run():
        async with AdcReader(
            scan.adc, channels=scan.channels, mode=scan.mode, gains=scan.gains, offsets=scan.offsets, reconnect=True
        ) as reader:
            return await reader.acquire(rule, timeout=wait, per_revolution=per_rev)

    try:
        return asyncio.run(run())
    except ValueError as err:  # bad scan list (channels not dividing 360 ...)
        _fail(str(err))
    except DaqTimeoutError as err:
        hint = _timeout_hint(err)
        if timeout is not None and hint != _HINT_MODE:  # frames of another mode: more time makes none good
            hint += "; or raise --timeout"
        _fail(f"{err}\n  {hint}")
    except DaqLinkError as err:
        _fail(f"{err}\n  {_HINT_LINK}")
    except DaqError as err:
        _fail(str(err))


def _print_table(block, labels: dict[int, tuple[str, str]]) -> None:
    from daq.averaging_rule import StopReason

    out = block_summary(block, labels)
    s = block.stats
    reasons = f" {dict(s.drop_reasons)}" if s.drop_reasons else ""
    stop = "" if block.stop_reason is StopReason.COUNT else f" (stopped: {block.stop_reason})"
    typer.echo(
        f"{out['revolutions_used']} revolutions averaged{stop}, {out['revolutions_dropped']} dropped"
        f"{reasons}, frames bad {out['frames_bad']}, "
        f"bytes skipped {out['bytes_skipped']}, orbit {out['orbit_hz'] or float('nan'):.4f} Hz"
    )
    typer.echo(
        f"{'ch':>3} {'re':>12} {'im':>12} {'amplitude':>12} {'phase deg':>10} {'rms resid':>12} {'u %':>8}  unit   name"
    )
    for c in out["channels"]:
        name, unit = c["name"], c["unit"]
        rel = (
            float("nan") if c["uncertainty"] is None or not c["amplitude"] else 100 * c["uncertainty"] / c["amplitude"]
        )
        typer.echo(
            f"{c['index']:>3} {c['re']:>12.5g} {c['im']:>12.5g} {c['amplitude']:>12.5g} "
            f"{c['phase_deg']:>10.3f} {c['rms_residual']:>12.5g} {rel:>8.2g}  {unit:<6} {name}".rstrip()
        )


Adc = Annotated[
    Optional[str],
    typer.Option(
        "--adc",
        help="A/D board URL: /dev/ttyUSB0, a pty path, socket://host:port (default: the rig config's adc_url).",
    ),
]
Channels = Annotated[
    Optional[int],
    typer.Option("--channels", min=1, help="Channels in the scan list (default: the rig config's, else 8)."),
]
Mode = Annotated[
    Optional[str],
    typer.Option("--mode", help=f"{' | '.join(AdcMode)} (default: the rig config's, else {AdcMode.SEQUENTIAL})."),
]
Revolutions = Annotated[
    int, typer.Option("--revolutions", min=1, help="Good revolutions to average (with --target: the most).")
]
Target = Annotated[
    Optional[float],
    typer.Option(
        "--target",
        help="Stop as soon as every channel's phasor uncertainty is below this percentage of its amplitude.",
    ),
]
MinRevolutions = Annotated[int, typer.Option("--min-revolutions", min=2, help="With --target: the fewest.")]
Timeout = Annotated[
    Optional[float],
    typer.Option(
        "--timeout",
        min=0.001,
        max=1e6,
        help="Seconds to wait "
        "(default: 10 s for the first revolution plus the rig config's "
        "timeout_factor x revolutions x measured orbit period).",
    ),
]
Rig = Annotated[
    Optional[Path],
    typer.Option(
        "--rig",
        "--config",
        help=f"{RIG_CONFIG_HELP}: URL, scan and calibration to engineering units (SI)",
    ),
]
Counts = Annotated[bool, typer.Option("--counts", help="Raw counts (gain 1, offset 0), not calibrated.")]
AsJson = Annotated[bool, typer.Option("--json", help="Print one JSON object.")]


def register(app: typer.Typer) -> None:
    @app.command("acquire")
    def acquire(
        adc: Adc = None,
        channels: Channels = None,
        mode: Mode = None,
        revolutions: Revolutions = 50,
        target: Target = None,
        min_revolutions: MinRevolutions = 10,
        timeout: Timeout = None,
        rig: Rig = None,
        counts: Counts = False,
        as_json: AsJson = False,
    ) -> None:
        """Average good revolutions of the clocked A/D board; print each channel's fundamental.

        Phasors in engineering units of the rig config (N, m), or raw counts with --counts;
        q(theta) = Re(q_bar e^{i theta}), theta the orbit angle after the trigger; "u %" is the
        standard uncertainty of the averaged phasor relative to its amplitude, to 2 significant
        digits (an uncertainty from n revolutions is itself uncertain by about 1 / sqrt(2 (n - 1))). Exit 2 if the
        link cannot be opened or the revolutions do not arrive in time.
        """
        import json
        import math

        if timeout is not None and not math.isfinite(timeout):
            _fail(f"--timeout must be a finite number of seconds, not {timeout}")
        scan = _scan(adc, channels, mode, rig, counts)
        block = _acquire(scan, _rule(revolutions, target, min_revolutions), timeout)
        if as_json:
            typer.echo(json.dumps(block_summary(block, scan.labels)))
        else:
            _print_table(block, scan.labels)
