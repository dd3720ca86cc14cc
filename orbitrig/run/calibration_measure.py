"""What the calibration steps measure at the slow roll of a `CalibrationSession`
(orbitrig.run.calibration): static loads, runout, the phase reference, displacement steps.

`measure_loads` applies each known static load through the ``hands`` (the simulator at once;
on the rig the operator applies it and confirms) and reads the static part (dc) of both load
measuring systems' force channels. The input a step puts on the rig (loads, a displacement step,
the phase reference) is on the rig inside `CalibrationSession.applied`: taken off only once both
drives are confirmed at standstill. SI throughout.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Protocol

import numpy as np

from orbitrig.config import LMS, ChannelDelay
from orbitrig.config import PROBE_CHANNELS as PROBES
from orbitrig.load_systems import LoadSystem
from orbitrig.run.calibration import CalibrationSession, SlowRoll
from reduction.calibration import DelayFit, fit_delay
from reduction.fourier import phasor
from reduction.noise import phasor_uncertainty
from reduction.runout_slip import SlipFit, aligned, fit_slip, slipped_harmonics
from reduction.statistics import Interval, coverage_factor
from rigunits import HZ, MICROSECOND, UM, US, micrometres

#: a probe lagging the four probes' mean by more (deg, µs) is named by the delay step: five times
#: the data sheets' 0.05 deg and 10 µs (the initial record's); like probes behind like filters agree closer
PROBE_LAG_WARN = (0.25, 50.0)
#: what the operator does to take each step's input off the rig (said when the step ends, and by the
#: operator's hands asked for a zero load, step or reference)
REMOVE_LOADS = "remove every calibration load"
REMOVE_STEP = "remove the displacement step"
REMOVE_REFERENCE = "disconnect the phase reference and reconnect the sensors"
#: the largest slip (fraction) of the slow roll's spin against its orbit spindle the runout step
#: corrects: within it a revolution's own turn of the 2x, 4 pi s, costs its phasor under 0.07 %
#: ((2 pi s)^2 / 6) and the harmonics leak under 2 s into each other, averaged out over the
#: revolutions; beyond it the drives do not hold their speeds (1 rpm at the 100 rpm slow roll, six
#: times their 0.15 rpm resolution) and something is wrong with them
SLIP_LIMIT = 0.01


class LoadHands(Protocol):
    """Whoever applies a known static load (N) on the journal: the simulator, or the operator."""

    async def apply_load(self, fx: float, fy: float) -> None: ...


class ProbeHands(Protocol):
    """Whoever steps the journal by a known static displacement (m) under the probes (a micrometer)."""

    async def apply_displacement(self, dx: float, dy: float) -> None: ...


class ReferenceHands(Protocol):
    """Whoever connects the phase reference (a calibrator locked to the orbit spindle, amplitude
    ``force`` N on the force channels, ``probe`` m on the probes; 0, 0: disconnected)."""

    async def apply_reference(self, force: float, probe: float) -> None: ...


async def measure_loads(
    session: CalibrationSession, hands: LoadHands, loads: np.ndarray
) -> dict[LoadSystem, np.ndarray]:
    """Each load of `loads` (n, 2; N) applied in turn and read by both load measuring systems:
    {lms: (n, 2) static readings (N, through rig.toml's channel gains)}; the load removed after, both
    drives at standstill."""
    ch = session.rig.channel_index
    out: dict[LoadSystem, list[list[float]]] = {lms: [] for lms in LMS}
    async with session.applied(lambda: hands.apply_load(0.0, 0.0), REMOVE_LOADS, hands):
        for fx, fy in np.asarray(loads, dtype=float):
            await session.watched(partial(hands.apply_load, float(fx), float(fy)))
            await session.hold()
            blk = await session.average()
            for lms in LMS:
                out[lms].append([blk.dc[ch[f"fx_{lms}"]], blk.dc[ch[f"fy_{lms}"]]])
            session.note(
                f"load ({fx:+.1f}, {fy:+.1f}) N read: "
                + ", ".join(f"{lms} ({r[-1][0]:+.2f}, {r[-1][1]:+.2f}) N" for lms, r in out.items())
            )
    return {lms: np.array(v) for lms, v in out.items()}


def revolution_harmonics(counts: np.ndarray, gain: float, offset: float, theta: np.ndarray) -> np.ndarray:
    """(2, N) complex phasors at 1x and 2x (engineering units) of each of one probe's slow-roll
    revolutions ``counts`` (N, S) read at angles ``theta`` (S,), phase to each revolution's trigger."""
    q = np.asarray(counts, dtype=float) * gain + offset
    return np.stack([phasor(q, theta, harmonic=h, axis=-1) for h in (1, 2)])  # linear in q


def runout_of(
    counts: np.ndarray, gain: float, offset: float, theta: np.ndarray, slip: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """One probe's runout from its slow-roll revolutions, ``counts`` (N, S) read at angles ``theta``
    (S,): ((2,) complex phasors (engineering units) at 1x and 2x, the harmonics of the mean of the
    revolutions; (2,) their standard uncertainties from the revolutions' scatter,
    reduction.noise.phasor_uncertainty: inf for one revolution). With the spin's ``slip`` (fraction,
    reduction.runout_slip) each revolution's harmonics are fitted at the slipped spin harmonics and
    turned back by it before the mean (phase to the middle revolution's trigger)."""
    if slip == 0.0:
        per_rev = revolution_harmonics(counts, gain, offset, theta)
    else:
        q = np.asarray(counts, dtype=float) * gain + offset
        per_rev = aligned(slipped_harmonics(q[None], np.asarray(theta)[None], slip), slip)[0]
    return per_rev.mean(axis=1), phasor_uncertainty(per_rev, axis=1)


def slip_refused(fit: SlipFit, limit: float = SLIP_LIMIT) -> str:
    """Why a slow roll whose spin slipped by ``fit`` cannot give the runout ('' when it can): a
    slip beyond ``limit`` (fraction)."""
    if abs(fit.slip) <= limit:
        return ""
    return (
        f"the spin slipped {fit.slip * 100:+.3f} % (u {fit.slip_u * 100:.4f} %) against the orbit spindle during "
        f"the slow roll, beyond the {limit * 100:g} % the runout step corrects: the spin and orbit drives do "
        "not hold the same speed (their actual speeds, their speed scaling); no record written"
    )


async def measure_runout(session: CalibrationSession) -> tuple[dict[str, dict[str, object]], int, SlipFit]:
    """Runout of every probe track at 1x and 2x spin (phase to the trigger of the slow roll's middle
    revolution) from one block of the slow roll, each revolution turned back by the spin's slip
    fitted from the runout itself (reduction.runout_slip), with its standard uncertainty:
    ({probe: ProbeRunout's keys (µm)}, revolutions averaged, the slip: the step refuses a slip
    beyond SLIP_LIMIT, `slip_refused`, once both drives are stopped)."""
    blk = await session.average()
    ch, out = session.rig.channel_index, dict[str, dict[str, object]]()
    theta = np.asarray(blk.theta)
    per_rev = np.stack(
        [
            revolution_harmonics(blk.raw_counts[:, ch[p], :], blk.gains[ch[p]], blk.offsets[ch[p]], theta[ch[p]])
            for p in PROBES
        ]
    )
    slip = fit_slip(per_rev)
    for p in PROBES:
        c = ch[p]
        h, u = runout_of(blk.raw_counts[:, c, :], blk.gains[c], blk.offsets[c], theta[c], slip.slip)
        um, u_um = h / UM, [float(x / UM) if np.isfinite(x) else None for x in u]
        pairs = [[float(v.real), float(v.imag)] for v in um]
        out[p] = {"h1_um": pairs[0], "h2_um": pairs[1], "h1_u_um": u_um[0], "h2_u_um": u_um[1]}
    return out, blk.n_revolutions, slip


async def measure_probes(session: CalibrationSession, hands: ProbeHands, steps: np.ndarray) -> dict[str, np.ndarray]:
    """Each step of `steps` (n,; m) applied along x, then along y, and read by the probes of that
    axis: {probe: (n,) static readings (m, through rig.toml's channel gains)}; the step removed after,
    both drives at standstill."""
    ch = session.rig.channel_index
    out: dict[str, list] = {p: [] for p in PROBES}
    async with session.applied(lambda: hands.apply_displacement(0.0, 0.0), REMOVE_STEP, hands):
        for axis in ("x", "y"):
            for d in np.asarray(steps, dtype=float):
                dx, dy = (float(d), 0.0) if axis == "x" else (0.0, float(d))
                await session.watched(partial(hands.apply_displacement, dx, dy))
                await session.hold()
                blk = await session.average()
                for p in PROBES:
                    if p.startswith(axis):
                        out[p].append(blk.dc[ch[p]])
                session.note(
                    f"step {axis} {micrometres(d, '+.2f')} read: "
                    + ", ".join(f"{p} {micrometres(out[p][-1], '+.3f')}" for p in PROBES if p.startswith(axis))
                )
    return {p: np.array(v) for p, v in out.items()}


async def measure_delay(
    session: CalibrationSession, hands: ReferenceHands, rolls: list[SlowRoll], amplitudes: tuple[float, float]
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The reference read at each slow roll of `rolls` (its orbit frequency; a ratio off 1 keeps
    the probes' runout out of the average): (frequencies Hz (n,), {channel: (n,) lag (rad)
    behind the mean of the four probes}); the reference removed after, both drives at standstill."""
    ch = session.rig.channel_index
    freqs: list[float] = []
    lags: dict[str, list[float]] = {name: [] for name in ch}
    async with session.applied(lambda: hands.apply_reference(0.0, 0.0), REMOVE_REFERENCE, hands):
        await hands.apply_reference(*amplitudes)
        for roll in rolls:
            await session.roll(roll)
            await session.hold()
            blk = await session.average()
            ph = np.asarray(blk.phasors)
            ref = np.mean([ph[ch[p]] / abs(ph[ch[p]]) for p in PROBES])
            freqs.append(roll.orbit / HZ)
            for name, i in ch.items():
                lags[name].append(-np.angle(ph[i] / ref))
            session.note(
                f"reference at {freqs[-1]:.2f} Hz: force channels lag the probes by "
                + ", ".join(f"{n} {np.degrees(lags[n][-1]):.3f} deg" for n in ch if n.startswith("f"))
            )
    return np.array(freqs), {name: np.array(v) for name, v in lags.items()}


def fitted_delay(freqs: np.ndarray, lag: np.ndarray) -> tuple[DelayFit, ChannelDelay]:
    """A channel's lag (rad) at `freqs` (Hz) fitted (reduction.calibration.fit_delay) and as a record
    holds it: the lag apart from its sign, the delay, their standard uncertainties, the line's
    degrees of freedom, the coverage factor (Student's t at them: the residuals alone) and the
    expanded uncertainties."""
    fit = fit_delay(freqs, lag)
    k = coverage_factor(Interval.STUDENT_T, fit.dof)
    phase_u, delay_u = float(np.degrees(fit.phase_u)), fit.delay_u / US
    d = ChannelDelay(
        phase_deg=float(np.degrees(fit.lag)),
        delay_us=fit.delay / US,
        phase_u_deg=phase_u,
        delay_u_us=delay_u,
        dof=fit.dof,
        k=k,
        phase_U_deg=k * phase_u,
        delay_U_us=k * delay_u,
    )
    return fit, d


def probe_delays(
    freqs: np.ndarray, lags: dict[str, np.ndarray], note: Callable[[str], None]
) -> dict[str, ChannelDelay]:
    """Each probe's lag behind the mean of the four (`measure_delay`'s), fitted as phase + 2 pi f
    delay with its standard uncertainties; a warning line to `note` per probe reading the reference
    inverted or lagging beyond PROBE_LAG_WARN. Only these differences are measurable: a lag common
    to the four probes is one with the forces' (their [delay] is the lag behind the probes' mean).
    ReductionError when a fit cannot be made (reduction.calibration.fit_delay)."""
    out: dict[str, ChannelDelay] = {}
    for p in PROBES:
        fit, d = fitted_delay(freqs, lags[p])
        out[p] = d
        if fit.polarity < 0 or abs(d.phase_deg) > PROBE_LAG_WARN[0] or abs(d.delay_us) > PROBE_LAG_WARN[1]:
            note(
                f"warning: probe {p} lags the four probes' mean by {d.phase_deg:+.3f} deg "
                f"{'-' if d.delay_us < 0 else '+'} {abs(d.delay_us):.1f} {MICROSECOND}"
                + (" and reads the reference inverted" if fit.polarity < 0 else "")
                + f" (plausible: within {PROBE_LAG_WARN[0]} deg and {PROBE_LAG_WARN[1]:g} {MICROSECOND}): "
                "is its driver, filter or cable unlike the others'? The sweep takes the recorded lag out "
                "of its phasors"
            )
    return out
