from __future__ import annotations

import sys
from pathlib import Path

# the synthetic-table helper lives next to the reduction tests
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "reduction"))
