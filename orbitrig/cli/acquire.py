"""`orbitrig acquire`: read N good revolutions from the A/D board and print the fundamentals."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer


def block_summary(block) -> dict:
    """The JSON object of `orbitrig acquire --json` (units: counts, or engineering
    units with a rig config; phase in degrees, q(theta) = Re(q_bar e^{i theta}))."""
    import math

    import numpy as np

    s = block.stats
    orbit_hz = block.orbit_speed / (2 * math.pi)
    return {
        "revolutions_used": s.revolutions_used,
        "revolutions_dropped": s.revolutions_dropped,
        "frames_bad": s.frames_bad,
        "bytes_skipped": s.bytes_skipped,
        "orbit_hz": None if math.isnan(orbit_hz) else orbit_hz,
        "channels": [
            {"index": k, "re": float(q.real), "im": float(q.imag), "amplitude": float(abs(q)),
             "phase_deg": float(np.degrees(np.angle(q))), "rms_residual": float(r)}
            for k, (q, r) in enumerate(zip(block.phasors, block.rms_residual))
        ],
    }


def register(app: typer.Typer) -> None:
    @app.command("acquire")
    def acquire(
        adc: Optional[str] = typer.Option(None, "--adc", help="A/D board URL: /dev/ttyUSB0, a pty path, "
                                          "socket://host:port (default: the rig config's adc_url)."),
        channels: Optional[int] = typer.Option(None, "--channels", help="Channels in the scan list (default 8, "
                                               "or the rig config's)."),
        mode: Optional[str] = typer.Option(None, "--mode", help="sequential | simultaneous (default sequential, "
                                           "or the rig config's)."),
        revolutions: int = typer.Option(50, "--revolutions", min=1, help="Good revolutions to average."),
        timeout: float = typer.Option(10.0, "--timeout", help="Seconds to wait for them."),
        rig: Optional[Path] = typer.Option(None, "--rig", help="Rig config (rig.toml): calibrate to "
                                           "engineering units with its gains and offsets."),
        as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
    ) -> None:
        """Average N good revolutions of the clocked A/D board; print each channel's fundamental.

        Without --rig the phasors are in raw counts (gain 1, offset 0). Exit 2 if the link
        cannot be opened or the revolutions do not arrive within --timeout.
        """
        import asyncio
        import json

        from daq.adc import AdcReader
        from daq.errors import DaqError

        def fail(msg: str) -> None:
            typer.echo(f"orbitrig acquire: {msg}", err=True)
            raise typer.Exit(2)

        gains = offsets = None
        labels: dict[int, tuple[str, str]] = {}  # index -> (channel name, unit), from --rig
        if rig is not None:
            from orbitrig.config import load_rig
            from orbitrig.errors import ConfigError

            try:
                cfg = load_rig(rig)
            except ConfigError as err:
                fail(str(err))
            gains, offsets = cfg.gains, cfg.offsets
            labels = {c.index: (c.name, c.unit) for c in cfg.ordered_channels}
            adc = adc or cfg.transports.adc_url
            channels = channels or len(gains)
            mode = mode or cfg.transports.adc_mode
        if adc is None:
            fail("--adc URL is required (or --rig with an adc_url)")
        channels = channels or 8
        mode = mode or "sequential"
        if mode not in ("sequential", "simultaneous"):
            fail(f"--mode must be sequential or simultaneous, not {mode!r}")
        if gains is not None and len(gains) != channels:
            fail(f"--channels {channels} but the rig config calibrates {len(gains)} channels")

        async def run():
            async with AdcReader(adc, channels=channels, mode=mode, gains=gains, offsets=offsets,
                                 reconnect=True) as reader:
                return await reader.acquire(revolutions, timeout=timeout)

        try:
            block = asyncio.run(run())
        except ValueError as err:  # bad scan list (channels not dividing 360 ...)
            fail(str(err))
        except DaqError as err:
            fail(str(err))
        out = block_summary(block)
        if as_json:
            typer.echo(json.dumps(out))
            return
        reasons = f" {dict(block.stats.drop_reasons)}" if block.stats.drop_reasons else ""
        typer.echo(f"{out['revolutions_used']} revolutions averaged, {out['revolutions_dropped']} dropped"
                   f"{reasons}, frames bad {out['frames_bad']}, "
                   f"bytes skipped {out['bytes_skipped']}, orbit {out['orbit_hz'] or float('nan'):.4f} Hz")
        typer.echo(f"{'ch':>3} {'re':>12} {'im':>12} {'amplitude':>12} {'phase deg':>10} {'rms resid':>12}  unit   name")
        for c in out["channels"]:
            name, unit = labels.get(c["index"], ("", "counts"))
            typer.echo(f"{c['index']:>3} {c['re']:>12.5g} {c['im']:>12.5g} {c['amplitude']:>12.5g} "
                       f"{c['phase_deg']:>10.3f} {c['rms_residual']:>12.5g}  {unit:<6} {name}".rstrip())
