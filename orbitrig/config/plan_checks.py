"""A matrix against the rig it is to run on: the plan's checks, before anything starts.

:func:`check_matrix_against_rig` raises one ConfigError naming every problem, each with the
matrix file, the line and the key (orbitrig.run.plan.make_plan calls it, so `sweep`, its dry
run and the service's `start` refuse alike):

- [drives]: every spin and the orbit speed of the highest ratio, the ratio band;
- [interlocks]: every operating point's supply pressure p_s = p_r / beta (recess pressure
  over pressure ratio: what the operator sets by hand, SetManual) inside the supply band the
  interlock watches (orbitrig.run.interlocks suspends the run outside it, with the drives
  already turning, and fails it below the minimum after supply_lost_timeout_s). The only interlock band a matrix sets: the others watch the drives and
  the CAN node;
- Omega/omega = 1: an orbit ratio within SYNCHRONOUS_REFUSAL of 1 (reduction.frequency_list,
  which says why);
- [sequential]: the candidates and the reference list against the drives
  (orbitrig.config.sequential), and the initial list ([orbit]) and the reference list
  (match_ratios, in the [orbit] directions) must identify the model the point is designed for
  (reduction.identifiability.check_plan, as the dry run's prediction).

:func:`plan_warnings` lists what the plan may run with but the operator should be told, once
per matrix: spin speeds below SLOW_SPIN_RPM (Hz written for rpm?), ratios within RUNOUT_KEEP_AWAY
of 1; :func:`runout_speed_warning` the spin speeds not
above the slow roll the active record's runout was measured at. SI inside; rpm, Hz and MPa in
the messages.
"""

from __future__ import annotations

import numpy as np

from orbitrig.config.fields import MPA
from orbitrig.config.matrix import MatrixConfig
from orbitrig.config.messages import key_line
from orbitrig.config.record_age import age_warning
from orbitrig.config.record_setup import PROBE_CHANNELS
from orbitrig.config.rig import RigConfig
from orbitrig.config.sequential import above_band, below_band, candidate_problems, orbit_too_fast
from orbitrig.errors import ConfigError
from reduction.errors import IdentifiabilityError
from reduction.frequency_list import RUNOUT_KEEP_AWAY, SYNCHRONOUS_REFUSAL, near_one, runout_stays
from reduction.identifiability import check_plan
from reduction.models import CONSTANT
from reduction.runout import MIN_REVOLUTIONS
from reduction.whirl import Directions
from rigunits import MINUTE

#: relative slack of the supply band's edges: a value on an edge (8 MPa from 5.6 / 0.7) is inside
BAND_SLACK = 1e-9
#: the freq-dep a sequential point identifies its model with (orbitrig.run.sequential_point)
SEQUENTIAL_FREQ_DEP = CONSTANT.text


def check_matrix_against_rig(matrix: MatrixConfig, rig: RigConfig) -> None:
    """Problems a matrix has only on this rig (module doc), all in one ConfigError."""
    problems = _drive_problems(matrix, rig) + _supply_problems(matrix, rig) + _synchronous_problems(matrix)
    problems += _sequential_problems(matrix, rig) + _runout_problems(matrix, rig)
    if problems:
        raise ConfigError(matrix.file, problems)


def _runout_problems(matrix: MatrixConfig, rig: RigConfig) -> list[str]:
    """The blocks too short for the runout fit (reduction.runout.MIN_REVOLUTIONS) while the active
    record's runout is subtracted: they would keep the runout whole. One line per key giving them."""
    if rig.record is None or rig.record.runout is None or not rig.subtract_runout:
        return []
    short: dict[tuple, list[tuple[float, int]]] = {}
    for k, r in enumerate(matrix.orbit.ratio_list):
        if (n := _fewest_revolutions(matrix, k, rig.averaging.revolutions)) < MIN_REVOLUTIONS:
            short.setdefault(_revolutions_key(matrix, k), []).append((r, n))
    return [
        f"{_at(matrix.text, key) if key else ''}key '{'.'.join(key) if key else 'averaging.revolutions'}'"
        f"{'' if key else ' of the rig configuration'}: {min(n for _, n in rn)} revolutions at orbit "
        f"ratio{'s' if len(rn) > 1 else ''} {_ratios([r for r, _ in rn])}: the active calibration record's "
        f"runout is taken out of a block by a fit over its revolutions, which needs at least "
        f"{MIN_REVOLUTIONS}; give at least {MIN_REVOLUTIONS}, or set subtract_runout = false in the rig "
        "configuration"
        for key, rn in short.items()
    ]


