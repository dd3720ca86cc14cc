"""The campaign catalog: stored runs as rows of a database (SQLAlchemy Core), and the
comparisons drawn from them (docs/catalog.md)."""
