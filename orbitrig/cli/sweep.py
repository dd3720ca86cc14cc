"""`orbitrig sweep`: run a test matrix on the rig or on the built-in simulator.

Exit status: 0 completed, 1 failed, 2 bad configuration or usage, 3 stopped,
4 aborted.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

DEFAULT_SIM_SPEEDUP = 40.0
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
            DEFAULT_SIM_SPEEDUP, "--speedup", min=0.01, help="simulator time / wall time (--sim only)"
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
        from orbitrig.errors import ConfigError, OrbitrigError

        if run_dir is not None and out is not None and run_dir != out:
            raise typer.BadParameter(f"two run directories: {run_dir} and --out {out}", param_hint="DIR")
        out = out or run_dir
        if sim_config is not None and not sim:
            raise typer.BadParameter("--sim-config needs --sim", param_hint="--sim-config")
        try:
            rig, mat = _load(config, matrix, sim=sim, resume=resume, out=out, dry_run=dry_run)
            if dry_run:
                from orbitrig.cli.dry_run import print_plan

                print_plan(rig, mat)
                return
            if out is None:
                raise typer.BadParameter("--out DIR is required (except with --dry-run)", param_hint="--out")
            if not sim:
                _check_rig_answers(rig)
            if not resume:
                _check_out(out)
            import asyncio

            sim_cfg = _sim_config(sim_config) if sim else None
            outcome = asyncio.run(_sweep(rig, mat, out=out, sim=sim_cfg, resume=resume, speedup=speedup))
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
    mat = cfg.load_matrix(cfg.matrix_file(matrix) if matrix else None)
    cfg.check_matrix_against_rig(mat, rig)  # before the simulator or any drive is started
    return rig, mat


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


async def _sweep(rig, mat, *, out: Path, sim, resume: bool, speedup: float):
    """Run the matrix; ``sim`` the simulator's SimConfig (None: the real rig)."""
    import contextlib

    from rich.console import Console

    from orbitrig.run.engine import RunEngine
    from orbitrig.cli.progress import SweepProgress

    console = Console(stderr=True)
    async with contextlib.AsyncExitStack() as stack:
        sim_rig = None
        if sim is not None:
            from sim.rig import SimRig

            sim_rig = await stack.enter_async_context(SimRig(sim, speedup=speedup, adc_pty=False))
        engine = RunEngine(rig, out_dir=out, sim=sim_rig, confirm_mode="auto" if sim_rig is not None else "prompt")
        operator = _Operator(engine, console)
        engine.subscribe(operator.on_event)
        with SweepProgress(console, revolutions=mat.revolutions or rig.averaging.revolutions) as bars:
            engine.subscribe(bars)
            operator.install()
            try:
                outcome = await engine.run(mat, resume=resume)
            finally:
                operator.uninstall()
    console.print(f"run {outcome.status}: {outcome.message}  ({len(outcome.completed_points)} of "
                  f"{outcome.points} points complete in {out})", markup=False)  # fmt: skip
    if outcome.completed_points:
        print_coefficients(out)
    return outcome


class _Operator:
    """Terminal side of the engine: answers confirmations, Ctrl-C pauses and asks, twice aborts."""

    def __init__(self, engine, console):
        import asyncio

        self.engine, self.console = engine, console
        self.loop = asyncio.get_running_loop()
        self.interrupts = 0
        self.lines: asyncio.Queue[str | None] = asyncio.Queue()
        self.reader = None
        self.asking = None
        self.eof = False  # standard input closed: nobody can answer, so the run stops

    def install(self) -> None:
        import signal

        self.loop.add_signal_handler(signal.SIGINT, self._sigint)

    def uninstall(self) -> None:
        import signal

        self.loop.remove_signal_handler(signal.SIGINT)
        if self.asking is not None:
            self.asking.cancel()

    def _start_reader(self) -> None:
        import sys
        import threading

        if self.reader is not None:
            return

        def read():  # a daemon thread: a pending input() never holds the exit
            for line in sys.stdin:
                self.loop.call_soon_threadsafe(self.lines.put_nowait, line.strip())
            self.loop.call_soon_threadsafe(self.lines.put_nowait, None)

        self.reader = threading.Thread(target=read, name="operator-stdin", daemon=True)
        self.reader.start()

    def _sigint(self) -> None:
        self.interrupts += 1
        if self.interrupts >= 2:
            self.console.print("second Ctrl-C: aborting (emergency ramp down)", style="bold red")
            self.engine.request_abort()
            return
        self.engine.request_pause()
        self._ask("paused at the next safe point: [r]esume, [s]top, [a]bort? (Ctrl-C again aborts) ", self._choice)

    def on_event(self, ev) -> None:
        from orbitrig.run.engine import StatusEvent

        if isinstance(ev, StatusEvent) and ev.state == "waiting" and self.engine.waiting_step:
            step = self.engine.waiting_step
            self._ask(f"{ev.message}\npress Enter to confirm {step} (or type stop / abort): ",
                      lambda ans: self._confirm(step, ans))  # fmt: skip

    def _ask(self, prompt: str, handle) -> None:
        import asyncio

        if self.asking is not None:
            self.asking.cancel()
        self._start_reader()
        self.console.print(prompt, style="bold yellow", markup=False)  # a whole line: the live bars redraw over a partial one
        if self.eof:
            self._no_operator()
            return

        async def ask():
            line = await self.lines.get()
            if line is None:
                self.eof = True
                self._no_operator()
            else:
                handle(line)

        self.asking = asyncio.ensure_future(ask())

    def _no_operator(self) -> None:
        self.console.print("\nstandard input is closed, nobody can answer: stopping the run "
                           "(continue later with --resume)", style="bold red", markup=False)  # fmt: skip
        self.engine.request_stop()

    def _choice(self, ans: str) -> None:
        a = ans.lower()[:1]
        if a == "s":
            self.engine.request_stop()
        elif a == "a":
            self.engine.request_abort()
        else:
            self.interrupts = 0
            self.engine.request_resume()

    def _confirm(self, step: str, ans: str) -> None:
        a = ans.lower()
        if a.startswith("abort"):
            self.engine.request_abort()
        elif a.startswith("stop"):
            self.engine.request_stop()
        else:
            try:
                self.engine.confirm(step)
            except Exception as err:  # noqa: BLE001 - tell the operator, keep going
                self.console.print(f"not confirmed: {err}", markup=False)


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
