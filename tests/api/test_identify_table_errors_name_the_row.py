"""`orbitrig.identify_table(df)` refuses a bad table naming the DataFrame's row (its position
and index label) and column: it named a line of a CSV the user never saw (`<DataFrame>, line 5`
for the row at position 3, whatever its index label) and called a NaN `''`."""

from __future__ import annotations

import numpy as np
import pytest

import orbitrig
from orbitrig.errors import TableError


@pytest.fixture(scope="module")
def table(sim_run):
    return orbitrig.open_run(sim_run).table(0, "piezo")


def test_a_bad_cell_names_row_position_index_label_and_column(table):
    df = table.copy()
    df.index = range(10, 10 + len(df))  # a filtered or re-indexed table: labels are not positions
    df.loc[13, "orbit_hz"] = -1.0
    with pytest.raises(TableError) as caught:
        orbitrig.identify_table(df)
    err = caught.value
    assert str(err) == "<DataFrame>, row 3 (index 13), column 'orbit_hz': orbit frequency must be > 0 Hz, got -1"
    assert (err.line, err.column) == (None, "orbit_hz")


def test_nan_is_named_nan(table):
    df = table.copy()
    df.loc[2, "fx_re"] = np.nan
    with pytest.raises(TableError, match=r"^<DataFrame>, row 2 \(index 2\), column 'fx_re': not a number: NaN$"):
        orbitrig.identify_table(df)


def test_a_missing_column_names_the_column_not_a_header_line(table):
    with pytest.raises(TableError) as caught:
        orbitrig.identify_table(table.drop(columns=["fy_im"]))
    assert str(caught.value) == "<DataFrame>, column 'fy_im': required column missing from the columns"


def test_what_is_no_table_is_named_and_a_mapping_of_columns_is_taken(table):
    """An ndarray (no column names) or one row (a Series) raised AttributeError ('no attribute
    to_csv') or claimed a column was missing; a dict of columns is a table."""
    for given, name in ((table.to_numpy(), "numpy.ndarray"), (table.iloc[0], "pandas.Series")):
        with pytest.raises(TypeError, match=f"^identify_table takes a pandas DataFrame .*, not {name}$"):
            orbitrig.identify_table(given)
    by_dict = orbitrig.identify_table(table.to_dict("list"), model="kc8")
    assert by_dict.coefficients.equals(orbitrig.identify_table(table, model="kc8").coefficients)
