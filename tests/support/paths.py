"""Where the repository is, for tests that read its shipped files (config/, examples/, docs/)."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
