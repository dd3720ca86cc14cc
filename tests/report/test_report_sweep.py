"""reduce and report on a run written by the real sweep on the simulator
(`orbitrig sweep --sim --sim-config config/sim/clean.toml --matrix SMALL --out DIR`: the clean
scenario, the demo matrix with fewer revolutions per block and one frequency-dependent model more)."""

from __future__ import annotations

import csv
import json
import hashlib
import re
from pathlib import Path

import numpy as np
import pytest

from orbitrig.analysis.reduce import csv_path
from orbitrig.analysis.typeset import operating_point_html
from orbitrig.store.reader import read_run

from support.cli_helpers import orbitrig

MODELS = (("kcd11", "none"), ("kc8", "none"), ("kcd11", "power:1"))  # the sweep_run fixture's (conftest)


def _csv(path: Path) -> list[dict]:
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.mark.parametrize("model, freq_dep", MODELS)
def test_reduce_gives_the_sweeps_coefficients(sweep_run, model, freq_dep):
    p = orbitrig("reduce", str(sweep_run), "--model", model, "--freq-dep", freq_dep, "--json")
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    point = read_run(sweep_run).points[0]
    assert [(r["point"], r["lms"]) for r in out["results"]] == [(0, "piezo"), (0, "strain")]
    for r in out["results"]:
        stored = point.identification(r["lms"], model, freq_dep)
        assert stored is not None and stored.ok
        assert r["coefficients"].keys() == stored.result["coefficients"].keys()
        for key, value in stored.result["coefficients"].items():
            assert r["coefficients"][key] == pytest.approx(value, rel=1e-9, abs=1e-12), key
    # the reduce CSV carries the numbers of the run's own coefficients.csv
    ours = _csv(csv_path(sweep_run, model, freq_dep, "ols"))
    theirs = [r for r in _csv(sweep_run / "coefficients.csv") if (r["model"], r["freq_dep"]) == (model, freq_dep)]
    assert len(ours) == len(theirs) == 2
    for a, b in zip(ours, theirs):
        assert (a["point"], a["lms"]) == (b["point"], b["lms"])
        for key in ("Kxx [N/m]", "Kxy [N/m]", "Cyx [N s/m]", "Cyy [N s/m]", "true_Kxx [N/m]"):
            assert float(a[key]) == pytest.approx(float(b[key]), rel=1e-6), key


def test_reduce_table_shows_each_fits_own_truth(sweep_run):
    """The table's true rows are each fit's own truth (the true Z projected onto kc7:
    C symmetric), the numbers of the CSV's true_* columns (--format csv: SI, in full)."""
    p = orbitrig("reduce", str(sweep_run), "--model", "kc7", "--format", "csv")
    assert p.returncode == 0, p.stderr
    rows = list(csv.DictReader(p.stdout.splitlines()))
    assert [r["lms"] for r in rows] == ["piezo", "true (piezo)", "strain", "true (strain)"]
    written = {r["lms"]: r for r in _csv(csv_path(sweep_run, "kc7", "none", "ols"))}
    for lms in ("piezo", "strain"):
        true = rows[[r["lms"] for r in rows].index(f"true ({lms})")]
        assert true["Cxy [N s/m]"] == true["Cyx [N s/m]"]
        for key, unit in (("Kxx", "N/m"), ("Kxy", "N/m"), ("Cxy", "N s/m"), ("Cyy", "N s/m")):
            assert float(true[f"{key} [{unit}]"]) == float(written[lms][f"true_{key} [{unit}]"]), (lms, key)


def test_reduce_is_within_5_percent_of_the_simulator(sweep_run):
    """K and C within 5 % of the largest true entry, plus three standard errors: the simulated
    chain (1.8 % strain-gauge gain error, 55-60 N noise per sample, 10 revolutions a block)
    leaves a statistical scatter that the fit's own standard errors state."""
    p = orbitrig("reduce", str(sweep_run), "--model", "kcd11", "--json")
    truth = read_run(sweep_run).points[0].truth
    for r in json.loads(p.stdout)["results"]:
        c, s = r["coefficients"], r["std_errors"]
        for m in "KC":
            true = np.asarray(truth[f"{m}0"])
            keys = [[f"{m}xx", f"{m}xy"], [f"{m}yx", f"{m}yy"]]
            got = np.array([[c[k] for k in row] for row in keys])
            std = np.array([[s[k] for k in row] for row in keys])
            assert np.all(np.abs(got - true) <= 0.05 * np.abs(true).max() + 3 * std), (r["lms"], m, got, true, std)


