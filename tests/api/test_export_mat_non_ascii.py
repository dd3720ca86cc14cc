"""run.mat keeps text outside ASCII exactly: scipy.io.loadmat (and MATLAB) read the char
fields as they are; GNU Octave reads a char field by bytes and cuts it, so every text with a
character outside ASCII also has ``<name>_utf8``, its UTF-8 bytes (uint8), which real
octave-cli turns back into the exact text with ``char(...)``."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.io import loadmat

from orbitrig.store.export import export_run
from orbitrig.store.export_mat import add_utf8, cell
from support.octave import octave_eval

OPERATOR = "Lager ø50 – Prüfstand"
CHANNELS = ["Weg ø1", "Weg ø2", "ascii"]  # a cell of texts, two of one length
RIG_ID = "Prüfstand Nr. 2 — Ω-Lager 𝄞"  # a character outside the BMP too
RECORD = '# Kalibrierung für Lager ø50 – Prüfstand\n[runout]\nspin_rpm = 1000.0\nnote = "µm, ±0.5"\n'


@pytest.fixture(scope="module")
def mat(tmp_path_factory):
    from support.report_synthetic import write_synthetic_run

    run = write_synthetic_run(
        tmp_path_factory.mktemp("non_ascii") / "run",
        n_points=1,
        incomplete=0,
        provenance={"operator": OPERATOR, "rig_id": RIG_ID},
        record_text=RECORD,
    )
    (path,) = export_run(run, "mat", run / "export").files
    return path


def test_scipy_reads_the_text_and_its_utf8_bytes(mat):
    m = loadmat(mat, simplify_cells=True)
    texts = {"operator": OPERATOR, "rig_id": RIG_ID, "calibration_record_text": RECORD}
    for name, text in texts.items():
        assert m["run"][name] == text
        utf8 = m["run"][f"{name}_utf8"]
        assert utf8.dtype == np.uint8 and bytes(utf8).decode("utf-8") == text
    assert "host_utf8" not in m["run"] and "software_version_utf8" not in m["run"]  # ASCII: no sibling
    assert "_utf8" in m["unit_rules"]["text"]


def test_a_cell_of_texts_gets_a_cell_of_utf8_rows(tmp_path):
    from scipy.io import savemat

    savemat(tmp_path / "c.mat", add_utf8({"s": {"channels": cell(CHANNELS)}}))
    m = loadmat(tmp_path / "c.mat", simplify_cells=True)
    assert list(m["s"]["channels"]) == CHANNELS
    assert [bytes(b).decode("utf-8") for b in m["s"]["channels_utf8"]] == CHANNELS
    done = octave_eval("m = load('c.mat'); disp(char(m.s.channels_utf8{2}))", tmp_path, text=False)
    assert done.stdout.decode("utf-8").splitlines()[0] == CHANNELS[1], done.stderr.decode()[-2000:]


def test_octave_reads_the_exact_text(mat, tmp_path):
    script = (
        f"m = load('{mat}');\n"
        "names = {'operator', 'rig_id', 'calibration_record_text'};\n"
        "for i = 1:numel(names)\n"
        "  t = char(m.run.([names{i} '_utf8']));\n"
        "  printf('%s=%s\\n', names{i}, sprintf('%02x', double(t)));\n"
        "end\n"
        "printf('rule=%s\\n', m.unit_rules.text);\n"
    )
    done = octave_eval(script, tmp_path, text=False)
    out = done.stdout.decode("utf-8")
    rows = dict(line.split("=", 1) for line in out.splitlines() if "=" in line)
    assert set(rows) >= {"operator", "rig_id", "calibration_record_text"}, out + done.stderr.decode()[-2000:]
    assert bytes.fromhex(rows["operator"]).decode("utf-8") == OPERATOR
    assert bytes.fromhex(rows["rig_id"]).decode("utf-8") == RIG_ID
    assert bytes.fromhex(rows["calibration_record_text"]).decode("utf-8") == RECORD
    assert "_utf8" in rows["rule"]
