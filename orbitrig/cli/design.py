"""`orbitrig design`: predicted standard errors of a list of orbit frequencies, and a better list.

The prediction is the Cramer-Rao bound of the model's coefficients for circular orbits of
one radius in the stated directions at the stated spin (reduction.frequency_list). Noise and
prior coefficients: orbitrig.cli.design_inputs. Exit 2 with a message on operator mistakes.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path
from typing import NoReturn, Optional

import typer

from orbitrig.cli import design_options as opt
from orbitrig.load_systems import LoadSystem
from reduction.whirl import Directions
from rigunits import UM


def _fail(message: str) -> NoReturn:
    from orbitrig.cli.failure import fail

    fail(message)


def _ratio_list(text: str) -> list[float]:
    try:
        values = [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        _fail(f"--ratios {text!r}: give numbers separated by commas, e.g. 0.2,0.5,1.2")
    if not values or any(not 0 < v < math.inf for v in values) or len(set(values)) != len(values):
        _fail(f"--ratios {text!r}: give distinct finite ratios > 0")
    return values


def _candidate(
    ratios: Optional[str], matrix: Optional[str], rig, rig_path: Path | None = None
) -> tuple[list[float], Directions, float | None, str, list, list[Directions] | None]:
    """(ratios, directions, orbit radius m or None, where from, the matrix's (model, freq_dep) pairs,
    each ratio's directions when the matrix's [orbit] gives them ('whirl'; the ratios ascending, a
    ratio there once per entry), else None); a matrix by name from the matrices/ beside
    ``rig_path`` (as `sweep --config`), else shipped."""
    from orbitrig import config as cfg

    if ratios and matrix:
        _fail("give --ratios or --matrix, not both")
    if ratios:
        return _ratio_list(ratios), Directions.BOTH, None, "--ratios", [], None
    if matrix:
        mat = cfg.load_matrix(cfg.matrix_file(matrix, rig_path=rig_path))
        radius = min(mat.operating.dynamic_eccentricity) * rig.bearing.clearance
        return (
            list(mat.orbit.ratio_list),
            Directions.of(mat.orbit.directions),
            radius,
            f"matrix {mat.name}",
            [(m.model, m.freq_dep) for m in mat.models],
            mat.orbit.whirl_list if mat.orbit.per_direction else None,
        )
    return (
        [round(0.2 + k / 9, 6) for k in range(10)],
        Directions.BOTH,
        None,
        "the paper's list (0.2 to 1.2, 10 ratios)",
        [],
        None,
    )


def _noise(noise_from: Optional[Path], lms: LoadSystem, force: Optional[float], probe_nm: Optional[float]):
    from orbitrig.cli import design_inputs as di

    for option, value, unit in (("--force-noise", force, "N"), ("--probe-noise", probe_nm, "nm")):
        if value is not None and not 0 < value < math.inf:
            _fail(f"{option} {value:g}: a per-revolution noise in {unit}, finite and > 0")
    probe = di.DEFAULT_PROBE_NOISE if probe_nm is None else probe_nm * 1e-9
    if noise_from is None:
        return di.stated_noise(di.DEFAULT_FORCE_NOISE if force is None else force, probe), None
    from orbitrig import open_run

    run = open_run(noise_from).run
    return di.run_noise(run, lms, probe), run


def _design_and_save(rig, request, save: Optional[str], rig_path: Path | None) -> dict:
    """design_report.design_object, written to designs/SAVE.toml when ``save`` names one."""
    from orbitrig.cli import design_output as output, design_report as report

    folder = None if save is None else output.designs_dir(rig_path)  # shipped: refused first
    obj = report.design_object(rig, request)
    if save is not None and folder is not None:
        saved = output.save_design(obj, save, folder)
        sys.stderr.write(f"orbitrig design: wrote {saved}\n")
    return obj


def register(app: typer.Typer) -> None:
    @app.command("design")
    def design_cmd(
        model: opt.Model,
        spin: opt.Spin,
        freq_dep: opt.FreqDep = "none",
        ratios: opt.Ratios = None,
        matrix: opt.Matrix = None,
        noise_from: opt.NoiseFrom = None,
        lms: opt.Lms = LoadSystem.PIEZO,
        force_noise: opt.ForceNoise = None,
        probe_noise: opt.ProbeNoise = None,
        radius: opt.Radius = None,
        revolutions: opt.Revolutions = None,
        target: opt.Target = None,
        match: opt.Match = False,
        keep_test: opt.KeepTest = True,
        per_direction: opt.PerDirection = False,
        keep_away: opt.KeepAway = 0.1,
        save: opt.Save = None,
        rig_path: opt.RigPath = None,
        as_json: opt.AsJson = False,
    ) -> None:
        """Predict the coefficients' standard errors for a list of orbit frequencies and propose a better list."""
        from orbitrig import config as cfg
        from orbitrig.cli import design_output as output, design_report as report
        from orbitrig.errors import OrbitrigError

        try:
            rig = cfg.load_rig(rig_path)
            cand, directions, mat_radius, source, mat_models, whirl = _candidate(ratios, matrix, rig, rig_path)
            tested = [(model, freq_dep)] + mat_models if keep_test else None
            noise, run = _noise(noise_from, lms, force_noise, probe_noise)
            request = report.DesignRequest(
                model=model,
                freq_dep=freq_dep,
                spin_rpm=spin,
                candidate=cand,
                candidate_whirl=whirl,
                source=source,
                directions=directions,
                radius=radius * UM if radius is not None else mat_radius,
                noise=noise,
                run=run,
                lms=lms,
                revolutions=revolutions,
                target=target,
                keep_away=keep_away,
                match=match,
                test_models=tested,
                per_direction=per_direction,
            )
            obj = _design_and_save(rig, request, save, rig_path)
        except OrbitrigError as err:
            _fail(str(err))
        typer.echo(json.dumps(obj, indent=1)) if as_json else output.print_design(obj)  # last: orbitrig.cli.boundary
