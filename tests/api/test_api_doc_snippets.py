"""docs/api.md's Python snippets run as written, in order, on a simulated run found where the
first one opens it (`runs/demo`), so the page stays true to the API."""

from __future__ import annotations

import re

from support.paths import ROOT


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
