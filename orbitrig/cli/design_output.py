"""`orbitrig design`'s result as it leaves the command: the object of orbitrig.cli.design_report
printed for a person, and its proposal saved as a design file a matrix names
(``[orbit] design = "NAME"``, config/designs/NAME.toml)."""

from __future__ import annotations

from pathlib import Path

import typer

from orbitrig.cli.design_inputs import DesignInputError
from orbitrig.cli.plain_table import PlainTable, wrap
from orbitrig.config import writable_home
from orbitrig.store.durable import write_atomic
from orbitrig.store.errors import storage_error
from reduction.whirl import Directions
from rigunits import display_unit, format_duration, micrometres

DESIGNS_DIR = "designs"  # next to config/matrices: config/designs/NAME.toml
#: what the table's `rel %` is of (reduction.frequency_list.coefficient_scales): a cross term's
#: small rel % is no promise about the cross term itself
REL_NOTE = (
    "rel % = SE relative to the size of the coefficient's matrix (RMS of the prior's K, C or D "
    "diagonal), not to the coefficient itself: a small cross term's rel % is of its diagonal"
)


def _revolutions_text(lst: dict) -> str:
    n = lst["revolutions"]
    if not isinstance(n, list):
        return f"{n} revolutions"
    text = "revolutions " + ", ".join(map(str, n))
    return text + (
        " (adaptive targets " + ", ".join(f"{t:.3g}" for t in lst["target_pct"]) + " %)"
        if lst.get("target_pct")
        else ""
    )


def _ratios_text(lst: dict, per_direction: bool) -> str:
    """'0.2, 0.5', or each ratio with its directions '0.15 forward, 0.35 backward, 0.5 both'."""
    if not per_direction:
        return ", ".join(f"{r:g}" for r in lst["ratios"])
    return ", ".join(f"{r:g} {w}" for r, w in zip(lst["ratios"], lst["whirl"]))


def print_design(obj: dict) -> None:
    """Readable form: settings, the two lists, one line per coefficient (folded, and the table
    split, to the terminal's width, 80 columns when piped: orbitrig.cli.plain_table)."""
    c, p = obj["candidate"], obj["proposal"]

    def echo(line: str) -> None:
        typer.echo(wrap(line))

    echo(
        f"model {obj['model']} ({obj['freq_dep']}), spin {obj['spin_rpm']:g} rpm, orbit radius "
        f"{micrometres(obj['orbit_radius_m'], '.3g')}, directions {obj['directions']}"
    )
    echo(f"noise {obj['noise']['source']}")
    echo(f"prior coefficients: {obj['prior']['source']}")
    a = obj["allowed"]
    echo(f"allowed ratios {a['ratio_min']:g} .. {a['ratio_max']:.3g}, none within {a['keep_away_from_1']:g} of 1")
    for label, lst in (("candidate", c), ("proposal ", p)):
        per = any(w != lst["directions"] for w in lst["whirl"])  # its ratios in directions of their own
        worst = "not identifiable" if lst["worst_relative_pct"] is None else f"worst {lst['worst_relative_pct']:.3g} %"
        ways = (
            f"{len(lst['ratios'])} blocks, each in its direction"
            if per
            else f"{len(lst['ratios'])} ratios x {lst['directions']}"
        )
        echo(
            f"{label}: {ways}, {_revolutions_text(lst)}, "
            f"rig time {format_duration(lst['rig_time_s'])}, {worst}: {_ratios_text(lst, per)}"
        )
    for w in c["warnings"]:
        echo(f"warning (candidate): {w}")
    for w in p.get("warnings", []):
        echo(f"warning (proposal): {w}")
    for w in obj.get("warnings", []):
        echo(f"warning (model): {w}")
    mt = obj.get("model_test")
    if mt:
        echo(f"model test kept: {'yes' if mt['kept'] else 'NO'}: {mt['reason']}")
    if obj["target_pct"] is not None:
        ok = p.get("reaches_target")
        echo(f"target {obj['target_pct']:g} %: " + ("reached" if ok else "not reachable on this grid"))
    typer.echo("")
    typer.echo(_coefficient_table(obj).text())
    echo(REL_NOTE)


