"""Errors of the campaign catalog."""

from __future__ import annotations

from orbitrig.errors import OrbitrigError

#: query parameters of a database URL that hold a secret (libpq's and SQLAlchemy's name)
SECRET_PARAMETERS = ("password",)


def shown_url(url: str) -> str:
    """``url`` as messages and logs show it: without the password of its user part
    (``postgresql://user:PW@host/db``) and without a ``password=`` query parameter
    (``postgresql://user@/db?host=/run/pg&password=PW``), which libpq and SQLAlchemy accept."""
    base, mark, query = url.partition("?")
    head, at, tail = base.rpartition("@")
    if at and "://" in head:
        scheme, _, user = head.partition("://")
        base = f"{scheme}://{user.split(':', 1)[0]}@{tail}"
    kept = [p for p in query.split("&") if p.partition("=")[0].lower() not in SECRET_PARAMETERS]
    return base + (mark + "&".join(kept) if mark and kept else "")


class CatalogError(OrbitrigError):
    """The catalog database cannot be opened, read or written (the URL names it)."""


class CatalogUsageError(CatalogError):
    """A bad option: a --where filter outside the grammar, an unknown column or format."""


class CatalogMissingError(CatalogError):
    """The SQLite catalog file is not there (reading, which never creates one)."""
