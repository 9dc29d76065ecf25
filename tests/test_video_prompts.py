"""Prompts tagged with frames (issue 25): #F on the command line, "frame" in prompt files."""

from __future__ import annotations

import argparse

import pytest

from lfsam.cli.prompts import PROMPT_PARSERS, objects_from_items
from lfsam.errors import LfsamError
from lfsam.prompts import (
    ObjectPrompts,
    PointPrompt,
    prompts_from_json,
    prompts_to_json,
    validate_objects,
)
from lfsam.video.tracking.prompts import negatives_since, prompts_at, start_frame


def test_command_line_frame_tags():
    items = [PROMPT_PARSERS["point"]("10,12@1,2#3"), PROMPT_PARSERS["neg"]("4,5#5"),
             PROMPT_PARSERS["box"]("1,2,30,40"), PROMPT_PARSERS["point"]("7,8")]
    first, second, third = objects_from_items(items)
    assert first.points[0] == PointPrompt(10, 12, True, (1, 2), 3)
    assert first.points[1] == PointPrompt(4, 5, False, None, 5)
    assert second.box.frame is None and third.points[0].frame is None
    assert (start_frame(first), start_frame(second)) == (3, 0)
    for bad in ("1,2#x", "1,2#-1", "1,2#"):
        with pytest.raises(argparse.ArgumentTypeError, match="frame after #"):
            PROMPT_PARSERS["point"](bad)


def test_prompt_file_frames_round_trip():
    data = [{"id": 4, "points": [[30, 40], {"xy": [12, 20], "label": 0, "frame": 5}],
             "frame": 3},
            {"id": 2, "box": {"xyxy": [1, 2, 10, 12], "frame": 1}}]
    objects = prompts_from_json(data)
    assert [p.frame for p in objects[0].points] == [3, 5] and objects[1].box.frame == 1
    assert prompts_from_json(prompts_to_json(objects)) == objects
    obj = objects[0]
    assert start_frame(obj) == 3 and prompts_at(obj, 4) is None
    assert prompts_at(obj, 3) == ObjectPrompts(4, (PointPrompt(30, 40),))
    assert negatives_since(obj, 4) == () and negatives_since(obj, 6) == (
        PointPrompt(12, 20, False),)
    with pytest.raises(LfsamError, match="frame must be a whole number"):
        prompts_from_json([{"points": [[1, 2]], "frame": -1}])


def test_frames_are_checked_against_the_input():
    obj = ObjectPrompts(1, (PointPrompt(3, 4, True, None, 3),))
    with pytest.raises(LfsamError, match="frame 3, but a single light field has frame 0 only"):
        validate_objects([obj], (3, 3), (8, 8))
    with pytest.raises(LfsamError, match=r"frame 3, but the video has frames 0\.\.2"):
        validate_objects([obj], (3, 3), (8, 8), num_frames=3)
    validate_objects([obj], (3, 3), (8, 8), num_frames=4)