def _coefficient_table(obj: dict) -> PlainTable:
    """One row per coefficient: unit, prior, each list's standard error and relative one ('-'
    where the list cannot identify the model), in the unit a person reads (rigunits.display_unit:
    MN/m, kN s/m, kg, as identify and reduce; the JSON stays SI); split into column blocks on a
    narrow terminal."""
    table = PlainTable()
    for i, name in enumerate(("coefficient", "unit", "prior", "candidate SE", "rel %", "proposal SE", "rel %")):
        table.add_column(name, justify="left" if i < 2 else "right")
    for name in obj["coefficients"]:
        unit, scale = display_unit(name)
        cells = [name, unit, f"{obj['prior']['coefficients'][name] * scale:.4g}"]
        for lst in (obj["candidate"], obj["proposal"]):
            if lst["std_errors"] is None:
                cells += ["-", "-"]
            else:
                cells += [f"{lst['std_errors'][name] * scale:.4g}", f"{lst['relative_pct'][name]:.3g}"]
        table.add_row(*cells)
    return table


def designs_dir(rig_path: Path | None = None) -> Path:
    """designs/ of the lab folder (orbitrig.config.writable_home: a ConfigError in the shipped
    defaults, which are never written to)."""
    return writable_home(rig_path) / DESIGNS_DIR


def save_design(obj: dict, name: str, folder: Path | None = None) -> Path:
    """Write config/designs/NAME.toml: the proposal's ratios, revolutions per ratio, adaptive
    targets per ratio (percent; with --target or --match), directions and, with
    --per-direction, each entry's direction (``whirl``; what a matrix reads
    with [orbit] design = "NAME") and, as comments, what it was designed for."""
    if not name.replace("-", "").replace("_", "").isalnum():
        raise DesignInputError(f"--save {name!r}: use letters, digits, - and _ only")
    folder = folder or designs_dir()
    p = obj["proposal"]
    goal = "" if obj["target_pct"] is None else f" --target {obj['target_pct']:g}"
    goal += " --match" if obj.get("match_candidate") else ""
    goal += " --no-model-test" if goal and obj.get("model_test") is None else ""  # a goal's list without the test
    goal += " --per-direction" if obj.get("per_direction") else ""
    n = p["revolutions"]
    per_ratio = isinstance(n, list)
    lines = [
        f"# orbitrig design --model {obj['model']} --freq-dep {obj['freq_dep']} --spin {obj['spin_rpm']:g}{goal}",
        f"# candidate: {obj['candidate']['source']}; orbit radius {micrometres(obj['orbit_radius_m'], '.3g')}",
        f"# predicted worst relative standard error {p['worst_relative_pct']:.3g} %, rig time "
        f"{p['rig_time_s']:.0f} s per operating point; noise {obj['noise']['source']}",
        f'model = "{obj["model"]}"',
        f'freq_dep = "{obj["freq_dep"]}"',
        f"spin_rpm = {obj['spin_rpm']:g}",
        "ratios = [" + ", ".join(f"{r:g}" for r in p["ratios"]) + "]",
        ("revolutions = [" + ", ".join(map(str, n)) + "]")
        if per_ratio
        else f"revolutions = [{', '.join([str(n)] * len(p['ratios']))}]",
        "directions = [" + ", ".join(f'"{w}"' for w in Directions(p["directions"]).whirls) + "]",
    ]
    if per_ratio and p.get("target_pct"):
        lines.append("target_pct = [" + ", ".join(f"{t:g}" for t in p["target_pct"]) + "]")
    if obj.get("per_direction"):  # each entry's directions: a ratio may be there once per direction
        lines.append("whirl = [" + ", ".join(f'"{w}"' for w in p["whirl"]) + "]")
    path = folder / f"{name}.toml"
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise storage_error(folder, "create the folder", err) from err
    write_atomic(path, ("\n".join(lines) + "\n").encode("utf-8"))
    return path
