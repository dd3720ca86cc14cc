"""What a run's header (run.json) says, as the run's writer (orbitrig.store.writer.RunStore)
hands it on: the run's id, its configurations, point order, simulator scenario, calibration
record and provenance. Read once (the writer's `_header`, else run.json now)."""

from __future__ import annotations

from typing import Any

from orbitrig.store.consolidate import read_header
from orbitrig.store.identity import header_identity
from orbitrig.store.layout import RunLayout
from rigunits import seconds_since


class StoredHeader:
    """The header accessors of a run's writer (a base of RunStore: its `layout` and `_header`)."""

    layout: RunLayout
    _header: dict[str, Any]

    def stored_header(self) -> dict[str, Any]:
        """run.json as the store holds it (read now when it holds none yet)."""
        return self._header or read_header(self.layout)

    @property
    def run_id(self) -> str:
        """The run's id (orbitrig.store.identity): the same in every session of a resumed run."""
        return header_identity(self.stored_header())

    def stored_configs(self) -> tuple[str, str, bool]:
        """(rig TOML text, matrix TOML text, sim) of the stored run."""
        h = self.stored_header()
        return str(h["rig_config"]), str(h["matrix_config"]), bool(h["sim"])

    def stored_point_order(self) -> list[int] | None:
        """Per point, its index in the matrix's written order, as the run started (None: a run
        written before the order was recorded: the written order)."""
        order = self.stored_header().get("point_order")
        return [int(i) for i in order] if isinstance(order, list) else None

    def stored_scenario(self) -> tuple[str, str] | None:
        """(name, TOML text) of the stored run's simulator scenario; None when the run did not
        record one (a rig run, or a run written before scenarios were recorded)."""
        sc = self.stored_header().get("sim_scenario")
        return (str(sc.get("name", "")), str(sc.get("text", ""))) if isinstance(sc, dict) else None

    def stored_record(self) -> str | None:
        """The TOML text of the calibration record the stored run was made with (None: none)."""
        text = self.stored_header().get("calibration_record_text")
        return str(text) if text else None

    def stored_provenance(self) -> dict[str, Any]:
        """The provenance recorded when the run started ({}: a run written before it was)."""
        prov = self.stored_header().get("provenance")
        return dict(prov) if isinstance(prov, dict) else {}

    def run_seconds(self) -> float:
        """Seconds since the run started (its provenance's start, else its creation; 0 when it
        records neither): the t of a row of the run's logs the store writes itself."""
        h = self.stored_header()
        started = self.stored_provenance().get("started") or h.get("created", "")
        age = seconds_since(str(started))
        return max(age, 0.0) if age is not None else 0.0
