"""`orbitrig sweep`: run a test matrix on the rig or on the built-in simulator.

Exit status: 0 completed, 1 failed, 2 bad configuration or usage, 3 stopped,
4 aborted.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

DEFAULT_SPEEDUP = 40.0  # as orbitrig.cli.simulated_rig.DEFAULT_SPEEDUP (imported only with --sim)
EXIT = {"completed": 0, "failed": 1, "stopped": 3, "aborted": 4}


def register(app: typer.Typer) -> None:
    @app.command("sweep")
    def sweep(
        run_dir: Optional[Path] = typer.Argument(None, help="the run directory, as --out (`--resume DIR`)"),
        out: Optional[Path] = typer.Option(None, "--out", help="run directory (run.h5, coefficients.csv, run.log)"),
        sim: bool = typer.Option(False, "--sim", help="run on the built-in simulator over loopback protocols"),
        config: Optional[Path] = typer.Option(None, "--config", help="rig configuration TOML (default: config/rig.toml of the orbitrig source tree)"),
        matrix: Optional[str] = typer.Option(
            None, "--matrix", metavar="NAME|FILE",
            help="test matrix: a TOML file, or a name from config/matrices/ (demo, paper); "
                 "required on the rig, --sim defaults to config/matrices/demo.toml",
        ),
        resume: bool = typer.Option(False, "--resume", help="continue the run in --out from its first incomplete point"),
        dry_run: bool = typer.Option(False, "--dry-run", help="print the plan's totals, then every step with its estimated duration (s); touches no hardware"),
        speedup: float = typer.Option(
            DEFAULT_SPEEDUP, "--speedup", min=0.01, help="simulator time / wall time (--sim only)"
        ),
        sim_config: Optional[Path] = typer.Option(
            None, "--sim-config", help="simulator scenario TOML (--sim only; default config/sim.toml, the paper's rig; "
            "also config/sim/clean.toml, config/sim/compressible.toml)"
        ),
    ) -> None:
        """Run a test matrix: manual settings, speeds, settle, acquire, identify, store.

        Matrix units: speeds rpm (spin omega; orbit Omega = ratio * omega), pressures MPa, times s.

        Ctrl-C pauses at the next safe point and asks resume / stop / abort; a second Ctrl-C aborts.

        Exit 0 completed, 1 failed, 2 bad configuration or usage, 3 stopped, 4 aborted.
        """
        _sweep_command(run_dir, out, sim, config, matrix, resume, dry_run, speedup, sim_config)


def _sweep_command(run_dir, out, sim, config, matrix, resume, dry_run, speedup, sim_config) -> None:
    """`orbitrig sweep`, its options checked; raises typer.Exit with the run's exit status."""
    from orbitrig.errors import ConfigError, OrbitrigError

    if run_dir is not None and out is not None and run_dir != out:
        raise typer.BadParameter(f"two run directories: {run_dir} and --out {out}", param_hint="DIR")
    out = out or run_dir
    if sim_config is not None and not sim:
        raise typer.BadParameter("--sim-config needs --sim", param_hint="--sim-config")
    try:
        plan = _load(config, matrix, sim=sim, resume=resume, out=out, dry_run=dry_run)
        if dry_run:
            from orbitrig.cli.dry_run import print_plan

            print_plan(plan)
            return
        if out is None:
            raise typer.BadParameter("--out DIR is required (except with --dry-run)", param_hint="--out")
        if not sim:
            _check_rig_answers(plan.rig)
        if not resume:
            _check_out(out)
        import asyncio

        sim_cfg = _sim_config(sim_config) if sim else None
        outcome = asyncio.run(_sweep(plan, out=out, sim=sim_cfg, resume=resume, speedup=speedup))
    except ConfigError as err:
        typer.echo(f"error: {err}", err=True)
        raise typer.Exit(2) from None
    except OrbitrigError as err:
        typer.echo(f"error: {err}", err=True)
        raise typer.Exit(2) from None
    except OSError as err:  # a file the run needs cannot be written (disk full, permissions)
        typer.echo(f"error: {err.filename or out}: {err.strerror or err}", err=True)
        raise typer.Exit(1) from None
    raise typer.Exit(EXIT[outcome.status])


def _sim_config(path):
    """The simulator scenario (SimConfig) of --sim-config, or the default rig."""
    from sim.config import SimConfig, load_sim_config

    if path is None:
        return SimConfig()
    try:
        return load_sim_config(path)
    except ValueError as err:
        raise typer.BadParameter(str(err), param_hint="--sim-config") from None


