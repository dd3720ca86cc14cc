"""The rig's units at the edges and its one timestamp format, in a module of its own.

SI inside (rad/s, Pa, s); rpm, Hz, MPa and clock text only where a person or a file
meets the code. Every package but ``sim`` (which re-derives its scales so that a
shared mistake cannot cancel out in the tests) may import this module; it imports
only the standard library (and numpy inside ``without_noise``, for arrays).

Unit strings: every unit stored or exported (HDF5 ``units``, ``field_units``, CSV headers,
DataFrame ``attrs``, MAT / TDMS properties) is a string pint parses, written one way:
``"1"`` for a dimensionless number (also a flag, a status word, a fault code, a fraction),
``""`` for text, ``"N s/m"`` (not ``"N*s/m"``) for damping.

Timestamps: ISO 8601 in UTC with milliseconds and a ``Z``, e.g.
``2026-11-27T01:30:05.123Z`` (files, logs, MQTT payloads); the compact form of
the same instant, ``20261127T013005.123Z``, names runs and folders; a calibration
record's name starts with it to the second, ``2026-11-27T013005Z``.
"""

from __future__ import annotations

import datetime as _dt
import math
from typing import TYPE_CHECKING, overload

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

RPM = 2.0 * math.pi / 60.0  # rad/s per rpm
HZ = 2.0 * math.pi  # rad/s per Hz
#: the float noise a speed at the edges drops, in units in the last place: ratio x (rpm x 2 pi / 60)
#: over 2 pi rounds a few times; 4 ulps reach the decimal meant for every ratio 0.01 .. 3 (step
#: 0.01) at 100 .. 6000 rpm (step 50)
NOISE_ULPS = 4
#: the most significant digits of a value the noise is taken off (a matrix's ratios keep 12 decimals)
NOISE_DIGITS = 12
MPA = 1.0e6  # Pa per MPa
UM = 1.0e-6  # m per micrometre
US = 1.0e-6  # s per microsecond (a channel delay, the A/D clock)
#: the micrometre as a person reads it (the operator's prompts, the dashboard, the figures): the
#: micro sign U+00B5, which pint parses too, never an ASCII "um"
MICROMETRE = "\u00b5m"
#: the microsecond likewise (a force channel's time delay), never an ASCII "us"
MICROSECOND = "\u00b5s"
MINUTE = 60.0  # s
HOUR = 3600.0  # s
DAY = 86400.0  # s

#: the unit of a dimensionless number (a ratio, a count of things, a flag, a status word, a code)
ONE = "1"
#: the unit of text (none)
TEXT = ""
STIFFNESS, DAMPING, MASS = "N/m", "N s/m", "kg"
#: SI unit of each matrix of a coefficient key (K, C, D)
COEFFICIENT_UNITS = {"K": STIFFNESS, "C": DAMPING, "D": MASS}


#: the unit a person reads each matrix in (tables, figures) and its scale: SI value * scale
DISPLAY_UNITS = {"K": ("MN/m", 1e-6), "C": ("kN s/m", 1e-3), "D": ("kg", 1.0)}


def display_unit(key: str) -> tuple[str, float]:
    """Display unit and scale of coefficient `key`: 'Kxx' -> ('MN/m', 1e-6); the term of order r
    ('Kxx_r') multiplies Omega^r, so its unit carries (rad/s)^-r: ('MN/m (rad/s)^-r', 1e-6)."""
    unit, scale = DISPLAY_UNITS[key[0]]
    return _per_order(unit, key), scale


def coefficient_unit(key: str) -> str:
    """SI unit of coefficient `key`: 'Kxx' -> 'N/m'; 'Cxy_2' (multiplies Omega^2) -> 'N s/m (rad/s)^-2'."""
    return _per_order(COEFFICIENT_UNITS[key[0]], key)


def _per_order(unit: str, key: str) -> str:
    """`unit` of the constant term; with (rad/s)^-r for coefficient `key`'s term of order r ('Kxx_r')."""
    _, _, order = key.partition("_")
    return unit if not order else f"{unit} (rad/s)^-{order}"


@overload
def without_noise(value: float) -> float: ...
@overload
def without_noise(value: NDArray[np.float64]) -> NDArray[np.float64]: ...
def without_noise(value: float | NDArray[np.float64]) -> float | NDArray[np.float64]:
    """`value` (a number or an array) as the shortest decimal of at most ``NOISE_DIGITS``
    significant digits within ``NOISE_ULPS`` of it (4.999999999999999 -> 5.0,
    19.999999999999996 -> 20.0); a value with no such decimal (10/3, a measured speed) is kept.
    A value moves by at most ``NOISE_ULPS`` ulps, so a file written with it reads back to 1e-15."""
    import numpy as np

    v = np.atleast_1d(np.asarray(value, dtype=np.float64)).ravel()
    out = v.copy()
    at = np.flatnonzero(np.isfinite(v) & (v != 0))
    tol = NOISE_ULPS * np.spacing(np.abs(v[at]))
    tens = np.floor(np.log10(np.abs(v[at]))).astype(np.int64)  # v = m 10^tens, 1 <= |m| < 10
    # the nearest decimal of d digits is no farther than that of d - 1: from the most digits
    # down, each value takes the shortest that stays within tol
    for digits in range(NOISE_DIGITS, 0, -1):
        c = _significant(v[at], digits - 1 - tens)
        near = np.abs(c - v[at]) <= tol
        out[at[near]] = c[near]
        at, tol, tens = at[near], tol[near], tens[near]
    return float(out[0]) if np.ndim(value) == 0 else out.reshape(np.shape(value))


