"""orbitrig: fluid-film bearing test rig service.

The Python API (docs/api.md): ``open_run(path)`` and ``identify_table(df, model=...)``.
They are imported on first use, so ``import orbitrig`` stays cheap (no pandas, no h5py).
"""

__version__ = "0.1.0"

__all__ = ["open_run", "identify_table", "__version__"]


def __getattr__(name: str):
    if name in ("open_run", "identify_table", "RunData", "Fit"):
        from orbitrig.store import run_data

        return getattr(run_data, name)
    raise AttributeError(f"module 'orbitrig' has no attribute {name!r}")
