import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "report"))  # the synthetic-run writer

from report_synthetic import write_synthetic_run  # noqa: E402


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """Two complete points (four models each, kcd12 poly:2 refused) and one incomplete, run ended."""
    return write_synthetic_run(tmp_path_factory.mktemp("store") / "run")
