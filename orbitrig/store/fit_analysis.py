"""Numeric datasets of a fit's judgement (orbitrig.run.point_analysis), beside its JSON.

Under ``identification/<lms>__<model>__<freq_dep>__<method>``, each group present only
when the sweep evaluated it (docs/storage.md):

- ``uncertainty/``: ``statistical``, ``systematic``, ``combined``, ``expanded`` aligned with
  the fit's ``names`` (SI per coefficient), ``k_values`` (each U's k) and ``effective_dof`` (1;
  inf: every part exact) where the run stored them, attribute ``k`` (the largest); ``sources`` and ``source_std``:
  the stated calibration uncertainties propagated (1, rad or s per source), ``source_dof`` their
  degrees of freedom (1; inf: exact; runs stored since) that rebuild each U's k; ``runout`` (per
  coefficient, SI) the subtracted runout's part of ``systematic`` when the record states its u,
  and its covariance ``runout_covariance`` (free coefficients, attribute ``names``): what rebuilds
  it, as ``sources`` and ``source_std`` rebuild the calibration's with the orbit table;
- ``adequacy/``: attributes ``verdict``, ``supported``, ``p_value``, ``statistic``, ``test``,
  ``dof``, ``alpha``, ``aic``, ``bic`` (constant, this fit), ``constant``;
- ``lms_consistency/``: ``e_n`` aligned with ``names`` (1), attributes ``max_abs``,
  ``consistent`` (the joint chi2 within ``limit`` at the family-wise ``level``), ``test``,
  ``chi2``, ``dof``, ``level``, ``p_value``, ``basis``, ``limit``, ``pair``;
- ``derived/``: at the point's planned orbit frequencies ``orbit`` (rad/s), ``orbit_hz``,
  ``c_eff_xx``/``c_eff_yy`` (+ ``_std``, N s/m), ``h_forward``/``h_backward`` (complex, N/m;
  ``_std`` columns re, im), ``wfr`` (+ ``_std``, 1), ``c_eff_zero_xx``/``_yy`` (Omega_0,
  std; rad/s) when C_eff changes sign; attribute ``covariance`` (combined | statistical).

A part that could not be evaluated is a group with only an ``error`` attribute.

Beside them, aligned with ``names``: ``expanded_uncertainty`` (U; attributes ``k``, the largest,
``basis``: combined | statistical), ``expanded_k`` (each U's k, fit_record.expanded_ks) and ``not_determined`` (1 where U exceeds the magnitude,
also the names in attribute ``names``); in --sim runs ``truth``: the fit's own truth, the
true Z(Omega) projected onto its model (orbitrig.run.model_truth; NaN where the model has
no such coefficient; attribute ``definition``, or only ``error``).
"""

from __future__ import annotations

import math
from typing import Any

import h5py
import numpy as np

from orbitrig.store.descriptions import DATASETS, ORBIT_DERIVED, SI_PER_COEFFICIENT
from orbitrig.store.layout import DERIVED_UNITS
from orbitrig.store.fit_record import expanded_ks
from orbitrig.store.pieces import fixed_text, put, strings
from reduction.whirl import Whirl
from rigunits import HZ

PER_COEFFICIENT = SI_PER_COEFFICIENT
SOURCE_UNITS = "per source: 1 (gain, sensitivity), rad (phase), s (delay)"


def c_eff_zero(derived: dict[str, Any], k: str) -> np.ndarray | None:
    """(Omega_0, its std) in rad/s where C_eff,k (k: xx, yy) changes sign, from the derived
    quantities as identified (stored in Hz); None where it does not."""
    zero = derived.get(f"c_eff_zero_{k}_hz")
    return None if zero is None else HZ * np.array([_num(v) for v in zero])


def _num(v: Any) -> float:
    return math.nan if v is None else float(v)


def _vector(d: dict[str, Any], names: list[str]) -> np.ndarray:
    return np.array([_num(d.get(k)) for k in names], dtype=np.float64)


def write_fit_analysis(h: h5py.Group, d: dict[str, Any], names: list[str]) -> None:
    """The uncertainty, adequacy, lms_consistency and derived parts of the fit's JSON ``d``."""
    write_fit_values(h, d, names)
    for part, writer in (
        ("uncertainty", lambda g, u, n: _uncertainty(g, u, n, list(d.get("free") or []))),
        ("adequacy", _adequacy),
        ("lms_consistency", _consistency),
        ("derived", _derived),
    ):
        if not d.get(part):
            continue
        g = h.create_group(part)
        if "error" in d[part]:
            g.attrs["error"] = str(d[part]["error"])
        else:
            writer(g, d[part], names)


def write_fit_values(h: h5py.Group, d: dict[str, Any], names: list[str]) -> None:
    """The expanded uncertainty, not_determined and the fit's own truth of the fit's JSON ``d``."""
    if d.get("expanded_uncertainty"):
        e = d["expanded_uncertainty"]
        put(
            h,
            "expanded_uncertainty",
            _vector(e["values"], names),
            PER_COEFFICIENT,
            k=float(e["k"]),
            basis=e["basis"],
            meaning="expanded uncertainty U, k times the combined standard uncertainty",
        )
        ks = expanded_ks(d)
        put(h, "expanded_k", np.array([ks[k] for k in names], dtype=float), "1", meaning=DATASETS["expanded_k"][1])
    if "not_determined" in d:
        nd = list(d["not_determined"])
        put(
            h,
            "not_determined",
            np.array([k in nd for k in names], dtype=np.uint8),
            "1",
            names=strings(nd),
            meaning="1: the expanded uncertainty exceeds the magnitude (not determined)",
        )
    t = d.get("truth")
    if t:
        if "error" in t:
            h.create_group("truth").attrs["error"] = str(t["error"])
        else:
            put(
                h,
                "truth",
                _vector(t["coefficients"], names),
                PER_COEFFICIENT,
                definition=t["definition"],
                meaning="the simulator's true Z(Omega) projected onto this fit's model",
            )