def _significant(v: NDArray[np.float64], decimals: NDArray[np.int64]) -> NDArray[np.float64]:
    """`v` rounded to `decimals` places (per value; < 0: to tens, hundreds ...): an integer over
    (or times) a power of ten, exact up to 1e22, so each is the double nearest its decimal."""
    import numpy as np

    scale = np.power(10.0, np.minimum(np.abs(decimals), 308))
    with np.errstate(over="ignore", invalid="ignore"):
        rounded: NDArray[np.float64] = np.where(decimals >= 0, np.rint(v * scale) / scale, np.rint(v / scale) * scale)
    return rounded


@overload
def in_hz(omega: float) -> float: ...
@overload
def in_hz(omega: NDArray[np.float64]) -> NDArray[np.float64]: ...
def in_hz(omega: float | NDArray[np.float64]) -> float | NDArray[np.float64]:
    """The frequency (Hz) of angular speed `omega` (rad/s; a number or an array) without float
    noise (``without_noise``): a planned orbit of ratio 0.3 at 1000 rpm is 0.3 x 1000 x 2 pi / 60
    rad/s, and its frequency reads 5.0 Hz, not the 4.999999999999999 of that product over 2 pi."""
    return without_noise(omega / HZ)


def in_rpm(omega: float) -> float:
    """Angular speed `omega` (rad/s) in rpm without float noise (``without_noise``): a matrix's
    20.5 rpm reads 20.5, not the 20.499999999999996 of 20.5 x 2 pi / 60 rad/s divided back."""
    return without_noise(omega / RPM)


def rpm_text(omega: float, signed: bool = False) -> str:
    """A set speed `omega` (rad/s) as a person reads it, the shortest decimal of ``in_rpm``:
    '1000 rpm', `signed` (an orbit's whirl) '+569 rpm', '-977.778 rpm'; 0 is '+0 rpm', never '-0'."""
    return f"{in_rpm(omega) + 0.0:{'+' if signed else ''}g} rpm"


def micrometres(length: float, spec: str = ".2f") -> str:
    """A length (m: an orbit radius, a displacement) as a person reads it: '60.00 µm'."""
    return f"{length / UM:{spec}} {MICROMETRE}"


def format_duration(seconds: float, hours: bool = False) -> str:
    """h:mm:ss, or m:ss under an hour (rounded to the second); `hours`: h:mm:ss always, as a
    column of times that line up (0:03:22 above 1:02:03)."""
    whole = int(round(seconds))
    h, rem = divmod(whole, int(HOUR))
    m, s = divmod(rem, int(MINUTE))
    return f"{h}:{m:02d}:{s:02d}" if h or hours else f"{m}:{s:02d}"


def _utc(when: _dt.datetime | float | None) -> _dt.datetime:
    if when is None:
        return _dt.datetime.now(_dt.timezone.utc)
    if isinstance(when, (int, float)):
        return _dt.datetime.fromtimestamp(float(when), _dt.timezone.utc)
    return when.astimezone(_dt.timezone.utc)  # a naive datetime is taken as local time


def utc_iso(when: _dt.datetime | float | None = None) -> str:
    """The timestamp text of a datetime, a POSIX time (s) or now."""
    return _utc(when).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def now_iso() -> str:
    """Now as timestamp text."""
    return utc_iso()


def parse_utc(text: str) -> _dt.datetime | None:
    """The instant of timestamp text (its zone stated: 'Z' or an offset), None if it is none."""
    try:
        then = _dt.datetime.fromisoformat(text.replace("Z", "+00:00"))
    except (AttributeError, ValueError):
        return None
    return None if then.tzinfo is None else then


def now_after(previous: str) -> str:
    """Now as timestamp text, or the millisecond after timestamp text ``previous`` when now is not
    later (two changes in one millisecond, a clock set back): each of a series later than the last."""
    now, last = _dt.datetime.now(_dt.timezone.utc), parse_utc(previous)
    if last is None or utc_iso(now) > utc_iso(last):
        return utc_iso(now)
    return utc_iso(last + _dt.timedelta(milliseconds=1))


def seconds_since(text: str) -> float | None:
    """Seconds from the instant of timestamp ``text`` to now (None: not a timestamp)."""
    then = parse_utc(text)
    return None if then is None else (_dt.datetime.now(_dt.timezone.utc) - then).total_seconds()


def utc_stamp(when: _dt.datetime | float | None = None) -> str:
    """The compact form (no separators), for run ids and folder names."""
    t = _utc(when)
    return f"{t:%Y%m%dT%H%M%S}.{t.microsecond // 1000:03d}Z"


#: a calibration record name's leading date (record_stamp), to the second
_RECORD_STAMP = "%Y-%m-%dT%H%M%SZ"


def record_stamp(when: _dt.datetime | float | None = None) -> str:
    """The form that starts a calibration record's name: to the second, the date readable
    (``2026-11-27T013005Z``); the names sort as the records were made."""
    return f"{_utc(when):{_RECORD_STAMP}}"


def record_stamp_date(name: str) -> _dt.datetime | None:
    """The UTC instant a name starting with `record_stamp` gives (to the second), None for another name."""
    try:
        return _dt.datetime.strptime(name[: len(record_stamp(0))], _RECORD_STAMP).replace(tzinfo=_dt.timezone.utc)
    except ValueError:
        return None
