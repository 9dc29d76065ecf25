"""Doctest collection of the package (``pytest --doctest-modules``, run by ``make test``).

Collecting a module's doctests imports the module. Modules whose module-level imports need an
optional extra that is not installed (e.g. a Ray back end), or a GUI toolkit (the napari viewer,
Qt), are not collected: a missing extra must never fail collection, and collection must never
start napari or Qt. This is decided from each file's source (its module-level ``import``
statements, followed through ``lfsam`` modules), without importing anything. Those modules are
tested by their own tests in ``tests/``, which skip cleanly without the extra.
"""

from __future__ import annotations

import ast
import importlib.util
from functools import cache
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parent

# Never imported at collection time, even when installed.
GUI_PACKAGES = frozenset(
    {"napari", "qtpy", "PyQt5", "PyQt6", "PySide2", "PySide6", "vispy", "magicgui", "superqt"}
)


def _module_file(name: str) -> Path | None:
    """The source file of an ``lfsam`` module inside this tree, or None."""
    base = SRC.joinpath(*name.split("."))
    for candidate in (base.with_suffix(".py"), base / "__init__.py"):
        if candidate.is_file():
            return candidate
    return None


def _module_imports(tree: ast.Module, package: str) -> set[str]:
    """Absolute names imported by the module's top-level statements (not guarded by ``try``)."""
    names: set[str] = set()
    for node in tree.body:
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1])
                module = f"{base}.{node.module}" if node.module else base
            else:
                module = node.module or ""
            names.add(module)
            # ``from lfsam.pkg import mod`` may import a submodule.
            names.update(f"{module}.{alias.name}" for alias in node.names)
    return names


@cache
def _installed(top: str) -> bool:
    return importlib.util.find_spec(top) is not None


@cache
def _blocked(path: Path) -> str | None:
    """Why importing ``path`` needs something unavailable at collection time, or None."""
    try:
        tree = ast.parse(path.read_text(encoding="utf-8"))
    except (OSError, SyntaxError, UnicodeDecodeError):
        return None  # let pytest report it
    package = ".".join(path.relative_to(SRC).parts[:-1])
    for name in sorted(_module_imports(tree, package)):
        top = name.split(".")[0]
        if not top:
            continue
        if top in GUI_PACKAGES:
            return f"imports the GUI package {top}"
        if top == "lfsam":
            inner = _module_file(name)
            reason = _blocked(inner) if inner is not None and inner != path else None
            if reason:
                return reason
            continue
        if not _installed(top):
            return f"needs {top}, not installed"
    return None


def pytest_ignore_collect(collection_path: Path, config: pytest.Config) -> bool | None:
    if collection_path.suffix != ".py":
        return None
    try:
        collection_path.resolve().relative_to(SRC)
    except ValueError:
        return None
    return True if _blocked(collection_path.resolve()) else None
