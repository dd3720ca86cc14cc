"""Impedance models and their frequency dependence -> named regression coefficients.

Z_ij(Omega) = sum_r Omega^r (K_ij^(r) + i Omega C_ij^(r) - Omega^2 D_ij^(r)), Omega in rad/s,
with the orders r of each matrix set by the frequency dependence (paper Eq. 15 and 16):

- ``none``: r = 0 only;
- ``power:M`` / ``power:m,n,p``: K orders {0, m}, C orders {0, n}, D orders {0, p} (Eq. 15);
- ``power:auto``: ``power:M`` with the best integer M in 1..4 (chosen by ``identify``);
- ``poly:R``: orders 0..R for every matrix (Eq. 16 truncated at Omega^R).

Inertia absorbs the colliding stiffness orders: Omega^r K^(r) and -Omega^2 Omega^(r-2) D^(r-2)
have the same regressor for every orbit, so in a model with D a K order r is not fitted when D
has order r - 2 (D carries that term); kc7/kc8 keep every K order. ``ModelSpec.absorbed``
lists the K orders dropped, ``ModelSpec.notes`` says so in words.

Coefficient names (the spec's keys): the constant term is ``Kxx``, the term multiplying
Omega^r is ``Kxx_r``. A constrained (symmetric) pair is ONE free coefficient named after its
upper entry (``Cxy`` in kc7 stands for Cxy = Cyx); the output repeats it under both keys.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import dataclass
from enum import Enum
from functools import cached_property
from typing import TypeVar

from reduction.errors import ReductionError

T = TypeVar("T")

ENTRIES = ("xx", "xy", "yx", "yy")
_INDEX = {"x": 0, "y": 1}

# model -> {matrix: symmetric?}; a matrix not listed is absent
MODELS: dict[str, dict[str, bool]] = {
    "kc7": {"K": False, "C": True},
    "kc8": {"K": False, "C": False},
    "kcd11": {"K": False, "C": False, "D": True},
    "kcd12": {"K": False, "C": False, "D": False},
}
AUTO_EXPONENTS = (1, 2, 3, 4)
MAX_ORDER = 8


class FreqDepKind(Enum):
    """The kind of a frequency dependence; the value is the word its spec starts with."""

    NONE = "none"
    POWER = "power"
    POLY = "poly"


@dataclass(frozen=True)
class FreqDep:
    """Parsed ``--freq-dep``: orders per matrix ({"K": (0, m), ...}); ``auto`` for power:auto.
    ``text`` is the canonical spec, the form stored and shown."""

    text: str
    orders: dict[str, tuple[int, ...]] | None  # None for power:auto
    kind: FreqDepKind

    @property
    def auto(self) -> bool:
        return self.orders is None

    @property
    def constant(self) -> bool:
        """No frequency dependence: every matrix has order 0 only (``none``)."""
        return self.kind is FreqDepKind.NONE

    def fixed_orders(self) -> dict[str, tuple[int, ...]]:
        """The orders per matrix; ReductionError for power:auto (no fixed coefficient list)."""
        if self.orders is None:
            raise ReductionError("power:auto has no fixed coefficient list: resolve the exponent first")
        return self.orders


def _int(text: str, spec: str) -> int:
    if not re.fullmatch(r"\s*\d+\s*", text):
        raise ReductionError(f"freq-dep {spec!r}: {text!r} is not a non-negative integer")
    return int(text)


#: the constant model's frequency dependence; ``CONSTANT.text`` ("none") names it in stored fits
CONSTANT = FreqDep(FreqDepKind.NONE.value, {"K": (0,), "C": (0,), "D": (0,)}, FreqDepKind.NONE)


def parse_freq_dep(spec: str) -> FreqDep:
    """Parse a frequency-dependence spec: none | power:M | power:m,n,p | power:auto | poly:R."""
    s = str(spec).strip().lower()
    if s in (CONSTANT.text, ""):
        return CONSTANT
    word, sep, arg = s.partition(":")
    kind = {k.value: k for k in (FreqDepKind.POWER, FreqDepKind.POLY)}.get(word)
    if not sep or kind is None:
        raise ReductionError(f"unknown freq-dep {spec!r}: use none, power:M, power:m,n,p, power:auto or poly:R")
    if kind is FreqDepKind.POWER and arg.strip() == "auto":
        return FreqDep("power:auto", None, kind)
    parts = [_int(p, spec) for p in arg.split(",")]
    if any(not 1 <= p <= MAX_ORDER for p in parts):
        raise ReductionError(f"freq-dep {spec!r}: exponents and orders must lie in 1..{MAX_ORDER}")
    if kind is FreqDepKind.POLY:
        if len(parts) != 1:
            raise ReductionError(f"freq-dep {spec!r}: poly takes one order R, e.g. poly:2")
        orders = tuple(range(parts[0] + 1))
        return FreqDep(f"poly:{parts[0]}", {"K": orders, "C": orders, "D": orders}, kind)
    if len(parts) == 1:
        m = n = p = parts[0]
    elif len(parts) == 3:
        m, n, p = parts
    else:
        raise ReductionError(f"freq-dep {spec!r}: power takes M or m,n,p")
    text = f"power:{parts[0]}" if len(parts) == 1 else f"power:{m},{n},{p}"
    return FreqDep(text, {"K": (0, m), "C": (0, n), "D": (0, p)}, kind)


def is_constant(freq_dep: str) -> bool:
    """Whether a stored or given frequency-dependence spec is the constant model's (``none``)."""
    return parse_freq_dep(freq_dep).constant


