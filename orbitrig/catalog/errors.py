"""Errors of the campaign catalog."""

from __future__ import annotations

from orbitrig.errors import OrbitrigError


class CatalogError(OrbitrigError):
    """The catalog database cannot be opened, read or written (the URL names it)."""


class CatalogUsageError(CatalogError):
    """A bad option: a --where filter outside the grammar, an unknown column or format."""
