"""The report's signal figures, checked for content: the paper's Figure 4 (both load measuring
systems' averaged forces and their difference; one raw revolution against the average) and
the x-y orbits, read back from the drawn lines against the stored arrays (read with h5py)."""

from __future__ import annotations

import re

import h5py
import numpy as np
import pytest

from orbitrig.analysis.plots_signals import lms_difference, orbits_figure, signals_figure
from orbitrig.analysis.report import signals_title
from orbitrig.analysis.rounding import orbit_frequency
from orbitrig.analysis.signals import default_frequencies, read_block_signals
from orbitrig.config import load_rig
from orbitrig.store.reader import read_run
from support.report_synthetic import N_REV, STRAIN_GAIN

CH = load_rig().channel_index


def _stored(run_dir, point: str, block: str) -> dict:
    """The block as stored, read independently of the report's reader."""
    with h5py.File(run_dir / "run.h5", "r") as f:
        g = f[f"points/{point}/frequencies/{block}"]
        return {k: g[k][()] for k in ("mean", "raw_counts", "gains", "offsets", "slots")}


def _fundamental(theta, values) -> complex:
    """Least-squares q_bar of dc + Re(q_bar e^{i theta}) (numpy only)."""
    basis = np.column_stack([np.ones_like(theta), np.cos(theta), -np.sin(theta)])
    c = np.linalg.lstsq(basis, values, rcond=None)[0]
    return complex(c[1], c[2])


@pytest.fixture(scope="module")
def run(synthetic_run):
    return read_run(synthetic_run)


def test_default_subset_is_lowest_and_highest_of_each_direction(run):
    point = run.points[0]
    chosen = default_frequencies(point)
    assert [f.name for f in chosen] == ["00_fwd", "09_fwd", "00_bwd", "09_bwd"]
    fwd = [f.orbit_hz for f in point.frequencies if f.direction > 0]
    assert chosen[0].orbit_hz == min(fwd) and chosen[1].orbit_hz == max(fwd)


def test_figure_4a_draws_both_systems_averages_and_states_their_difference(synthetic_run, run):
    point = run.points[1]
    freq = next(f for f in point.frequencies if f.name == "03_fwd")
    stored = _stored(synthetic_run, "0001", "03_fwd")
    fig = signals_figure(read_block_signals(run, point, freq), title="t")
    for col, axis in enumerate(("fx", "fy")):
        ax = fig.axes[col]  # row (a)
        lines = {ln.get_label(): ln for ln in ax.get_lines()}
        q = {}
        for lms in ("piezo", "strain"):
            c = CH[f"{axis}_{lms}"]
            order = np.argsort(stored["slots"][c])
            np.testing.assert_allclose(lines[lms].get_xdata(), stored["slots"][c][order] * 1.0)  # deg = slot
            np.testing.assert_allclose(lines[lms].get_ydata(), stored["mean"][c][order])
            q[lms] = _fundamental(2 * np.pi * stored["slots"][c] / 360, stored["mean"][c])
        title = ax.get_title().replace("\n", " ")
        found = re.search(r"piezo \u2212 strain: ([-+\d.]+) % of \|piezo\|, phase ([-+\d.]+) deg", title)
        amp, phase = map(float, found.groups())
        # the page's consistency table's convention: (piezo - strain) / |piezo|, phase piezo - strain
        assert amp == pytest.approx(100 * (abs(q["piezo"]) - abs(q["strain"])) / abs(q["piezo"]), abs=0.006)
        assert phase == pytest.approx(np.degrees(np.angle(q["piezo"] / q["strain"])), abs=0.006)


