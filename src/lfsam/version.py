"""The package's version, in a module of its own so that any layer can import it (docs/design.md
section 8) without importing the package root."""

__version__ = "0.1.0"
