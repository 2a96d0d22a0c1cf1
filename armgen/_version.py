"""The package version, on the ground floor: every layer may import it (the root package's
``__init__`` only re-exports it, and pyproject.toml reads it from here)."""

__version__ = "0.1.0"