def resolved_freq_dep(freq_dep: str, exponent: int | None) -> str:
    """``freq_dep`` with power:auto replaced by ``power:exponent`` (the M it chose); another spec as given."""
    return f"power:{exponent}" if parse_freq_dep(freq_dep).auto else freq_dep


@dataclass(frozen=True)
class Term:
    """One free coefficient: matrix K|C|D, order r (multiplies Omega^r), the matrix entries
    (i, j) it fills (two for a symmetric off-diagonal pair) and its name."""

    matrix: str
    order: int
    entries: tuple[tuple[int, int], ...]
    name: str


def coefficient_name(matrix: str, entry: str, order: int) -> str:
    """Spec key of one matrix entry: ``Kxx`` (order 0), ``Kxx_r`` (order r >= 1)."""
    return f"{matrix}{entry}" if order == 0 else f"{matrix}{entry}_{order}"


@dataclass(frozen=True)
class ModelSpec:
    """A model with a resolved frequency dependence: its free coefficients (``terms``)."""

    model: str
    freq_dep: FreqDep
    terms: tuple[Term, ...]
    absorbed: tuple[int, ...] = ()  # K orders not fitted: D of order r - 2 carries them

    @property
    def names(self) -> list[str]:
        """Free coefficient names, in regression column order."""
        return [t.name for t in self.terms]

    @property
    def n_coefficients(self) -> int:
        return len(self.terms)

    @property
    def min_frequencies(self) -> int:
        """ceil(free coefficients / 4): every orbit frequency gives four real equations."""
        return math.ceil(len(self.terms) / 4)

    @property
    def matrices(self) -> tuple[str, ...]:
        return tuple(MODELS[self.model])

    def orders(self, matrix: str) -> tuple[int, ...]:
        """Fitted orders of ``matrix`` (K without the absorbed orders)."""
        rs = self.freq_dep.fixed_orders()[matrix]
        return tuple(r for r in rs if not (matrix == "K" and r in self.absorbed))

    def keys(self) -> list[str]:
        """Output keys: all four entries of every matrix and fitted order of the model."""
        out = []
        for m in self.matrices:
            for r in self.orders(m):
                out += [coefficient_name(m, e, r) for e in ENTRIES]
        return out

    @property
    def notes(self) -> list[str]:
        """Facts about the coefficient list: which stiffness orders inertia absorbed."""
        out = []
        for r in self.absorbed:
            d = r - 2
            dname = "D" if d == 0 else f"D_{d}"
            out.append(
                f"K order {r} (Kxx_{r} .. Kyy_{r}) is not fitted: Omega^{r} K_{r} and the inertia term "
                f"-Omega^{r} {dname} have the same regressor for every orbit, so {dname} carries "
                f"that term (its reported value is {dname} - K_{r})"
                + (
                    "; the skew-symmetric part of K_%d, a skew-symmetric inertia, is not represented" % r
                    if MODELS[self.model].get("D")
                    else ""
                )
                + "."
            )
        return out

    @cached_property
    def _key_columns(self) -> tuple[tuple[str, int], ...]:
        """(output key, free-coefficient column) pairs, in key order."""
        column = {}
        for j, t in enumerate(self.terms):
            for i, l in t.entries:
                column[coefficient_name(t.matrix, "xy"[i] + "xy"[l], t.order)] = j
        return tuple((k, column[k]) for k in self.keys())

    def expand(self, values: Iterable[T]) -> dict[str, T]:
        """Free coefficient values (column order) -> {key: value}, symmetric pairs repeated."""
        values = list(values)
        return {k: values[j] for k, j in self._key_columns}


def check_model(model: str) -> None:
    """Raise ReductionError unless ``model`` is one of MODELS (kc7 | kc8 | kcd11 | kcd12): the
    one check of a model's name and its message."""
    if model not in MODELS:
        raise ReductionError(f"unknown model {model!r}: use one of {', '.join(MODELS)}")


def model_spec(model: str, freq_dep: str | FreqDep = "none") -> ModelSpec:
    """Build the coefficient list of ``model`` (kc7 | kc8 | kcd11 | kcd12) with ``freq_dep``.

    ``power:auto`` cannot be resolved here (``identify`` tries each exponent): it raises.
    """
    check_model(model)
    fd = freq_dep if isinstance(freq_dep, FreqDep) else parse_freq_dep(freq_dep)
    orders = fd.fixed_orders()  # ReductionError for power:auto
    has_d = "D" in MODELS[model]
    absorbed = tuple(r for r in orders["K"] if has_d and r - 2 in orders["D"])
    terms = []
    for matrix, symmetric in MODELS[model].items():
        for r in orders[matrix]:
            if matrix == "K" and r in absorbed:
                continue
            for e in ENTRIES:
                i, j = _INDEX[e[0]], _INDEX[e[1]]
                if symmetric and (i, j) == (1, 0):
                    continue  # Cyx is Cxy
                entries = ((i, j), (j, i)) if symmetric and i != j else ((i, j),)
                terms.append(Term(matrix, r, entries, coefficient_name(matrix, e, r)))
    return ModelSpec(model, fd, tuple(terms), absorbed)


def power_spec(model: str, exponent: int) -> ModelSpec:
    """``model`` with ``power:M`` (one of the candidates of power:auto)."""
    return model_spec(model, f"power:{exponent}")
