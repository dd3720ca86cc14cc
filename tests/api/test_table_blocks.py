"""Each orbit-table row names the block it was measured in (`block`, as the waveforms' block
coordinate names it): the table's rows run forward, backward per ratio while the waveforms'
blocks sort by name, so pairing them by position paired a forward row with a backward block."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

import orbitrig


@pytest.fixture(scope="module")
def run(sim_run):
    return orbitrig.open_run(sim_run)


@pytest.mark.parametrize("lms", ["piezo", "strain"])
def test_each_row_names_its_block_and_that_block_holds_the_rows_phasors(run, sim_run, lms):
    table, waves = run.table(0, lms), run.waveforms(0)
    assert table.attrs["units"]["block"] == ""  # text
    assert sorted(table["block"]) == sorted(waves["block"].values)  # every block once
    assert list(table["block"]) != list(waves["block"].values)  # the orders differ: position pairs wrongly
    with h5py.File(sim_run / "run.h5", "r") as f:
        for _, row in table.iterrows():
            block = f[f"points/0000/frequencies/{row['block']}"]
            assert block.attrs["direction"] == row["direction"]
            assert block.attrs["measured_orbit_speed"] / (2 * np.pi) == pytest.approx(row["orbit_hz"], rel=1e-12)
            assert block.attrs["n_records"] == row["n_records"]
            phasor = waves["phasor"].sel(block=row["block"], channel=f"fx_{lms}").item()
            assert phasor == pytest.approx(row["fx_re"] + 1j * row["fx_im"], rel=1e-12)  # no force correction stated


def test_identify_table_ignores_the_block_column(run):
    table = run.table(0, "piezo")
    fit = orbitrig.identify_table(table, model="kcd11")
    stored = run.fit(0, "piezo", "kcd11").coefficients
    np.testing.assert_allclose(fit.coefficients["value"], stored["value"], rtol=1e-9)
