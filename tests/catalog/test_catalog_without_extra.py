"""`orbitrig catalog` and `compare` without the [catalog] extra (SQLAlchemy, the PostgreSQL
driver): one line naming the missing module and the extra to install, exit 2, no traceback.
The extra is absent here through a child interpreter in which importing sqlalchemy fails, as
it does where it was never installed."""

from __future__ import annotations

import os
import subprocess
import sys

from support.paths import ROOT

NO_SQLALCHEMY = (
    "import sys\n"
    "class _Absent:\n"
    "    def find_spec(self, name, path=None, target=None):\n"
    "        if name.split('.')[0] == 'sqlalchemy':\n"
    "            raise ModuleNotFoundError(f\"No module named '{name}'\", name=name)\n"
    "sys.meta_path.insert(0, _Absent())\n"
    "from orbitrig.cli import main\n"
    "sys.argv = ['orbitrig', *sys.argv[1:]]\n"
    "main()\n"
)


def _without_sqlalchemy(tmp_path, *args):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    return subprocess.run(
        [sys.executable, "-c", NO_SQLALCHEMY, *args], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=60
    )


def test_catalog_and_compare_name_the_missing_extra(tmp_path):
    for args in (("catalog", "list", "--runs", str(tmp_path)), ("compare", "--runs", str(tmp_path))):
        p = _without_sqlalchemy(tmp_path, *args)
        assert p.returncode == 2, (args, p.stderr)
        assert "Traceback" not in p.stderr
        assert p.stderr.strip().splitlines() == [
            f"orbitrig {' '.join(args[:-2])}: error: the catalog needs sqlalchemy, which is not installed: "
            "pip install -e '.[catalog]'"
            " in orbitrig's source tree (SQLAlchemy and the PostgreSQL driver)"
        ]
