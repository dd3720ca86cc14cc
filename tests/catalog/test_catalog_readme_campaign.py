"""The README's catalog-and-compare block and docs/catalog.md's compare and ROSS examples run as
written on real sweep output: two `sweep --sim --matrix eccentricity` runs, `catalog add`,
`list`, `export` and `compare` with the shipped predictions (examples/predicted/sim-bearing.csv),
which are the simulator's own bearing at each static eccentricity; then the ROSS hand-off."""

from __future__ import annotations

import csv
import re
import shlex
import subprocess
import sys
import tomllib

import pytest

import orbitrig
from orbitrig.catalog.compare import repeatability
from orbitrig.catalog.store import Catalog
from support.paths import ROOT


def _block_after(path, heading: str) -> list[str]:
    """The shell commands of the first fenced block after ``heading`` (continuations joined,
    comments dropped)."""
    text = path.read_text()
    block = re.search(r"```\w*\n(.*?)```", text[text.index(heading) :], re.S)
    assert block, f"{path.name}: no block after {heading!r}"
    joined = block.group(1).replace("\\\n", " ")
    return [re.sub(r"\s+#.*$", "", line).strip() for line in joined.splitlines() if line.strip()]


def _run(command: str, cwd) -> subprocess.CompletedProcess:
    words = shlex.split(command)
    assert words[0] == "orbitrig", command
    line = " ".join([shlex.quote(sys.executable), "-m", "orbitrig", *map(shlex.quote, words[1:])])
    line = line.replace("'runs/*/'", "runs/*/")  # the README's glob, for the shell
    return subprocess.run(
        ["bash", "-c", line], cwd=cwd, capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL
    )


def _predicted() -> dict[float, dict[str, float]]:
    with (ROOT / "examples" / "predicted" / "sim-bearing.csv").open() as f:
        rows = csv.DictReader(line for line in f if not line.startswith("#"))
        return {float(r["static_eccentricity"]): {k.split()[0]: float(v) for k, v in r.items()} for r in rows}


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """(folder, {"catalog add": process, ...}): the README's block run there, in order."""
    tmp_path = tmp_path_factory.mktemp("campaign")
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    readme = _block_after(ROOT / "README.md", "### catalog and compare")
    assert readme[0].startswith("pip install") and len(readme) == 7
    out = {}
    for command in readme[1:]:
        p = _run(command, tmp_path)
        assert p.returncode == 0, f"{command}: {p.stdout[-2000:]}\n{p.stderr[-2000:]}"
        out[command.split()[1] + " " + command.split()[2]] = p
    return tmp_path, out


def test_readme_campaign_runs_as_written(campaign):
    tmp_path, out = campaign
    assert out["catalog add"].stdout.split("\n")[:2] == ["runs/ecc-1: 12 rows", "runs/ecc-2: 12 rows"]
    listed = out["catalog list"].stdout.splitlines()
    header = listed[0].split()
    eps = [float(line.split()[header.index("static_eccentricity")]) for line in listed[1:]]
    assert sorted(eps) == [0.15] * 4 + [0.3] * 4  # two runs x kc8, kcd11 x the two points above 0.1
    assert all(line.split()[header.index("lms")] == "piezo" for line in listed[1:])
    with (tmp_path / "campaign.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 24
    compare = out["compare --runs"]
    assert compare.stdout.split() == ["figures/compare.png", "figures/compare.pdf"]
    assert "none drawn" not in compare.stderr  # the predictions' conditions are the runs'
    assert (tmp_path / "figures" / "compare.png").read_bytes()[:4] == b"\x89PNG"

    docs = _block_after(ROOT / "docs" / "catalog.md", "## `orbitrig compare`")
    assert len(docs) == 1
    p = _run(docs[0], tmp_path)
    assert p.returncode == 0 and "none drawn" not in p.stderr, p.stderr

    # the repeat: at each static eccentricity the two runs form a group
    rows = Catalog(f"sqlite:///{tmp_path / 'runs' / 'catalog.sqlite'}", create=False).rows(
        "matrix_name = eccentricity and lms = piezo and model = kcd11 and freq_dep = none"
    )
    rep = repeatability(rows, "Kxx")
    assert (rep.groups, rep.dof) == (3, 3)

    # the shipped predictions are the simulator's truth at these points, and the runs find them
    predicted = _predicted()
    for run_dir in ("ecc-1", "ecc-2"):
        run = orbitrig.open_run(tmp_path / "runs" / run_dir)
        fit = {(r.point, r.lms, r.model): r for r in run.coefficients.itertuples()}
        for point, eps_s in run.points["static_eccentricity"].items():
            truth, pred = run.truth(point), predicted[round(eps_s, 2)]
            assert pred["Kxx"] == pytest.approx(truth["K0"][0][0], rel=1e-5)
            assert pred["Cyy"] == pytest.approx(truth["C0"][1][1], rel=1e-5)
            assert pred["Dxx"] == pytest.approx(truth["D0"][0][0], rel=1e-5)
            measured = fit[(point, "piezo", "kcd11")]
            for name in ("Kxx", "Kyy", "Cxx", "Cyy"):
                assert abs(getattr(measured, name) - pred[name]) < 2 * getattr(measured, f"{name}_U"), (point, name)


def test_ross_example_runs_as_written_on_a_campaign_run(campaign, monkeypatch):
    """docs/catalog.md's ROSS snippet, on a run of the campaign in the place it names."""
    tmp_path, _ = campaign
    (tmp_path / "runs" / "demo").symlink_to(tmp_path / "runs" / "ecc-1")
    p = _run("orbitrig export runs/demo --format ross", tmp_path)
    assert p.returncode == 0, p.stderr
    snippets = re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "catalog.md").read_text(), re.S)
    assert len(snippets) == 1
    monkeypatch.chdir(tmp_path)
    names: dict[str, object] = {}
    with pytest.warns(UserWarning, match="not determined"):  # the apparent masses' U exceed them (stderr says so)
        exec(compile(snippets[0].replace("print(", "_ = ("), "docs/catalog.md, python snippet", "exec"), names)
    rotor = names["rotor"]
    bearing = rotor.bearing_elements[0]
    run = orbitrig.open_run(tmp_path / "runs" / "ecc-1")
    assert bearing.kxx_interpolated(100.0) == pytest.approx(
        run.fit(0, "piezo", "kcd11").coefficients.loc["Kxx", "value"]
    )
    recorded = tomllib.loads(run.run.rig_config)["bearing"]  # the journal the run records
    assert names["d"] == pytest.approx(2e-3 * recorded["radius_mm"], rel=1e-12)
    log_dec = names["_"][:6]
    assert all(abs(x) < 1e3 for x in log_dec) and max(log_dec) > 0