def _revolutions_key(matrix: MatrixConfig, k: int) -> tuple:
    """The matrix key giving the fewest revolutions at ratio ``k`` (() : the rig's [averaging])."""
    if matrix.averaging is not None:
        return ("averaging", "min_revolutions")
    if matrix.orbit.revolutions_at(k):
        return ("orbit", "revolutions")
    return ("revolutions",) if matrix.revolutions else ()


def plan_warnings(matrix: MatrixConfig, default_revolutions: int) -> list[str]:
    """What the plan of ``matrix`` runs with but should be said, one line each (naming the line
    and key): spin speeds below SLOW_SPIN_RPM (rpm meant?), the orbit ratios within RUNOUT_KEEP_AWAY of Omega/omega = 1, all in one line, and
    of those the ratios where the runout stays in a block's average (fewest revolutions a block
    there may average; ``default_revolutions``: rig.toml's [averaging] count)."""
    near, slow = _near_one(matrix, RUNOUT_KEEP_AWAY), _slow_spin(matrix)
    if near is None:
        return slow
    return slow + [
        f"{near}: the spindle's runout (1x spin) "
        "turns only slowly through a block's revolutions there, so averaging and the runout fit take it "
        "out only in part and the coefficients at these ratios (C most) may be biased; `orbitrig design` "
        f"keeps {RUNOUT_KEEP_AWAY:g} away" + _runout_stays(matrix, default_revolutions)
    ]


#: rpm: a matrix's spin below one turn a second is said (Hz written where rpm was meant?)
SLOW_SPIN_RPM = 60.0


def _slow_spin(matrix: MatrixConfig) -> list[str]:
    """The matrix's spin speeds below SLOW_SPIN_RPM in one line (naming the line and key), as
    a frequency in Hz written where the file means rpm would give them; [] when there is none."""
    low = sorted(r for r in set(matrix.operating.spin_rpm) if r < SLOW_SPIN_RPM)
    if not low:
        return []
    many = len(low) > 1
    return [
        f"{_at(matrix.text, ('operating', 'spin_rpm'))}key 'operating.spin_rpm': spin "
        f"{', '.join(f'{r:g}' for r in low)} rpm {'are' if many else 'is'} below {SLOW_SPIN_RPM:g} rpm (one turn "
        f"a second): Hz written where rpm is meant? {low[0]:g} Hz is {low[0] * 60:g} rpm; every speed in a matrix "
        "is in rpm, and so slow an orbit makes each block last minutes (`orbitrig sweep --dry-run` says how long)"
    ]


def _runout_stays(matrix: MatrixConfig, default_revolutions: int) -> str:
    """'; at ratio R (N revolutions) the runout turns less than once ...' for the ratios whose
    fewest revolutions leave the runout whole in the average (reduction.frequency_list.runout_stays)."""
    ratios = matrix.orbit.ratio_list
    fewest = [_fewest_revolutions(matrix, k, default_revolutions) for k in range(len(ratios))]
    stays = [f"{r:g} ({n} revolutions)" for r, n, s in zip(ratios, fewest, runout_stays(ratios, fewest)) if s]
    if not stays:
        return ""
    return (
        f"; at {', '.join(stays)} it turns less than once against the orbit over the block, so it stays in "
        "the averaged phasors and the stated uncertainties u understate their error (on the simulator 2.6 "
        "times at 0.99 with 50 revolutions): more revolutions there, or ratios farther from 1"
    )


