"""docs/api.md's Python snippets run as written, in order, on a simulated run found where the
first one opens it (`runs/demo`), and so do the expressions its tables show, so the page stays
true to the API."""

from __future__ import annotations

import re

import numpy as np
import pytest

from support.paths import ROOT


#: the expressions the page's tables show in code spans, run as written on the snippets' names
INLINE = ('coef[coef.not_determined != ""]', "waveforms(p).sel(block=row.block)")


def _snippets() -> list[str]:
    return re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "api.md").read_text(), re.S)


def test_every_snippet_runs_verbatim(sim_run, tmp_path, monkeypatch):
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "demo").symlink_to(sim_run)
    monkeypatch.chdir(tmp_path)
    snippets = _snippets()
    assert len(snippets) >= 2
    names: dict[str, object] = {}
    for i, code in enumerate(snippets):
        exec(compile(code, f"docs/api.md, python snippet {i + 1}", "exec"), names)
    assert names["fit"].coefficients.loc["Kxx", "unit"] == "N/m"
    assert str(names["kxx"].units) == "meganewton / meter"
    # pint's Hz is 1/s and rad is 1: the page converts orbit_hz as turn/s, which gives Omega = 2 pi f
    # (the table's Omega/omega is the design's 0.3 ... 1.2), where Hz would be off by 2 pi
    table, ureg = names["table"], names["ureg"]
    np.testing.assert_allclose(names["orbit"].magnitude, 2 * np.pi * table["orbit_hz"], rtol=1e-15)
    np.testing.assert_allclose(sorted(set(np.round(names["ratio"].magnitude, 3))), [0.3, 0.5, 0.7, 0.9, 1.2])
    assert ureg.Quantity(5.0, "Hz").to("rad/s").magnitude == 5.0  # what the page warns of
    assert abs(ureg.Quantity(1000.0, "rpm").to("Hz").magnitude - 104.72) < 0.01

    # the tables' expressions: the fits with a coefficient whose U exceeds its magnitude ...
    page = (ROOT / "docs" / "api.md").read_text()
    assert all(f"`{e}`" in page for e in INLINE), "docs/api.md no longer shows one of INLINE: update it"
    run = names["run"]
    names.update(coef=run.coefficients, waveforms=run.waveforms, p=0, row=table.iloc[-1])
    undetermined, block = (eval(e, names) for e in INLINE)
    coef = names["coef"]
    keys = [c.removesuffix("_U") for c in coef.columns if c.endswith("_U")]
    over = (coef[[f"{k}_U" for k in keys]].to_numpy() > abs(coef[keys].to_numpy())).any(axis=1)
    assert len(undetermined) and list(undetermined.index) == list(coef.index[over])
    # ... and the block a table row was measured in, paired by name: its direction and force phasor
    row = names["row"]
    assert (block["block"].item(), int(block["direction"])) == (row.block, row.direction)
    assert block["phasor"].sel(channel="fx_piezo").item() == pytest.approx(row.fx_re + 1j * row.fx_im, rel=1e-12)
