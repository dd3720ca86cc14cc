"""The dashboard server starts without the rig's configuration and numerics.

It needs the service's wire words (orbitrig.service.protocol) and no more: importing
numpy, scipy or orbitrig.config doubled its start-up (0.25 s -> 0.55 s) when the run
commands' Enum lived beside the run's provenance.
"""

from __future__ import annotations

import json
import subprocess
import sys

from support.paths import ROOT

HEAVY = ("numpy", "scipy", "orbitrig.config", "orbitrig.run.provenance", "orbitrig.analysis", "h5py")


def test_the_dashboard_server_imports_no_numerics_nor_rig_configuration():
    probe = (
        f"import json, sys, orbitrig.dashboard.server; print(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))"
    )
    done = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout) == []
