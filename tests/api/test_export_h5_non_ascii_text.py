"""Text outside ASCII in the h5 export (an operator `Jürgen Ø`): docs/storage.md's reading
gives it exactly in h5py (`.asstr("utf-8")`; a bare `.asstr()` refuses it, as HDF5's ASCII
string type, which GNU Octave's load needs, says ASCII) and GNU Octave's load reads the file."""

from __future__ import annotations

import h5py
import pytest

from orbitrig.store.export import export_run
from support.octave import octave_eval
from support.report_synthetic import write_synthetic_run

OPERATOR = "Jürgen Ø"


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    run = write_synthetic_run(
        tmp_path_factory.mktemp("nonascii") / "run", incomplete=0, provenance={"operator": OPERATOR}
    )
    out = tmp_path_factory.mktemp("nonascii_export")
    export_run(run, "h5", out)
    return out / "run.h5"


def test_h5py_reads_the_text_as_documented(exported):
    with h5py.File(exported, "r") as f:
        assert f.attrs["operator"] == OPERATOR
        ds = f["attributes/operator"]
        assert ds.asstr("utf-8")[()] == OPERATOR
        with pytest.raises(UnicodeDecodeError):
            ds.asstr()[()]  # what the docs no longer suggest for text that may leave ASCII


def test_octave_loads_the_file_with_the_text(exported):
    done = octave_eval(
        f"x = load('{exported.name}'); disp(double(x.attributes.operator))", exported.parent, timeout=300
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert [int(v) for v in done.stdout.split()] == list(OPERATOR.encode("utf-8"))
