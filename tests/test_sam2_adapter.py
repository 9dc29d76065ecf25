"""Private parts of Meta's sam2: all in lfsam.segmenters.sam2.adapter, all present in this sam2.

If a sam2 upgrade removes or renames something the adapter relies on, these tests fail naming the
adapter module and the attribute, instead of lfsam failing at run time.
"""

from __future__ import annotations

import ast
import importlib
import re
from importlib import metadata
from pathlib import Path

import pytest

import lfsam
from lfsam.segmenters.sam2 import adapter as sam2_adapter
from lfsam.segmenters.sam2.adapter import (
    SAM2_CLASS_ATTRIBUTES,
    SAM2_MODULE_ATTRIBUTES,
    SAM2_PREDICTOR_STATE,
    missing_sam2_api,
)

SRC = Path(lfsam.__file__).resolve().parent
ADAPTER = Path(sam2_adapter.__file__).resolve()
SAM2_VERSION = metadata.version("sam2")


def _fail_message(name: str) -> str:
    return (
        f"lfsam.segmenters.sam2.adapter needs {name}, which the installed sam2 {SAM2_VERSION} "
        "does not have: adapt src/lfsam/segmenters/sam2/adapter.py to this sam2 or keep sam2 "
        "within the bound of pyproject.toml"
    )


@pytest.mark.parametrize(
    "dotted, name",
    [(dotted, name) for dotted, names in SAM2_CLASS_ATTRIBUTES.items() for name in names],
)
def test_sam2_classes_have_what_the_adapter_needs(dotted, name):
    module_name, _, class_name = dotted.rpartition(".")
    owner = getattr(importlib.import_module(module_name), class_name, None)
    if owner is None:
        pytest.fail(_fail_message(dotted))
    if not hasattr(owner, name):
        pytest.fail(_fail_message(f"{dotted}.{name}"))


@pytest.mark.parametrize(
    "module_name, name",
    [(module, name) for module, names in SAM2_MODULE_ATTRIBUTES.items() for name in names],
)
def test_sam2_modules_have_what_the_adapter_needs(module_name, name):
    if not hasattr(importlib.import_module(module_name), name):
        pytest.fail(_fail_message(f"{module_name}.{name}"))


def test_sam2_image_predictor_keeps_the_state_the_adapter_sets():
    from lfsam.segmenters.sam2.build import build_sam2, make_image_predictor

    predictor = make_image_predictor(build_sam2("sam2-tiny-test", device="cpu"))
    missing = missing_sam2_api(predictor)
    if missing:
        pytest.fail("; ".join(_fail_message(name) for name in missing))
    # the state the adapter writes is what Meta's predictor reads back after reset
    predictor.reset_predictor()
    assert predictor._is_image_set is False and predictor._features is None


def _private_attributes(path: Path) -> set[str]:
    """Every ``x._name`` (single leading underscore) and ``def _name`` in a module."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Attribute):
            names.add(node.attr)
        elif isinstance(node, ast.FunctionDef):
            names.add(node.name)
    return {n for n in names if n.startswith("_") and not n.startswith("__")}


def test_the_adapter_declares_every_private_name_it_uses():
    declared = set(SAM2_PREDICTOR_STATE)
    for names in SAM2_CLASS_ATTRIBUTES.values():
        declared |= set(names)
    own = {"_no_bar"}  # the adapter's own helper
    undeclared = _private_attributes(ADAPTER) - declared - own
    assert not undeclared, (
        f"sam2_adapter uses {sorted(undeclared)} without listing them in SAM2_CLASS_ATTRIBUTES / "
        "SAM2_PREDICTOR_STATE (so no test checks that sam2 has them)"
    )


def _sam2_private_names() -> set[str]:
    """Names with one leading underscore that the sam2 package defines (methods, attributes)."""
    import sam2

    names = set()
    for path in Path(sam2.__file__).parent.rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        names |= set(re.findall(r"def (_[A-Za-z]\w*)", text))
        names |= set(re.findall(r"self\.(_[A-Za-z]\w*)\s*=", text))
    return {n for n in names if not n.startswith("__")}


#: (module, name) pairs that are another library's private name spelled as one of sam2's:
#: transformers' ``EdgeTamVideoModel._use_mask_as_output``, wrapped by transformers.video_build to
#: fix its
#: object-score shape (docs/design.md section 10).
NOT_SAM2 = {("segmenters/transformers/video_build.py", "_use_mask_as_output")}


def test_no_other_module_touches_sam2_private_names():
    sam2_private = _sam2_private_names()
    assert {"_predict", "_features", "_prepare_backbone_features"} <= sam2_private  # sanity
    offenders = []
    for path in sorted(SRC.rglob("*.py")):
        if path.resolve() == ADAPTER:
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            name = None
            if isinstance(node, ast.Attribute) and node.attr in sam2_private:
                name = node.attr
            elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("sam2"):
                private = [a.name for a in node.names if a.name.startswith("_")]
                name = private[0] if private else None
            if name and (str(path.relative_to(SRC)), name) not in NOT_SAM2:
                offenders.append(f"{path.relative_to(SRC)}:{node.lineno} {name}")
    assert not offenders, (
        "only lfsam.segmenters.sam2.adapter may touch private names of sam2: "
        + ", ".join(offenders)
    )


def test_no_module_imports_private_helpers_of_the_sam2_builder():
    offenders = []
    for path in sorted(SRC.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and node.module == "lfsam.segmenters.sam2.build":
                offenders += [
                    f"{path.relative_to(SRC)}:{node.lineno} {a.name}"
                    for a in node.names
                    if a.name.startswith("_")
                ]
    assert not offenders, f"private helpers of sam2.build imported elsewhere: {offenders}"
