"""`orbitrig report` as an operator reads it after a crash."""

from typer.testing import CliRunner

from orbitrig.cli import app

from support.report_synthetic import write_synthetic_run


def test_report_of_a_killed_run_says_how_to_continue_it(tmp_path):
    run = write_synthetic_run(tmp_path / "run", n_points=1, incomplete=1, finished=False)  # as kill -9 leaves it
    assert not (run / "run.h5").exists()
    r = CliRunner().invoke(app, ["report", str(run), "--point", "0", "--figures", "coherence"])  # the quickest kind
    assert r.exit_code == 0, r.output
    assert "run running: 1 complete point(s), 1 incomplete" in r.stdout
    assert f"orbitrig sweep --resume {run}" in r.stdout


def test_forces_plot_keeps_agreeing_models_visible(tmp_path):
    """kc8 and kcd11 reproduce nearly the same forces: the lines differ in width so neither hides the other."""
    from orbitrig.analysis import plots, plots_forces
    from orbitrig.analysis.report_analysis import analyse_point
    from orbitrig.store.reader import read_run

    run = write_synthetic_run(tmp_path / "run", n_points=1, incomplete=0)
    pr = analyse_point(read_run(run).points[0])
    fitted = [plots.Fitted(f"{r.model} {r.freq_dep}", r.identification) for r in pr.results["piezo"]]
    assert len(fitted) >= 2
    amp = plots_forces.forces_figure(pr.point.tables["piezo"], fitted, title="t").axes[0]
    model_lines = [ln for ln in amp.get_lines() if ln.get_linestyle() != "None"]
    widths = sorted({ln.get_linewidth() for ln in model_lines}, reverse=True)
    assert len(widths) == len(fitted) and widths[-1] >= 0.7  # pt, at a journal column's width
    assert all(a - b >= 0.6 - 1e-9 for a, b in zip(widths, widths[1:]))


def test_the_page_says_micrometres_as_the_prompts_do(synthetic_report):
    """The report's settings table spells the orbit radius in rigunits' micrometre, as the
    service's prompt and the dashboard do: 0.04 of the 60 µm clearance."""
    from rigunits import MICROMETRE

    assert f"orbit radius (commanded)</th><td>2.4 {MICROMETRE}<" in synthetic_report.page
    assert MICROMETRE == "\u00b5m" and " um<" not in synthetic_report.page
