"""The pint unit registry the tests parse units with (pint: an independent reader of the units the
files and messages state). One per process: building a registry takes about half a second, and
no test changes it (no definitions added)."""

from __future__ import annotations

import pint

UREG = pint.UnitRegistry()
