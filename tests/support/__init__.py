"""Helpers shared by the tests (and by the benches in bench/): real parts to run against (a
broker, the simulator, the command line, a PostgreSQL server, a browser) and synthetic runs
and tables with known answers. pytest puts tests/ on the path (`pythonpath` in pyproject.toml),
so a test imports `support.mqtt_helpers`; a bench, run from the repository root as
`python3 -m bench.NAME`, imports `tests.support...`. Modules here import each other relatively."""
