"""docs/catalog.md's ROSS example runs as written: on a simulated run in `runs/demo`, after
`orbitrig export runs/demo --format ross` (as the page says), its rotor is built from the
exported bearing and its modal analysis prints six log decrements."""

from __future__ import annotations

import contextlib
import io
import re
import warnings

import numpy as np
from typer.testing import CliRunner

from orbitrig.cli import app
from support.paths import ROOT


def test_the_ross_example_runs_verbatim(sim_run, tmp_path, monkeypatch):
    (code,) = re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "catalog.md").read_text(), re.S)
    assert 'bearing_elements("runs/demo/export/ross_bearings.json"' in code
    export = tmp_path / "runs" / "demo" / "export"  # the export of the run, beside it as `export` writes it
    res = CliRunner().invoke(app, ["export", str(sim_run), "--format", "ross", "--out", str(export)])
    assert res.exit_code == 0, res.output
    monkeypatch.chdir(tmp_path)
    printed = io.StringIO()
    with warnings.catch_warnings(), contextlib.redirect_stdout(printed):
        warnings.simplefilter("ignore")  # what the bearings' numbers warn of: tests/report/test_ross_*
        names: dict[str, object] = {}
        exec(compile(code, "docs/catalog.md, python", "exec"), names)
    last = printed.getvalue().strip().rsplit("[", 1)[-1]  # after ross' own notices: the printed array
    log_dec = np.array(last.rstrip("]").split(), dtype=float)
    assert log_dec.shape == (6,) and np.isfinite(log_dec).all(), printed.getvalue()[-500:]
    assert len(names["rotor"].bearing_elements) == 2  # type: ignore[attr-defined]  # nodes 0 and 6