def _fewest_revolutions(matrix: MatrixConfig, k: int, default_revolutions: int) -> int:
    """The fewest revolutions a block at ``orbit.ratio_list[k]`` may average: an adaptive
    point's minimum, else the ratio's, the matrix's or the rig's fixed count."""
    if matrix.averaging is not None:
        return matrix.averaging.min_revolutions
    return matrix.fixed_revolutions(k, default_revolutions)


def _near_one(matrix: MatrixConfig, within: float) -> str | None:
    """ "line N: key 'orbit.KEY': orbit ratios A, B are within WITHIN of Omega/omega = 1" for the
    matrix's ratios closer to 1 than ``within`` (reduction.frequency_list.near_one); None when there is none."""
    ratios = matrix.orbit.ratio_list
    near = [r for r, close in zip(ratios, near_one(ratios, within)) if close]
    if not near:
        return None
    key, many = _ratio_key(matrix), len(near) > 1
    return (
        f"{_at(matrix.text, ('orbit', key))}key 'orbit.{key}': orbit ratio{'s' if many else ''} "
        f"{_ratios(near)} {'are' if many else 'is'} within {within:g} of Omega/omega = 1"
    )


def warning_lines(matrix: MatrixConfig, default_revolutions: int, rig: RigConfig | None = None) -> list[str]:
    """The plan's warnings as the dry run prints and run.log records them: 'warning: FILE: ...';
    with ``rig`` also the spin speeds its active record's runout does not suit (runout_speed_warning),
    the record's measurements older than its calibration_valid_days (record_age.age_warning) and a
    runout subtracted without its recorded uncertainty (runout_uncertainty_warning)."""
    lines = plan_warnings(matrix, default_revolutions)
    slow = runout_speed_warning(matrix, rig) if rig is not None else None
    rig_lines = [] if rig is None else [w for w in (age_warning(rig), runout_uncertainty_warning(rig)) if w]
    return [f"warning: {matrix.file}: {line}" for line in lines + ([slow] if slow else [])] + [
        f"warning: {rig.file}: {line}" for line in rig_lines if rig is not None
    ]


def runout_uncertainty_warning(rig: RigConfig) -> str | None:
    """The active record's runout, subtracted, without its standard uncertainties (``h1_u_um``,
    ``h2_u_um``: a record written before the runout step recorded them): the coefficients' U
    holds no term for it (docs/calibration.md, Limits); None otherwise."""
    rec = rig.record
    if rec is None or rec.runout is None or not rig.subtract_runout:
        return None
    if rec.runout.uncertainties(PROBE_CHANNELS) is not None:
        return None
    why, again = "written before the runout step recorded them", ""
    if rec.runout.revolutions < 2:
        why, again = "a slow roll of one revolution: no scatter to take it from", " over more than one revolution"
    return (
        f"the active calibration record {rig.calibration_record}'s runout has no recorded uncertainty "
        f"([runout.<probe>] h1_u_um, h2_u_um: {why}): the runout is taken out, but the coefficients' U "
        f"holds no term for its error; `orbitrig calibrate runout` again{again} to have it counted"
    )


def runout_speed_warning(matrix: MatrixConfig, rig: RigConfig) -> str | None:
    """The matrix's spin speeds not above the slow roll the active record's runout was measured at
    (its ``[runout] spin_rpm``), while that runout is subtracted; None when every spin is faster.
    A slow-roll runout is the probe track's 1x and 2x at a spin where the spindle's own synchronous
    response is negligible: measured at a spin as fast as the point's or faster it is no slow roll
    for that point, and its 1x response would be taken out as runout."""
    rec = rig.record
    if rec is None or rec.runout is None or not rig.subtract_runout:
        return None
    slow = rec.runout.spin_rpm
    low = sorted(r for r in set(matrix.operating.spin_rpm) if r <= slow)
    if not low:
        return None
    many = len(low) > 1
    return (
        f"{_at(matrix.text, ('operating', 'spin_rpm'))}key 'operating.spin_rpm': spin "
        f"{', '.join(f'{r:g}' for r in low)} rpm {'are' if many else 'is'} not above the slow roll of the "
        f"active calibration record {rig.calibration_record}'s runout ([runout] spin_rpm = {slow:g}): the "
        f"runout taken out at {'these points' if many else 'this point'} was measured at a spin as fast or "
        f"faster, so it holds the spindle's own 1x and 2x response at {slow:g} rpm besides the runout; "
        f"measure the runout below {min(low):g} rpm (`orbitrig calibrate runout --spin-rpm`), or set "
        "subtract_runout = false in the rig configuration"
    )