def _uncertainty(g: h5py.Group, u: dict[str, Any], names: list[str], free: list[str]) -> None:
    g.attrs["k"] = float(u["k"])
    for k in ("statistical", "systematic", "combined", "expanded"):
        put(g, k, _vector(u[k], names), PER_COEFFICIENT, meaning=DATASETS[k][1])
    if u.get("k_values"):
        put(g, "k_values", _vector(u["k_values"], names), "1", meaning=DATASETS["k_values"][1])
        dof = np.array([math.inf if (u.get("dof") or {}).get(k) is None else float(u["dof"][k]) for k in names])
        put(g, "effective_dof", dof, "1", meaning=DATASETS["effective_dof"][1])
    if u.get("runout"):
        put(g, "runout", _vector(u["runout"], names), PER_COEFFICIENT, meaning=DATASETS["runout"][1])
    if u.get("runout_covariance") is not None and free:  # what rebuilds the term, as sources and source_std
        cov = np.array([[_num(v) for v in row] for row in u["runout_covariance"]], dtype=np.float64)
        put(g, "runout_covariance", cov.reshape(len(free), -1), PER_COEFFICIENT, names=strings(free))
    g.create_dataset("sources", data=fixed_text(u["sources"]))
    put(
        g,
        "source_std",
        np.asarray(u["source_std"], dtype=np.float64),
        SOURCE_UNITS,
        meaning="stated standard uncertainty of each calibration error",
    )
    if u.get("source_dof"):  # what rebuilds each U's k with the sources (quality.budget_coverage)
        dof = np.array([math.inf if v is None else float(v) for v in u["source_dof"]])
        put(g, "source_dof", dof, "1", meaning=DATASETS["source_dof"][1])


def _adequacy(g: h5py.Group, a: dict[str, Any], names: list[str]) -> None:
    g.attrs.update(
        {
            "verdict": a["verdict"],
            "supported": bool(a["supported"]),
            "p_value": _num(a["p_value"]),
            "statistic": _num(a["statistic"]),
            "test": a["test"],
            "dof": np.asarray(a["dof"], dtype=np.int64),
            "alpha": float(a["alpha"]),
            "aic": np.asarray([_num(v) for v in a["aic"]]),
            "bic": np.asarray([_num(v) for v in a["bic"]]),
            "constant": a["constant"],
            "aic_bic_order": "constant, this fit",
        }
    )


def _consistency(g: h5py.Group, c: dict[str, Any], names: list[str]) -> None:
    put(g, "e_n", _vector(c["e_n"], names), "1", meaning=f"normalised difference {c['pair']}")
    g.attrs.update(
        {
            "max_abs": _num(c["max_abs"]),
            "consistent": bool(c["consistent"]),
            "basis": c["basis"],
            "limit": _num(c["limit"]),
            "pair": c["pair"],
        }
    )
    if "chi2" in c:  # the joint test (absent in a fit stored before it)
        g.attrs.update(
            {
                "test": c["test"],
                "chi2": _num(c["chi2"]),
                "dof": int(c["dof"]),
                "level": float(c["level"]),
                "p_value": _num(c["p_value"]),
            }
        )


def _derived(g: h5py.Group, d: dict[str, Any], names: list[str]) -> None:
    hz = np.asarray(d["orbit_hz"], dtype=np.float64)
    g.attrs["covariance"] = d.get("covariance", "")
    put(g, "orbit", HZ * hz, "rad/s", meaning=ORBIT_DERIVED)
    put(g, "orbit_hz", hz, "Hz")
    for k in ("xx", "yy"):
        put(
            g,
            f"c_eff_{k}",
            np.asarray(d[f"c_eff_{k}"], dtype=np.float64),
            DERIVED_UNITS[f"c_eff_{k}"],
            meaning=f"effective damping C_eff,{k}",
        )
        if d.get(f"c_eff_{k}_std") is not None:
            put(g, f"c_eff_{k}_std", np.asarray(d[f"c_eff_{k}_std"], dtype=np.float64), DERIVED_UNITS[f"c_eff_{k}"])
        zero = c_eff_zero(d, k)
        if zero is not None:
            put(
                g,
                f"c_eff_zero_{k}",
                zero,
                "rad/s",
                columns=strings(("omega_0", "std")),
                meaning="zero crossing of C_eff",
            )
    for k in Whirl:
        h = np.asarray(d[f"h_{k}_re"], dtype=np.float64) + 1j * np.asarray(d[f"h_{k}_im"], dtype=np.float64)
        put(g, f"h_{k}", h, "N/m", meaning=f"{k} direct dynamic stiffness H")
        if d.get(f"h_{k}_std") is not None:
            std = np.array([[_num(v) for v in row] for row in d[f"h_{k}_std"]], dtype=np.float64).T
            put(g, f"h_{k}_std", std, "N/m", columns=strings(("re", "im")))
    wfr = np.array([_num(v) for v in d["wfr"]], dtype=np.float64)
    put(g, "wfr", wfr, DERIVED_UNITS["wfr"], meaning="whirl frequency ratio")
    if d.get("wfr_std") is not None:
        put(g, "wfr_std", np.array([_num(v) for v in d["wfr_std"]], dtype=np.float64), "1")