def _load(config, matrix, *, sim: bool, resume: bool, out, dry_run: bool):
    """The plan of this sweep: matrix checked against the rig and expanded, before anything starts."""
    from orbitrig.run.plan import make_plan

    rig, mat = _configs(config, matrix, sim=sim, resume=resume, out=out, dry_run=dry_run)
    return make_plan(mat, rig)


def _configs(config, matrix, *, sim: bool, resume: bool, out, dry_run: bool):
    from orbitrig import config as cfg
    from orbitrig.errors import ConfigError

    if resume:
        if out is None:
            raise typer.BadParameter("--resume needs --out DIR (the run to continue)", param_hint="--out")
        from orbitrig.store.writer import RunStore

        store = RunStore.open_existing(out)
        rig_text, matrix_text, was_sim = store.stored_configs()
        if was_sim != sim:
            raise ConfigError(str(store.path), [f"this run was made {'on the simulator' if was_sim else 'on the rig'}: "
                                                f"resume it {'with' if was_sim else 'without'} --sim"])  # fmt: skip
        rig = cfg.load_rig(config) if config else cfg.rig_from_text(rig_text, f"{store.path}:rig_config")
        matrix = cfg.matrix_file(matrix) if matrix else None
        mat = cfg.load_matrix(matrix) if matrix else cfg.matrix_from_text(matrix_text, f"{store.path}:matrix_config")
        if matrix and mat.text != matrix_text:  # before the simulator or any drive is started
            raise ConfigError(mat.file, [f"differs from the matrix of the run being resumed in {store.path}; "
                                         "resume without --matrix (the stored one is used)"])  # fmt: skip
        return rig, mat
    rig = cfg.load_rig(config)
    if matrix is None and not sim and not dry_run:
        raise typer.BadParameter("--matrix NAME|FILE is required on the rig (--sim defaults to the demo)",
                                 param_hint="--matrix")  # fmt: skip
    return rig, cfg.load_matrix(cfg.matrix_file(matrix) if matrix else None)


def _check_out(out: Path) -> None:
    """The run directory can be created and written, before anything is started."""
    import os

    from orbitrig.errors import ConfigError

    if out.exists() and not out.is_dir():
        raise ConfigError(str(out), ["--out is a file, not a directory"])
    if (out / "run.h5").exists():
        raise ConfigError(str(out / "run.h5"), ["already exists: use --resume to continue that run, or another --out"])
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ConfigError(str(out), [f"cannot create the run directory: {err.strerror or err}"]) from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise ConfigError(str(out), ["the run directory is not writable"])


def _check_rig_answers(rig) -> None:
    """On the rig: every transport must answer before the run directory is made (exit 2 if not)."""
    import asyncio

    from orbitrig.cli.preflight import unreachable_transports

    problems = asyncio.run(unreachable_transports(rig))
    if problems:
        lines = "\n".join(f"  {p}" for p in problems)
        typer.echo(f"error: the rig does not answer ([transports] in {rig.file}):\n{lines}\n"
                   "Nothing was started and no run directory was made. On a machine without the rig, "
                   "run on the built-in simulator: orbitrig sweep --sim ...", err=True)  # fmt: skip
        raise typer.Exit(2)


async def _sweep(plan, *, out: Path, sim, resume: bool, speedup: float):
    """Run the plan; ``sim`` the simulator's SimConfig (None: the real rig)."""
    import contextlib

    from rich.console import Console

    from orbitrig.cli.operator import Operator
    from orbitrig.cli.progress import SweepProgress
    from orbitrig.run.engine import RunEngine

    console = Console(stderr=True)
    async with contextlib.AsyncExitStack() as stack:
        access = None
        if sim is not None:
            from orbitrig.cli.simulated_rig import simulated_rig

            _, access = await stack.enter_async_context(simulated_rig(speedup, sim))
        engine = RunEngine(plan.rig, out_dir=out, access=access, confirm_mode="auto" if access else "prompt")
        operator = Operator(engine, console)
        engine.subscribe(operator.on_event)
        with SweepProgress(console, revolutions=plan.revolutions) as bars:
            engine.subscribe(bars)
            operator.install()
            try:
                outcome = await engine.run(plan, resume=resume)
            finally:
                operator.uninstall()
    console.print(f"run {outcome.status}: {outcome.message}  ({len(outcome.completed_points)} of "
                  f"{outcome.points} points complete in {out})", markup=False)  # fmt: skip
    if outcome.completed_points:
        print_coefficients(out)
    return outcome


# ---------------------------------------------------------- the final table
def compare_with_truth(coefficients: dict, truth: dict) -> dict[str, float]:
    """Error of each constant-term K, C, D entry in percent of the largest true entry of its matrix."""
    out = {}
    for m in "KCD":
        true = truth.get(f"{m}0")
        if true is None:
            continue
        scale = max(abs(v) for row in true for v in row) or 1.0
        for i, a in enumerate("xy"):
            for j, b in enumerate("xy"):
                key = f"{m}{a}{b}"
                if key in coefficients:
                    out[key] = abs(coefficients[key] - true[i][j]) / scale * 100.0
    return out


