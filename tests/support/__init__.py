"""Helpers shared by the tests (and by the benches in bench/): real parts to run against (a
broker, the simulator, the command line, a PostgreSQL server, a browser) and synthetic runs
and tables with known answers. pytest puts tests/ on the path (`pythonpath` in pyproject.toml),
so a test imports `support.mqtt_helpers`; a bench run as a script imports `tests.support...`
from the repository root. Modules here import each other relatively."""