def test_figure_4a_difference_recovers_the_injected_1_8_percent_and_0_3_degrees(run):
    """The strain gauges read 1.018 e^{i 0.3 deg} times the piezo force, so piezo - strain is
    -1.8 % of |piezo| and -0.3 deg (the page's convention); the averaged waveforms
    carry 3 % per-sample noise (8 revolutions, 45 samples: about 0.3 % / 0.2 deg per block).
    The mean over 40 block/axis pairs is within 4 standard errors of the injected values."""
    diffs = [
        lms_difference(read_block_signals(run, p, f), axis)
        for p in run.complete_points
        for f in p.frequencies
        for axis in ("fx", "fy")
    ]
    amp = np.array([d.amplitude_pct for d in diffs])
    phase = np.array([d.phase_deg for d in diffs])
    assert len(diffs) == 80
    assert abs(amp.mean() - 100 * (1 - abs(STRAIN_GAIN))) < 4 * amp.std() / np.sqrt(amp.size)
    assert abs(phase.mean() + np.degrees(np.angle(STRAIN_GAIN))) < 4 * phase.std() / np.sqrt(phase.size)


def test_figure_4b_draws_one_raw_revolution_against_the_average(synthetic_run, run):
    point = run.points[0]
    freq = next(f for f in point.frequencies if f.name == "09_bwd")
    stored = _stored(synthetic_run, "0000", "09_bwd")
    sig = read_block_signals(run, point, freq)
    assert sig.n_revolutions == N_REV and sig.revolution == 0
    fig = signals_figure(sig, title="t")
    for col, axis in enumerate(("fx", "fy")):
        ax = fig.axes[2 + col]  # row (b)
        c = CH[f"{axis}_piezo"]
        order = np.argsort(stored["slots"][c])
        raw, mean = ax.get_lines()
        expect_raw = stored["raw_counts"][0, c] * stored["gains"][c] + stored["offsets"][c]
        np.testing.assert_allclose(raw.get_ydata(), expect_raw[order])
        np.testing.assert_allclose(mean.get_ydata(), stored["mean"][c][order])
        assert raw.get_label() == "revolution 1 (raw)" and mean.get_label() == f"average of {N_REV}"
        rms_raw, rms_mean = map(float, re.search(r"raw ([\d.e+-]+), average ([\d.e+-]+) N", ax.get_title()).groups())
        # averaging 8 revolutions of independent sample noise divides its RMS by about sqrt(8)
        assert 1.8 < rms_raw / rms_mean < 4.5


def test_orbit_figure_one_panel_per_frequency_with_both_planes(synthetic_run, run):
    point = run.points[0]
    blocks = [read_block_signals(run, point, f) for f in point.frequencies]
    fig = orbits_figure(blocks, radius=point.settings.orbit_radius, title="t")
    panels = [ax for ax in fig.axes if ax.get_visible()]
    assert len(panels) == 20
    for ax, sig in zip(panels, blocks):
        f = sig.frequency
        head, mean, radii = ax.get_title().split("\n")  # short lines: neighbouring titles stay apart
        assert mean == "mean radius"
        assert head == f"{orbit_frequency(f.orbit_hz)} {'forward' if f.direction > 0 else 'backward'}"
        stated = [float(v) for v in re.findall(r"[AB] ([\d.]+)", radii)]
        lines = {ln.get_label(): ln for ln in ax.get_lines()}
        stored = _stored(synthetic_run, "0000", f.name)
        for plane, (xn, _yn) in (("A", ("x_a", "y_a")), ("B", ("x_b", "y_b"))):
            x, y = lines[f"plane {plane}"].get_xdata() / 1e6, lines[f"plane {plane}"].get_ydata() / 1e6
            c = CH[xn]
            np.testing.assert_allclose(x[:-1], stored["mean"][c][np.argsort(stored["slots"][c])])
            # measured radius: the commanded 2.4 um within the synthetic 1 % scatter and noise
            r = np.hypot(x[:-1] - x[:-1].mean(), y[:-1] - y[:-1].mean())
            assert np.median(r) == pytest.approx(point.settings.orbit_radius, rel=0.05), (f.name, plane)
            assert stated["AB".index(plane)] == pytest.approx(r.mean() * 1e6, rel=5e-3)
        # the arrow from the trigger point shows the sense of the whirl: counter-clockwise forward
        arrow = next(t for t in ax.texts if t.arrow_patch is not None)
        (x0, y0), (x1, y1) = arrow.xyann, arrow.xy
        cx, cy = lines["plane A"].get_xdata().mean(), lines["plane A"].get_ydata().mean()
        turn = (x0 - cx) * (y1 - cy) - (y0 - cy) * (x1 - cx)
        assert np.sign(turn) == f.direction, f.name


