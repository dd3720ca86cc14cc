"""`orbitrig design`: predicted standard errors of a list of orbit frequencies, and a better list.

The prediction is the Cramer-Rao bound of the model's coefficients for circular orbits of
one radius in the stated directions at the stated spin (reduction.frequency_list). Noise and
prior coefficients: orbitrig.cli.design_inputs. Exit 2 with a message on operator mistakes.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Optional

import typer

from orbitrig.load_systems import LoadSystem


def _fail(message: str) -> None:
    sys.stderr.write(f"orbitrig design: {message}\n")
    raise typer.Exit(code=2)


def _ratio_list(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        _fail(f"--ratios {text!r}: give numbers separated by commas, e.g. 0.2,0.5,1.2")
    if not values or any(not v > 0 for v in values) or len(set(values)) != len(values):
        _fail(f"--ratios {text!r}: give distinct ratios > 0")
    return values


def _candidate(ratios: Optional[str], matrix: Optional[str], rig) -> tuple[list[float], str, float | None, str, list]:
    """(ratios, directions, orbit radius m or None, where from, the matrix's (model, freq_dep) pairs)."""
    from orbitrig import config as cfg

    if ratios and matrix:
        _fail("give --ratios or --matrix, not both")
    if ratios:
        return _ratio_list(ratios), "both", None, "--ratios", []
    if matrix:
        mat = cfg.load_matrix(cfg.matrix_file(matrix))
        dirs = set(mat.orbit.directions)
        direction = "both" if len(dirs) == 2 else next(iter(dirs))
        radius = min(mat.operating.dynamic_eccentricity) * rig.bearing.clearance
        return (
            list(mat.orbit.ratio_list),
            direction,
            radius,
            f"matrix {mat.name}",
            [(m.model, m.freq_dep) for m in mat.models],
        )
    return [round(0.2 + k / 9, 6) for k in range(10)], "both", None, "the paper's list (0.2 to 1.2, 10 ratios)", []


def _noise(noise_from: Optional[Path], lms: str, force: Optional[float], probe_nm: Optional[float]):
    from orbitrig.cli import design_inputs as di

    probe = di.DEFAULT_PROBE_NOISE if probe_nm is None else probe_nm * 1e-9
    if noise_from is None:
        return di.stated_noise(di.DEFAULT_FORCE_NOISE if force is None else force, probe), None
    from orbitrig import open_run

    run = open_run(noise_from).run
    return di.run_noise(run, lms, probe), run


def register(app: typer.Typer) -> None:
    @app.command("design")
    def design_cmd(
        model: str = typer.Option(..., "--model", help="kc7 | kc8 | kcd11 | kcd12"),
        freq_dep: str = typer.Option("none", "--freq-dep", help="none | power:M | power:m,n,p | poly:R (as identify)"),
        spin: float = typer.Option(..., "--spin", help="Journal spin speed, rpm."),
        ratios: Optional[str] = typer.Option(
            None, "--ratios", help="Candidate orbit ratios |Omega|/omega, e.g. 0.2,0.5,1.2 (both directions)."
        ),
        matrix: Optional[str] = typer.Option(
            None,
            "--matrix",
            help="Take the candidate list, directions and smallest orbit radius from this matrix (NAME in config/matrices or FILE).",
        ),
        noise_from: Optional[Path] = typer.Option(
            None, "--noise-from", help="Run directory: per-revolution noise (and prior coefficients) measured there."
        ),
        lms: LoadSystem = typer.Option(
            LoadSystem.PIEZO, "--lms", help="Load measuring system whose noise counts: piezo | strain."
        ),
        force_noise: Optional[float] = typer.Option(
            None, "--force-noise", help="Per-revolution force phasor noise, N (default 20)."
        ),
        probe_noise: Optional[float] = typer.Option(
            None, "--probe-noise", help="Per-revolution displacement phasor noise, nm (default 100)."
        ),
        radius: Optional[float] = typer.Option(
            None, "--radius", help="Orbit radius, um (default: the matrix's smallest, else 0.1 x clearance)."
        ),
        revolutions: Optional[int] = typer.Option(
            None, "--revolutions", help="Revolutions averaged per block (default: rig.toml [averaging])."
        ),
        target: Optional[float] = typer.Option(
            None,
            "--target",
            help="Worst relative standard error to reach, percent: propose ratios and revolutions per ratio that reach it in the least rig time.",
        ),
        match: bool = typer.Option(
            False,
            "--match",
            help="Propose revolutions per ratio that give every coefficient at most the candidate's standard error in the least rig time.",
        ),
        keep_test: bool = typer.Option(
            True,
            "--model-test/--no-model-test",
            help="With --match or --target: keep the adequacy test of the richest frequency-dependent model (the matrix's, else this model's poly:1; --freq-dep if not none): enough ratios spread over the band, its errors at most the candidate's.",
        ),
        keep_away: float = typer.Option(
            0.1, "--keep-away", help="Propose no ratio closer than this to Omega/omega = 1 (runout)."
        ),
        save: Optional[str] = typer.Option(
            None,
            "--save",
            help='Write the proposal to config/designs/NAME.toml (a matrix uses it with [orbit] design = "NAME").',
        ),
        rig_path: Optional[Path] = typer.Option(None, "--config", help="Rig configuration (default config/rig.toml)."),
        as_json: bool = typer.Option(False, "--json", help="Print one JSON object."),
    ) -> None:
        """Predict the coefficients' standard errors for a list of orbit frequencies and propose a better list."""
        from orbitrig import config as cfg
        from orbitrig.cli.design_report import design_object, designs_dir, print_design, save_design
        from orbitrig.errors import OrbitrigError

        try:
            rig = cfg.load_rig(rig_path)
            cand, directions, mat_radius, source, mat_models = _candidate(ratios, matrix, rig)
            tested = [(model, freq_dep)] + mat_models if keep_test else None
            noise, run = _noise(noise_from, lms, force_noise, probe_noise)
            obj = design_object(
                rig,
                model=model,
                freq_dep=freq_dep,
                spin_rpm=spin,
                candidate=cand,
                source=source,
                directions=directions,
                radius=radius * 1e-6 if radius is not None else mat_radius,
                noise=noise,
                run=run,
                lms=lms,
                revolutions=revolutions,
                target=target,
                keep_away=keep_away,
                match=match,
                test_models=tested,
            )
            if save:
                saved = save_design(obj, save, designs_dir(rig_path))
                sys.stderr.write(f"orbitrig design: wrote {saved}\n")
        except OrbitrigError as err:
            _fail(str(err))
        if as_json:
            typer.echo(json.dumps(obj, indent=1))
        else:
            print_design(obj)
