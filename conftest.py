"""Repository-wide pytest set-up.

``--doctest-modules`` (in ``pyproject.toml``) collects every ``.py`` file under the test paths as
a doctest module. ``tests/conftest.py`` and ``src/conftest.py`` are both plain modules named
``conftest``; importing one of them a second time for doctests clashes with the other
("import file mismatch" since pytest 9). Neither holds doctests, so they are never collected as
doctest modules; pytest still loads both as conftests.
"""

from __future__ import annotations

from pathlib import Path

import pytest


def pytest_ignore_collect(collection_path: Path, config: pytest.Config) -> bool | None:
    return True if collection_path.name == "conftest.py" else None