def test_report_on_the_sweep(sweep_run):
    p = orbitrig("report", str(sweep_run), "--formats", "png", timeout=300)  # PDF and SVG: test_report_journal
    assert p.returncode == 0, p.stderr
    assert "warning" not in p.stderr  # every stored identification repeated to the same numbers
    plots = sweep_run / "plots"
    pngs = sorted(f.name for f in plots.glob("*.png"))
    assert pngs == sorted(
        [
            "forces_0000_piezo.png",
            "forces_0000_strain.png",
            "coherence_0000.png",
            "lms_0000.png",
            "coefficients_0000_piezo_kcd11.png",
            "coefficients_0000_strain_kcd11.png",
            "coefficients_0000_piezo_kc8.png",
            "coefficients_0000_strain_kc8.png",
            "derived_0000_piezo.png",
            "derived_0000_strain.png",
            "impedance_0000_piezo.png",
            "impedance_0000_strain.png",
            "orbits_0000.png",
            "signals_0000_00_fwd.png",
            "signals_0000_04_fwd.png",
            "signals_0000_00_bwd.png",
            "signals_0000_04_bwd.png",
        ]
    )
    for name in pngs:
        data = (plots / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 30_000
    html = (plots / "index.html").read_text(encoding="utf-8")
    assert set(re.findall(r'<img src="([^"]+)"', html)) == set(pngs)
    assert "completed" in html and "report-small" in html
    # which bearing, rig and calibration the page shows: the scenario by its name and its stored text's
    # SHA-256 (linked), not by the path of its file on the machine that made the run; the rig id, the
    # record with its SHA-256
    run = read_run(sweep_run)
    top = html[: html.index("Operating points")]
    header = re.sub(r"<[^>]+>", " ", top)
    scenario_sha = hashlib.sha256(run.sim_scenario_config.encode()).hexdigest()
    assert f"clean (clean.toml), SHA-256 {scenario_sha} of its  stored text" in header
    assert "/" in run.sim_scenario_name and run.sim_scenario_name not in html
    assert '<a href="#scenario">' in top and '<details id="scenario"><summary>simulator scenario</summary>' in html
    record, sha = run.provenance["calibration_record"], run.provenance["calibration_record_sha256"]
    assert f"{record} (SHA-256 {sha})" in header and f"rig  {run.provenance['rig_id']}" in " ".join(header.split("\n"))
    assert "<summary>simulator scenario</summary>" in html and "<summary>calibration record</summary>" in html
    # the operating point's symbols as the figures write them (orbitrig.analysis.typeset), in <sub>
    assert (
        '<tr><th>point</th><th class="l">label</th><th>\u03c9 [rpm]</th><th>p<sub>r</sub> [MPa]</th>'
        "<th>\u03b2</th><th>\u03b5<sub>s</sub></th><th>\u03b5<sub>d</sub></th><th>models identified</th></tr>"
    ) in html
    assert '<tr><th class="l">static eccentricity \u03b5<sub>s</sub></th>' in html
    assert f'<h2 id="p0000">Point 0000: {operating_point_html(run.points[0].settings)}</h2>' in html
    assert '<th class="l">\u03c7\u00b2 (known noise u<sub>*</sub>)</th>' in html
    assert '<th class="l">degrees of freedom 4n \u2212 p</th>' in html
    stored = read_run(sweep_run).points[0].identification("piezo", "kcd11", "none").result
    for key in ("Kxx", "Kyx", "Cxx", "Cyy"):
        scale = 1e-6 if key[0] == "K" else 1e-3
        assert f"{stored['coefficients'][key] * scale:.4g}".replace("-", "\u2212") in html, key  # the minus sign


def test_figure_4a_on_the_sweep_matches_the_stored_comparison(sweep_run):
    """The amplitude and phase difference that Figure 4 (a) states, from the averaged waveforms,
    equal the sweep's own strain/piezo comparison of the block phasors, stated as the page's
    consistency table states a difference: piezo - strain, relative to |piezo| (1 - the stored
    ratio, the stored phase difference negated)."""
    from orbitrig.analysis.plots_signals import lms_difference
    from orbitrig.analysis.signals import read_block_signals

    run = read_run(sweep_run)
    point = run.points[0]
    cmp = point.lms_comparison
    blocks = sorted(point.frequencies, key=lambda f: (f.orbit_hz, -f.direction))
    assert [f.orbit_hz for f in blocks] == pytest.approx(cmp["orbit_hz"])
    for k, f in enumerate(blocks):
        sig = read_block_signals(run, point, f)
        for axis in ("fx", "fy"):
            d = lms_difference(sig, axis)
            assert d.amplitude_pct == pytest.approx(100 * (1 - cmp[f"{axis}_amp_ratio"][k]), abs=2e-3), f.name
            assert d.phase_deg == pytest.approx(-cmp[f"{axis}_phase_diff_deg"][k], abs=2e-3), f.name
