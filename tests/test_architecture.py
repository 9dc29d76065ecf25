"""The package's shape (docs/architecture.md): small modules with one job, the predictor facade
kept small, the segmenters grouped by model family (issue 46) and video/ by job (issue 67)."""

from __future__ import annotations

from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "lfsam"

#: No module grows past this many lines: split it by job first (issue 67: from 700 to 550, each
#: split by responsibility, docs/architecture.md).
MAX_MODULE_LINES = 550
#: The interactive entry point stays a thin facade over the pipeline (docs/architecture.md).
MAX_PREDICTOR_LINES = 400


def _lines(path: Path) -> int:
    return len(path.read_text(encoding="utf-8").splitlines())


def test_no_module_over_the_line_limit():
    too_long = {
        str(p.relative_to(SRC)): _lines(p)
        for p in SRC.rglob("*.py")
        if _lines(p) > MAX_MODULE_LINES
    }
    assert not too_long, f"modules over {MAX_MODULE_LINES} lines (split them by job): {too_long}"


def test_predictor_facade_stays_small():
    assert _lines(SRC / "predictor.py") <= MAX_PREDICTOR_LINES


def test_segmenters_are_grouped_by_model_family():
    """The interface, the oracle and shared helpers at the top; one sub-package per family."""
    top = sorted(p.name for p in (SRC / "segmenters").glob("*.py"))
    assert len(top) <= 8, top
    families = sorted(
        p.name for p in (SRC / "segmenters").iterdir() if (p / "__init__.py").is_file()
    )
    assert families == ["sam2", "text", "transformers"]
    assert not [n for n in top if n.startswith(("sam2_", "hf_"))], top


def test_video_is_grouped_by_job():
    """Nothing but the package's entry and the whole-video scoring at the top of video/; one
    sub-package per job, each saying what it may import (their order: pyproject.toml)."""
    top = sorted(p.name for p in (SRC / "video").glob("*.py"))
    assert top == ["__init__.py", "evaluate.py"], top
    rooms = sorted(p.name for p in (SRC / "video").iterdir() if (p / "__init__.py").is_file())
    assert rooms == ["io", "memory", "stream", "tracking"]
    for room in rooms:
        doc = (SRC / "video" / room / "__init__.py").read_text(encoding="utf-8")
        assert "May import" in doc, room
