"""`identify --json` on the example orbit tables: the v3 keys exactly, and the truth within
the reported uncertainty (the examples carry noise of their stated u_*). The command runs in the
test's process (its real process's streams: test_identify_cli.py)."""

from __future__ import annotations

import json
import subprocess

import pytest

from support.cli_helpers import orbitrig_here
from support.units import UREG
from support.identify_keys import keys

from support.paths import ROOT

EXAMPLES = ROOT / "examples" / "orbit-tables"
TRUTH = json.loads((EXAMPLES / "truth.json").read_text())


def _identify(name: str, args: str, *extra: str) -> subprocess.CompletedProcess:
    return orbitrig_here("identify", str(EXAMPLES / name), *args.split(), *extra, columns=80)


@pytest.mark.parametrize("name", sorted(TRUTH))
def test_examples_follow_the_v3_contract(name):
    truth = TRUTH[name]
    res = _identify(name, truth["command"], "--json")
    assert res.returncode == truth.get("exit_status", 0), res.stderr
    if res.returncode == 2:
        assert res.stdout == "" and "Kxx_1 - Cxy" in res.stderr
        return
    d = json.loads(res.stdout)
    has_u = "n_records" in (EXAMPLES / name).read_text().splitlines()[0]
    assert list(d) == keys(has_u)
    assert d["interval"] == ("normal" if has_u else "student_t") and d["warnings"] == []
    # the constant models are determined; poly:2's higher D orders are not from this table
    assert (d["not_determined"] == []) == (d["freq_dep"] == "none"), d["not_determined"]
    assert set(d["coefficients"]) == set(truth["coefficients"]) == set(d["std_errors"]) == set(d["confidence_95"])
    assert list(d["units"]) == list(d["coefficients"])
    for key, unit in d["units"].items():  # SI, machine-readable: Kxx_r in N/m (rad/s)^-r
        order = int(key.partition("_")[2] or 0)
        si = {"K": "N/m", "C": "N*s/m", "D": "kg"}[key[0]] + f" * (rad/s)**{-order}"
        assert UREG.parse_units(unit) == UREG.parse_units(si), (key, unit)
    p = len(d["free"])
    assert d["n_coefficients"] == p and len(d["covariance"]) == p and all(len(r) == p for r in d["covariance"])
    assert d["dof"] == 4 * d["n_frequencies"] - p
    for key, true in truth["coefficients"].items():
        assert abs(d["coefficients"][key] - true) < 5 * d["std_errors"][key], key
    if has_u:
        assert 0.001 < d["p_value"] < 0.999  # the stated u_* are the noise the tables carry


def test_absorbed_order_is_a_note_and_readable_output_puts_notes_on_stderr():
    res = _identify("kcd11-poly2.csv", "--model kcd11 --freq-dep poly:2")
    assert res.returncode == 0
    assert "note: K order 2" in res.stderr and "note:" not in res.stdout
    assert "Kxx_1" in res.stdout and "Kxx_2 " not in res.stdout
    d = json.loads(_identify("kcd11-poly2.csv", "--model kcd11 --freq-dep poly:2", "--json").stdout)
    assert d["n_coefficients"] == 29 and any("K order 2" in n for n in d["notes"])
