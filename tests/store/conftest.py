import pytest

from support.report_synthetic import write_synthetic_run
from support.small_disk import mounted_tmpfs


@pytest.fixture(scope="session")
def synthetic(tmp_path_factory):
    """Two complete points (four models each, kcd12 poly:8 refused) and one incomplete, run ended:
    one run per worker, which the tests read (a test that changes a run changes its own copy)."""
    return write_synthetic_run(tmp_path_factory.mktemp("store") / "run")


@pytest.fixture
def tiny_disk(tmp_path):
    """A 6 MB tmpfs (enough for the run, until `fill` eats the rest); unmounted afterwards."""
    with mounted_tmpfs(tmp_path / "disk", "6m") as mnt:
        yield mnt
