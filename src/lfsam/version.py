"""The package version, in a module of its own so that any module can import it without
importing :mod:`lfsam` (and its light-field and result modules) first.

Examples
--------
>>> from lfsam.version import __version__
>>> __version__
'0.1.0'
"""

__all__ = ["__version__"]

__version__ = "0.1.0"