def _at(text: str, loc: tuple) -> str:
    """'line N: ' of the key at ``loc`` (its table's when the key is not written), else ''."""
    line = key_line(text, loc)
    return f"line {line}: " if line else ""


def _ratios(values: list[float]) -> str:
    return ", ".join(f"{r:g}" for r in values)


def _ratio_key(matrix: MatrixConfig) -> str:
    """The [orbit] key the matrix gives its ratios with: 'design', 'ratios' or 'ratio_start'."""
    o = matrix.orbit
    return "design" if o.design is not None else "ratios" if o.ratios is not None else "ratio_start"


def _drive_problems(matrix: MatrixConfig, rig: RigConfig) -> list[str]:
    """Spin and orbit speeds and the ratio band against [drives]."""
    problems = []
    d, ratios = rig.drives, matrix.orbit.ratio_list
    at_spin, at_ratio = _at(matrix.text, ("operating", "spin_rpm")), _at(matrix.text, ("orbit", _ratio_key(matrix)))
    for rpm in matrix.operating.spin_rpm:
        if rpm > d.max_spin_rpm:
            problems.append(
                f"{at_spin}key 'operating.spin_rpm': {rpm:g} rpm exceeds the rig's drives.max_spin_rpm = {d.max_spin_rpm:g}"
            )
        if (words := orbit_too_fast(d, max(ratios), rpm)) is not None:
            problems.append(f"{at_ratio}key 'orbit': {words}")
    for words in (below_band(d, min(ratios)), above_band(d, max(ratios))):
        if words is not None:
            problems.append(f"{at_ratio}key 'orbit': {words}")
    return problems


def _supply_problems(matrix: MatrixConfig, rig: RigConfig) -> list[str]:
    """Every (recess pressure, pressure ratio) whose supply pressure p_r / beta is outside the
    [interlocks] supply band (none when the interlock does not watch the supply pressure)."""
    lock = rig.interlocks
    if not lock.check_supply_pressure:
        return []
    lo, hi = lock.supply_pressure_min_mpa * MPA, lock.supply_pressure_max_mpa * MPA
    at = _at(matrix.text, ("operating", "recess_pressure_mpa"))
    beta_line = key_line(matrix.text, ("operating", "pressure_ratio"))
    beta_at = f" (line {beta_line})" if beta_line else ""
    problems = []
    for recess_mpa in matrix.operating.recess_pressure_mpa:
        for beta in matrix.operating.pressure_ratio:
            supply = recess_mpa * MPA / beta  # Pa
            if not lo * (1 - BAND_SLACK) <= supply <= hi * (1 + BAND_SLACK):  # p_r / beta rounds
                problems.append(
                    f"{at}key 'operating.recess_pressure_mpa': {recess_mpa:g} MPa at 'operating.pressure_ratio' "
                    f"{beta:g}{beta_at} needs a supply pressure of {supply / MPA:.4g} MPa (recess / pressure "
                    f"ratio), outside the rig's interlocks band supply_pressure_min_mpa..supply_pressure_max_mpa "
                    f"= {lo / MPA:g}..{hi / MPA:g} MPa: the interlock would suspend the run at that point"
                )
    return problems


def _synchronous_problems(matrix: MatrixConfig) -> list[str]:
    """Orbit ratios within SYNCHRONOUS_REFUSAL of Omega/omega = 1 (static and initial lists)."""
    near = _near_one(matrix, SYNCHRONOUS_REFUSAL)
    if near is None:
        return []
    return [
        f"{near}, where the spindle's runout (1x spin) has the orbit's frequency and the same phase in every "
        "revolution: "
        "averaging cannot separate the two and the coefficients are biased; keep every ratio at least "
        f"{SYNCHRONOUS_REFUSAL:g} from 1 (`orbitrig design` keeps {RUNOUT_KEEP_AWAY:g})"
    ]


