"""The prompt model and the prompt file (docs/design.md section 8)."""

from __future__ import annotations

import json

import pytest

from lfsam.errors import LfsamError
from lfsam.prompts import (
    BoxPrompt,
    ObjectPrompts,
    PointPrompt,
    load_prompts,
    prompts_from_json,
    prompts_to_json,
    save_prompts,
    validate_objects,
)

GRID, SIZE = (5, 5), (60, 80)


def test_round_trip_and_reference_view(tmp_path):
    objects = [
        ObjectPrompts(1, (PointPrompt(10, 20), PointPrompt(30, 40, positive=False))),
        ObjectPrompts(
            7, (PointPrompt(5, 6, True, (0, 4)),), BoxPrompt(1, 2, 30, 40, view=(4, 0))
        ),
    ]
    path = save_prompts(objects, tmp_path / "p.json")
    assert load_prompts(path, GRID, SIZE) == objects
    assert objects[0].reference_view((2, 2)) == (2, 2)
    assert objects[1].reference_view((2, 2)) == (4, 0)  # the box's view wins
    assert ObjectPrompts(3, (PointPrompt(1, 1, False, (0, 0)), PointPrompt(2, 2, True, (1, 3)))
                         ).reference_view((2, 2)) == (1, 3)


def test_compact_format_with_labels_and_object_view():
    data = [{"id": 2, "points": [[10, 12], [20, 22]], "labels": [1, 0], "view": [0, 1],
             "box": [1, 2, 3, 4]}]
    (obj,) = prompts_from_json(data)
    assert obj.obj_id == 2
    assert [(p.x, p.y, p.positive, p.view) for p in obj.points] == [
        (10, 12, True, (0, 1)), (20, 22, False, (0, 1))
    ]
    assert obj.box == BoxPrompt(1, 2, 3, 4, view=(0, 1))
    assert prompts_from_json(prompts_to_json([obj])) == [obj]
    assert prompts_from_json({"objects": data}) == [obj]


@pytest.mark.parametrize(
    ("data", "fragment"),
    [
        ({"x": 1}, "JSON list of objects"),
        ([{"id": 1, "point": [[1, 2]]}], "object 1: unknown key(s) point"),
        ([{"id": 4, "points": [[1]]}], "object 4: point 1 must be 2 numbers"),
        ([{"id": 4, "points": [[1, 2]], "labels": [2]}], "object 4: point 1: label must be"),
        ([{"id": 4, "points": [[1, 2]], "labels": [1, 1]}], "labels must be a list as long"),
        ([{"id": 5, "box": [1, 2, 3]}], "object 5: box must be 4 numbers"),
        ([{"id": 5, "points": [[1, 2]], "view": [1]}], "object 5: view must be [S, T]"),
        ([{"id": "a", "points": [[1, 2]]}], "id must be an integer"),
        ([{"id": 3, "points": [{"xy": [1, 2], "lbl": 1}]}], "object 3: point 1: unknown key"),
    ],
)
def test_malformed_json_names_object_and_field(data, fragment):
    with pytest.raises(LfsamError) as info:
        prompts_from_json(data)
    message = str(info.value)
    assert fragment in message and "\n" not in message


@pytest.mark.parametrize(
    ("obj", "fragment"),
    [
        (ObjectPrompts(1, (PointPrompt(100, 5),)), "object 1: point 1 X,Y = 100,5 lies outside"),
        (ObjectPrompts(2, (PointPrompt(5, 5, True, (5, 0)),)), "object 2: point 1 is tagged with view 5,0"),
        (ObjectPrompts(3, (PointPrompt(5, 5, False),)), "object 3: only negative points"),
        (ObjectPrompts(4, (), BoxPrompt(10, 10, 5, 20)), "object 4: box 10,10,5,20 is empty"),
        (ObjectPrompts(0, (PointPrompt(5, 5),)), "object 0: id must be"),
        (ObjectPrompts(6, (), BoxPrompt(1, 1, 5, 5, view=(0, 9))), "object 6: box is tagged"),
    ],
)
def test_validation_names_object_and_field(obj, fragment):
    with pytest.raises(LfsamError) as info:
        validate_objects([obj], GRID, SIZE)
    assert fragment in str(info.value)


def test_duplicate_ids_rejected():
    obj = ObjectPrompts(1, (PointPrompt(5, 5),))
    with pytest.raises(LfsamError, match="object 1: id used twice"):
        validate_objects([obj, obj], GRID, SIZE)


def test_bad_files(tmp_path):
    with pytest.raises(LfsamError, match="not found"):
        load_prompts(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text('[{"id": 1,, }]')
    with pytest.raises(LfsamError, match="not valid JSON: .* at line 1 column"):
        load_prompts(bad)
    outside = tmp_path / "outside.json"
    outside.write_text(json.dumps([{"id": 9, "points": [[500, 5]]}]))
    with pytest.raises(LfsamError, match="object 9: point 1"):
        load_prompts(outside, GRID, SIZE)
