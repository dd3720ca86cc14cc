from __future__ import annotations

import pytest

from report_synthetic import write_synthetic_run


@pytest.fixture(scope="session")
def synthetic_run(tmp_path_factory):
    """Two complete points and one incomplete one, known coefficients, 0.1 % force noise."""
    return write_synthetic_run(tmp_path_factory.mktemp("synthetic") / "run")


@pytest.fixture(scope="session")
def synthetic_report(tmp_path_factory):
    """`make_report` on a one-point synthetic run (plots take ~0.5 s each)."""
    from orbitrig.report import make_report

    directory = write_synthetic_run(tmp_path_factory.mktemp("synthetic_report") / "run", n_points=1)
    return make_report(directory)