def _sequential_problems(matrix: MatrixConfig, rig: RigConfig) -> list[str]:
    """A sequential matrix's candidates and reference list against the drive limits, each with
    its key's own line, and its initial list's identifiability."""
    keyed = [f"{_at(matrix.text, loc)}{p}" for loc, p in candidate_problems(matrix, rig)]
    return keyed + _initial_list_problems(matrix) + _match_list_problems(matrix)


def orbit_hz(ratios, spin_rpm: float) -> np.ndarray:
    """The orbit frequencies (Hz) of a list's `ratios` (of the spin) at `spin_rpm`, as the checks of a
    plan before a run (reduction.identifiability.check_plan) take them."""
    return np.asarray(ratios, dtype=float) * spin_rpm / MINUTE


def _match_list_problems(matrix: MatrixConfig) -> list[str]:
    """The reference list of a sequential point (match_ratios, in the matrix's directions)
    must identify the point's model at every spin: its standard errors are the target
    (reduction.sequential.reference_errors refuses it at run time, after the initial list)."""
    s, model = matrix.sequential, matrix.sequential_model
    if s is None or model is None or not s.match_ratios:
        return []
    ways = Directions.of(matrix.orbit.directions)
    for rpm in sorted(set(matrix.operating.spin_rpm)):
        try:
            check_plan(model, SEQUENTIAL_FREQ_DEP, orbit_hz(s.match_ratios, rpm), ways)
        except IdentifiabilityError as err:
            cause = str(err).splitlines()[0].rstrip(".")
            return [
                f"{_at(matrix.text, ('sequential', 'match_ratios'))}key 'sequential.match_ratios': the reference "
                f"list (ratios {_ratios(s.match_ratios)}, directions {', '.join(matrix.orbit.directions)}) cannot "
                f"identify {model} at {rpm:g} rpm, so no standard error to match follows from it: {cause}; "
                "give more ratios or both directions, or 'sequential.target_pct'"
            ]
    return []


def _initial_list_problems(matrix: MatrixConfig) -> list[str]:
    """The [orbit] list of a sequential point must identify the point's model at every spin:
    the engine identifies it on these blocks before it can choose the next one."""
    model = matrix.sequential_model
    if model is None:
        return []
    o = matrix.orbit
    for rpm in sorted(set(matrix.operating.spin_rpm)):
        try:
            check_plan(model, SEQUENTIAL_FREQ_DEP, orbit_hz(o.ratio_list, rpm), o.whirl_list)
        except IdentifiabilityError as err:
            return [_unidentifiable(matrix, model, rpm, err)]
    return []


def _unidentifiable(matrix: MatrixConfig, model: str, rpm: float, err: IdentifiabilityError) -> str:
    """The refusal of a sequential initial list that cannot identify ``model`` at ``rpm``."""
    o, key = matrix.orbit, _ratio_key(matrix)
    given = matrix.sequential is not None and matrix.sequential.model is not None
    where = key_line(matrix.text, ("sequential", "model") if given else ("models", 0, "model"))
    named = ("'sequential.model'" if given else "the first [[models]]") + (f", line {where}" if where else "")
    cause = str(err).splitlines()[0].rstrip(".")
    return (
        f"{_at(matrix.text, ('orbit', key))}key 'orbit.{key}': the initial list of a sequential point ("
        f"{_list_text(o)}) cannot identify {model} ({named}) at "
        f"{rpm:g} rpm, and the engine identifies it on these blocks before it chooses the next one: {cause}; "
        "give more ratios or both directions in [orbit], or design for another model"
    )


def _list_text(o) -> str:
    """'ratios A, B, directions forward, backward', or with a 'whirl' list 'ratios A forward, B both'."""
    if not o.per_direction:
        return f"ratios {_ratios(o.ratio_list)}, directions {', '.join(o.directions)}"
    return "ratios " + ", ".join(f"{r:g} {w.value}" for r, w in zip(o.ratio_list, o.whirl_list))
