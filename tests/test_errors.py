"""The error rule of lfsam.errors: user errors are LfsamError; ValueError/TypeError only where the
calling code is at fault, and then documented in the function's Raises section."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
import torch

import lfsam
from lfsam.errors import LfsamError
from lfsam.pipeline import PipelineConfig
from lfsam.pipeline.propagation import mask_disparities, propagate_masks
from lfsam.segmenters.base import Prompts
from lfsam.synth.shapes import inside
from lfsam.synth.textures import make_texture

SRC = Path(lfsam.__file__).resolve().parent


def _raised_builtin(node: ast.Raise) -> str | None:
    exc = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
    if isinstance(exc, ast.Name) and exc.id in ("ValueError", "TypeError"):
        return exc.id
    return None


def test_every_builtin_error_raised_is_documented_in_its_function():
    undocumented = []
    for path in sorted(SRC.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for func in ast.walk(tree):
            if not isinstance(func, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            doc = ast.get_docstring(func) or ""
            raises = doc.split("Raises\n", 1)[1] if "Raises\n" in doc else ""
            for node in ast.walk(func):
                if not isinstance(node, ast.Raise) or node.exc is None:
                    continue
                name = _raised_builtin(node)
                if name and name not in raises:
                    undocumented.append(f"{path.relative_to(SRC)}:{node.lineno} {name}")
    assert not undocumented, (
        "raise ValueError/TypeError only where the caller's code is at fault, and say so in the "
        f"docstring's Raises section (else raise LfsamError): {undocumented}"
    )


@pytest.mark.parametrize(
    "make",
    [
        lambda: PipelineConfig(occlusion="sometimes"),
        lambda: PipelineConfig(propagation="teleport"),
        lambda: PipelineConfig(encode_batch_size=0),
        lambda: PipelineConfig.from_ablation("ref+everything"),
        lambda: Prompts(),
        lambda: Prompts(points=[[[1.0, 2.0]]]),
        lambda: Prompts(points=[[[1.0, 2.0]]], point_labels=[[1]], boxes=[[0, 0, 4, 4]] * 2),
        lambda: make_texture("plaid", 0, (8, 8)),
        lambda: inside("hexagon", torch.zeros(2), torch.zeros(2)),
        lambda: propagate_masks(torch.ones(1, 4, 4, dtype=torch.bool), torch.zeros(4, 4), 1, 0,
                                mode="teleport"),
        lambda: mask_disparities(torch.ones(1, 4, 4, dtype=torch.bool), torch.zeros(4, 4), "mode"),
    ],
)
def test_user_errors_are_one_line_lfsam_errors(make):
    with pytest.raises(LfsamError) as info:
        make()
    message = str(info.value)
    assert message and "\n" not in message and ";" in message  # the problem; the fix


def test_a_disparity_of_another_size_is_a_user_error():
    from lfsam.api import RunOptions, SegmentOptions, segment
    from lfsam.segmenters.oracle import OracleSegmenter
    from lfsam.synth import generate_scene

    scene = generate_scene(grid=(3, 3), size=(24, 32), seed=1, num_objects=1)
    with pytest.raises(LfsamError, match=r"has shape \(24, 31\).*24x32"):
        segment(
            scene, model=OracleSegmenter(scene, device="cpu"), disparity=np.zeros((24, 31)),
            options=SegmentOptions(run=RunOptions(progress=False)),
        )
