"""orbitrig: fluid-film bearing test rig service."""

__version__ = "0.1.0"