def test_signals_titles_and_orbit_panels_state_an_orbit_frequency_alike(run):
    """One rule (rounding.orbit_frequency, 4 significant digits): the lowest frequency of the
    synthetic run, 0.2 x 1000 rpm, is 3.333 Hz in its Figure 4's title and its orbit panel."""
    assert [orbit_frequency(v) for v in (10 / 3, 20.0, 12.5, 33.333333, None, float("nan"))] == [
        "3.333 Hz",
        "20 Hz",
        "12.5 Hz",
        "33.33 Hz",
        "- Hz",
        "- Hz",
    ]
    point = run.points[0]
    blocks = [read_block_signals(run, point, f) for f in point.frequencies]
    panels = [
        ax for ax in orbits_figure(blocks, radius=point.settings.orbit_radius, title="t").axes if ax.get_visible()
    ]
    for ax, sig in zip(panels, blocks):
        f = sig.frequency
        stated = ax.get_title().split(" ")[0]
        assert signals_title(f, "where").startswith(f"Force signals at {stated} Hz "), f.name
    lowest = min(blocks, key=lambda b: b.frequency.orbit_hz).frequency
    assert (
        signals_title(lowest, "p").split("\n")[0]
        == f"Force signals at 3.333 Hz {'forward' if lowest.direction > 0 else 'backward'} whirl (paper Fig. 4)"
    )


def test_an_unreadable_block_leaves_the_other_figures(synthetic_run, tmp_path):
    """A block the store lists but the report cannot read is named (stderr lines, page); the
    point's other signal figures and its orbits are still drawn."""
    from dataclasses import replace

    from orbitrig.analysis.report import ReportOptions, _plot_signals

    from orbitrig.analysis.report_analysis import analyse_point

    point = read_run(synthetic_run).points[0]
    ghost = replace(next(f for f in point.frequencies if f.name == "00_fwd"), name="00_fwd_missing", orbit_hz=0.1)
    point.frequencies.append(ghost)  # the lowest forward frequency now, and not in storage
    pr = analyse_point(point)
    _plot_signals(read_run(synthetic_run), pr, tmp_path, "where", ReportOptions())
    assert len(pr.unreadable) == 1 and pr.unreadable[0].startswith("signals of block 00_fwd_missing not drawn: ")
    assert pr.unreadable[0] in pr.fit_warnings()
    names = {p.name for p in pr.plots}
    assert names == {"orbits_0000.png", "signals_0000_09_fwd.png", "signals_0000_00_bwd.png", "signals_0000_09_bwd.png"}


def test_the_lms_figure_draws_piezo_minus_strain_as_the_page_s_consistency_table(synthetic_figures):
    """The LMS figure's differences take the consistency table's convention, (piezo - strain) /
    |piezo| and phase piezo - strain: the strain gauges read 1.018 e^{i 0.3 deg} times the piezo
    force, so every frequency's amplitude difference is near -1.8 % and its phase near -0.3 deg
    (it drew strain vs piezo, +1.8 % and +0.3 deg)."""
    (fig,) = synthetic_figures("double")["lms"][:1]
    amplitude, phase = fig.axes[0], fig.axes[1]
    assert amplitude.get_ylabel().replace("\n", " ") == "(|F piezo| \u2212 |F strain|) / |F piezo|  [%]"
    assert phase.get_ylabel().replace("\n", " ") == "phase(F piezo) \u2212 phase(F strain)  [deg]"
    amp = np.concatenate([ln.get_ydata() for ln in amplitude.get_lines() if ln.get_label()[0] != "_"])
    deg = np.concatenate([ln.get_ydata() for ln in phase.get_lines() if ln.get_label()[0] != "_"])
    assert amp.size == deg.size >= 20
    assert np.mean(amp) == pytest.approx(100 * (1 - abs(STRAIN_GAIN)), abs=0.2)
    assert np.mean(deg) == pytest.approx(-np.degrees(np.angle(STRAIN_GAIN)), abs=0.15)
