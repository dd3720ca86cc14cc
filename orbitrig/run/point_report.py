"""A point's results in words and as the published object: run.log lines and the
``result`` payload (MQTT result topic), with warnings, refusals, intervals, the
uncertainty budget, the model-adequacy verdicts and the two systems' consistency."""

from __future__ import annotations

from typing import Any

from orbitrig.load_systems import LoadSystem
from orbitrig.run.plan import OperatingPoint
from orbitrig.store.layout import point_name
from orbitrig.store.records import IdentificationEntry, PointResults
from rigunits import coefficient_unit

#: keys of a fit's stored JSON that the result payload carries
PAYLOAD_KEYS = (
    "coefficients",
    "std_errors",
    "confidence_95",
    "interval",
    "condition_number",
    "residual_rms",
    "dof",
    "chi2",
    "p_value",
    "aic",
    "bic",
    "notes",
    "warnings",
    "exponent",
    "expanded_uncertainty",
    "not_determined",
    "truth",
)


def point_log_lines(p: OperatingPoint, res: PointResults) -> list[str]:
    """One line per refusal, warning, adequacy verdict and LMS consistency check of the point."""
    fits = [
        (lms, f"{e['spec'].model} {e['spec'].freq_dep} {e['spec'].method}", e.get("json"), e.get("error"))
        for (lms, _), e in res.identifications.items()
    ]
    return [f"point {point_name(p.index)}: {line}" for line in judgement_lines(fits)]


def judgement_lines(
    fits: list[tuple[LoadSystem, str, dict[str, Any] | None, str | None]],
    *,
    verdicts: bool = True,
    brief: bool = False,
    warnings: bool = True,
) -> list[str]:
    """Lines of (lms, "model freq_dep method", stored JSON or None, refusal or None) fits: refusals
    (``brief``: their first line; else every line joined by ' | '), (``warnings``) warnings, parts
    not evaluated, and (``verdicts``) the adequacy verdicts and LMS consistency."""
    lines, compared = [], set()
    for lms, name, d, error in fits:
        if d is None:
            reason = str(error).strip().splitlines() or [""]
            text = f"{reason[0]} (the full reason is in run.log)" if brief and len(reason) > 1 else " | ".join(reason)
            lines.append(f"{lms} {name}: refused: {text}")
            continue
        lines += [f"{lms} {name}: warning: {w}" for w in d.get("warnings") or [] if warnings]
        for part in ("uncertainty", "derived"):
            if "error" in (d.get(part) or {}):
                lines.append(f"{lms} {name}: {part} not evaluated: {d[part]['error']}")
        if verdicts and d.get("adequacy"):
            lines.append(f"{lms} {name}: {adequacy_text(d['adequacy'])}")
        if verdicts and d.get("lms_consistency") and name not in compared:
            compared.add(name)
            lines.append(f"{name}: {consistency_text(d['lms_consistency'])}")
    return lines


def adequacy_text(a: dict[str, Any]) -> str:
    """'frequency dependence supported: no (p = 0.94); AIC 812 / 815, BIC 840 / 858 (constant / this)'."""
    if "error" in a:
        return f"frequency dependence not tested: {a['error']}"
    aic, bic = a["aic"], a["bic"]
    return (
        f"{a['verdict']} against {a['constant']}; AIC {aic[0]:.6g} / {aic[1]:.6g}, "
        f"BIC {bic[0]:.6g} / {bic[1]:.6g} (constant / this)"
    )


def consistency_text(c: dict[str, Any]) -> str:
    """'load measuring systems piezo - strain: consistent (chi2 = 9.1 on 11 coefficients <= 19.7
    at the 5 % level, combined uncertainty); max |E_n| = 1.3'."""
    if "error" in c:
        return f"load measuring systems not compared: {c['error']}"
    if c["max_abs"] is None:
        return "load measuring systems not compared: no uncertainty"
    verdict = "consistent" if c["consistent"] else "NOT consistent"
    if c.get("chi2") is None:  # a run stored before the joint test: |E_n| per coefficient
        return (
            f"load measuring systems {c['pair']}: max |E_n| = {c['max_abs']:.3g} "
            f"({verdict} within |E_n| <= {c['limit']:g}, {c['basis']} uncertainty)"
        )
    return (
        f"load measuring systems {c['pair']}: {verdict} (chi2 = {c['chi2']:.3g} on {c['dof']} coefficients "
        f"{'<=' if c['consistent'] else '>'} {c['limit']:.3g} at the {100 * c['level']:g} % level, "
        f"{c['basis']} uncertainty); max |E_n| = {c['max_abs']:.3g}"
    )


def _row(lms: LoadSystem, e: IdentificationEntry) -> dict[str, Any]:
    spec = e["spec"]
    row = {"lms": lms, "model": spec.model, "freq_dep": spec.freq_dep, "method": spec.method}
    if "error" in e:
        row["error"] = e["error"]
        return row
    d = e["json"]
    row.update({k: d[k] for k in PAYLOAD_KEYS if k in d})
    row["units"] = {k: coefficient_unit(k) for k in d.get("coefficients") or {}}
    u = d.get("uncertainty")
    if u:
        parts = ("k", "k_values", "dof", "dof_notes", "systematic", "combined", "expanded")
        row["uncertainty"] = u if "error" in u else {k: u[k] for k in parts if k in u}
    for k in ("adequacy", "lms_consistency"):
        if d.get(k):
            row[k] = d[k]
    return row


def result_payload(run_id: str | None, p: OperatingPoint, res: PointResults) -> dict[str, Any]:
    """The point's results as published (MQTT result topic): settings, one row per fit (its
    coefficients, std_errors, confidence_95, warnings, notes, uncertainty budget, expanded
    uncertainty, not_determined, its own truth in --sim runs, adequacy, LMS consistency, or the
    refusal), and per point the adequacy verdicts, every warning, the refused fits, each block's
    spin turns the runout was placed with (runout_turns) and (--sim) the constant best fit of the
    true Z."""
    rows = [_row(lms, e) for (lms, _), e in res.identifications.items()]
    out: dict[str, Any] = {
        "run_id": run_id,
        **p.settings(),
        "identification": rows,
        "lms_comparison": res.lms_comparison,
    }
    if res.runout_turns is not None:
        out["runout_turns"] = res.runout_turns
    out["adequacy"] = [
        {
            "lms": r["lms"],
            "model": r["model"],
            "freq_dep": r["freq_dep"],
            "method": r["method"],
            **(
                {
                    "verdict": r["adequacy"]["verdict"],
                    "supported": r["adequacy"]["supported"],
                    "p_value": r["adequacy"]["p_value"],
                }
                if "verdict" in r["adequacy"]
                else r["adequacy"]
            ),
        }
        for r in rows
        if "adequacy" in r
    ]
    out["warnings"] = [
        f"{r['lms']} {r['model']} {r['freq_dep']} {r['method']}: {w}" for r in rows for w in r.get("warnings") or []
    ]
    out["refused"] = [{k: r[k] for k in ("lms", "model", "freq_dep", "method", "error")} for r in rows if "error" in r]
    if res.truth is not None:
        out["truth"] = {k: res.truth[k] for k in ("K0", "C0", "D0")}
    return out
