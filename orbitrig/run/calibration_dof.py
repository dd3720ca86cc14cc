"""The degrees of freedom of the rig's stated calibration uncertainty, from the active record's fits:
what the sweep's combined expanded uncertainty takes each calibration part at (reduction.combined_dof).

A channel's [uncertainty] gain_pct is its fit's: a force channel's the loads step's gain matrix
([loads.<system>] dof, 2 (n - 3)), a probe's its line ([probes.<probe>] dof, steps - 2); its
phase_deg and delay_us its [delay.<channel>] line's (dof, speeds - 2); the probes' sensitivity is
the reference's, a certificate (exact: infinite dof); the runout's u the scatter of the slow roll's
revolutions (revolutions - 1, as docs/calibration.md states them; every probe's and harmonic's
counted as one part, the conservative choice). A force channel's gain_pct holds the reference's share too, which
the record does not keep apart: it is taken at the fit's dof with the rest (the smaller dof: a
larger k). A record written before records held dof is read as `calibrate show` reads it: the
fit's dof from its loads or steps; a [delay] section of such a record, and the [uncertainty] of
rig.toml or of a record that measured no channel (its runout keeps its revolutions' dof), are
taken as exactly known (infinite dof), and :attr:`CalibrationDof.notes` says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from orbitrig.config import CalibrationRecord, ChannelDelay, LoadGains, ProbeGain

#: the note of a stated uncertainty that no record's fit gives a dof
TYPED_IN = (
    "calibration u taken as exactly known (infinite degrees of freedom): "
    "typed in (rig.toml's [calibration_uncertainty] or a record that measured no channel), no fit's dof"
)


@dataclass(frozen=True)
class CalibrationDof:
    """Per channel (fields.ChannelName) the degrees of freedom of its gain u and of its phase and
    delay u (one line); the runout's; inf where a part is taken as exactly known; ``notes``: where
    the record did not state them (sentences for the run's output)."""

    gain: dict[str, float] = field(default_factory=dict)
    lag: dict[str, float] = field(default_factory=dict)
    runout: float = math.inf
    notes: list[str] = field(default_factory=list)

    def gain_of(self, channel: str) -> float:
        return self.gain.get(channel, math.inf)

    def lag_of(self, channel: str) -> float:
        return self.lag.get(channel, math.inf)


def calibration_dof(record: CalibrationRecord | None) -> CalibrationDof:
    """The :class:`CalibrationDof` of the active ``record`` (None: rig.toml's stated uncertainty)."""
    if record is None:
        return CalibrationDof(notes=[TYPED_IN])
    if not (record.loads or record.probes or record.delay):  # its channels' u typed in; a runout measured
        return CalibrationDof(runout=_runout_dof(record), notes=[TYPED_IN])
    gain: dict[str, float] = {}
    lag: dict[str, float] = {}
    notes: list[str] = []
    sections: list[tuple[str, LoadGains | ProbeGain | ChannelDelay, list[str], dict[str, float]]]
    sections = [(f"loads.{lms}", v, [f"fx_{lms}", f"fy_{lms}"], gain) for lms, v in record.loads.items()]
    sections += [(f"probes.{p}", v, [p], gain) for p, v in record.probes.items()]
    sections += [(f"delay.{c}", v, [c], lag) for c, v in record.delay.items()]
    for name, v, channels, into in sections:
        dof = v.fit_dof
        for c in channels:
            into[c] = math.inf if dof is None else float(dof)
        if v.dof is None:
            notes.append(
                f"[{name}] written before records held dof: "
                + ("its u taken as exactly known" if dof is None else f"its u at its fit's {dof} dof")
            )
    return CalibrationDof(gain, lag, _runout_dof(record), notes)


def _runout_dof(record: CalibrationRecord) -> float:
    """The dof of ``record``'s runout u: its slow roll's revolutions - 1 (inf without them)."""
    runout = record.runout
    if runout is not None and runout.x_a.h1_u_um is not None and runout.revolutions > 1:
        return float(runout.revolutions - 1)
    return math.inf