_COEF_UNIT = {"K": "N/m", "C": "N s/m", "D": "kg"}


#: above this many complete points the final table is one summary row per point
DETAIL_POINTS = 4


def _fits(g) -> dict[str, dict]:
    import json

    return {key: json.loads(h.attrs["json"]) for key, h in g["identification"].items() if "json" in h.attrs}


def _print_summary(console, complete: list, out: Path) -> None:
    """One row per operating point: the main stiffness and damping entries of the first
    fit (piezo), and in --sim mode the worst K and C error of every fit."""
    import json

    from rich.table import Table

    table = Table(title=f"{len(complete)} operating points (full tables: coefficients.csv, "
                        f"orbitrig report {out})", title_justify="left")
    for col in ("point", "label", "Kxx MN/m", "Kyy MN/m", "Cxx kN s/m", "Cyy kN s/m", "worst K / C error"):
        table.add_column(col, justify="left" if col in ("point", "label") else "right")
    for name, g in complete:
        fits = _fits(g)
        truth = json.loads(g["truth"].attrs["json"]) if "truth" in g else None
        first = next((d["coefficients"] for k, d in sorted(fits.items()) if k.startswith("piezo")), None)
        row = [name, str(g.attrs["label"])]
        row += [f"{first[c] * scale:.4g}" if first and c in first else "-"
                for c, scale in (("Kxx", 1e-6), ("Kyy", 1e-6), ("Cxx", 1e-3), ("Cyy", 1e-3))]
        if truth:
            errs = [compare_with_truth(d["coefficients"], truth) for d in fits.values()]
            k = max((e[c] for e in errs for c in e if c[0] == "K"), default=float("nan"))
            c = max((e[c] for e in errs for c in e if c[0] == "C"), default=float("nan"))
            row.append(f"{k:.1f} % / {c:.1f} %")
        else:
            row.append(f"{len(fits)} fits")
        table.add_row(*row)
    console.print(table)
    if any("truth" in g for _, g in complete):
        console.print("error = |identified - true| / largest true entry of the matrix, worst over all fits",
                      markup=False)


def print_coefficients(out: Path) -> None:
    """Identified constant-term coefficients of every complete point, beside the true ones in --sim mode."""
    import json

    import h5py
    from rich.console import Console
    from rich.table import Table

    from orbitrig.store.writer import coef_order

    console = Console()
    with h5py.File(Path(out) / "run.h5", "r") as f:
        complete = [(name, g) for name, g in sorted(f["points"].items()) if g.attrs.get("complete", False)]
        if len(complete) > DETAIL_POINTS:
            _print_summary(console, complete, out)
            return
        for name, g in complete:
            truth = json.loads(g["truth"].attrs["json"]) if "truth" in g else None
            fits = _fits(g)
            names = sorted({k for d in fits.values() for k in d["coefficients"] if "_" not in k}, key=coef_order)
            table = Table(title=f"point {name}  {g.attrs['label']}", title_justify="left")
            table.add_column("coef")
            if truth:
                table.add_column("true", justify="right")
            for key in fits:
                table.add_column(key.replace("__none", "").replace("__", " "), justify="right")
            errs = {k: compare_with_truth(d["coefficients"], truth) for k, d in fits.items()} if truth else {}
            for c in names:
                row = [c]
                if truth:
                    row.append(f"{truth[c[0] + '0']['xy'.index(c[1])]['xy'.index(c[2])]:.4g}")
                for key, d in fits.items():
                    v = d["coefficients"].get(c)
                    cell = "" if v is None else f"{v:.4g}"
                    if v is not None and c in errs.get(key, {}):
                        cell += f" ({errs[key][c]:.1f}%)"
                    row.append(cell)
                table.add_row(*row)
            console.print(table)
            console.print("units: " + ", ".join(f"{m} {u}" for m, u in _COEF_UNIT.items() if any(c[0] == m for c in names)),
                          markup=False)  # fmt: skip
            if truth:
                console.print("(%) = |identified - true| / largest true entry of the matrix", markup=False)
                top = max(truth["orbit"], key=abs)
                k, d = (max(abs(v) for row in truth[m] for v in row) for m in ("K0", "D0"))
                console.print(f"D acts as Omega^2 D: at the highest orbit speed that is {100 * top**2 * d / k:.2g} % "
                              "of the largest K entry, so D is weakly determined here", markup=False)  # fmt: skip
