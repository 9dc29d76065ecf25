"""LightFieldPredictor: any reference view, clicks, incremental edits, caching (issue 13)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from lfsam.api import RunOptions, SegmentOptions, segment
from lfsam.embeddings import embedding_nbytes
from lfsam.errors import LfsamError
from lfsam.generator import LightFieldMaskGenerator
from lfsam.pipeline.propagation import propagate_masks
from lfsam.predictor import LightFieldPredictor
from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.segmenters import load_segmenter
from lfsam.synth import generate_scene

_QUIET = SegmentOptions(run=RunOptions(progress=False))


def _from(references: str) -> SegmentOptions:
    """Quiet batch options with automatic mode from ``references``."""
    return SegmentOptions(run=RunOptions(progress=False, references=references))


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    union = np.logical_or(a, b).sum()
    return 1.0 if union == 0 else float(np.logical_and(a, b).sum() / union)


def _inner_pixel(mask: np.ndarray) -> tuple[float, float]:
    """(x, y) of the object pixel farthest inside the mask (a click a user would make)."""
    from scipy import ndimage

    depth = ndimage.distance_transform_edt(mask)
    row, col = np.unravel_index(np.argmax(depth), mask.shape)
    return float(col), float(row)


@pytest.fixture(scope="module")
def hidden_scene():
    return generate_scene(grid=(5, 5), size=(120, 160), seed=2, hidden_objects=1)


@pytest.fixture(scope="module")
def scene():
    return generate_scene(grid=(5, 5), size=(64, 96), seed=3)


def test_object_hidden_in_center_segmented_from_an_outer_view(hidden_scene):
    lf = hidden_scene
    (hidden,) = lf.meta["generator"]["hidden_labels"]
    areas = (lf.labels == hidden).sum(axis=(2, 3))
    assert areas[lf.center] == 0 and areas.max() > 0
    view = tuple(int(i) for i in np.unravel_index(np.argmax(areas), areas.shape))
    predictor = LightFieldPredictor(load_segmenter("oracle", lightfield=lf, device="cpu"))
    predictor.set_lightfield(lf, disparity="gt")
    x, y = _inner_pixel(lf.labels[view] == hidden)
    predictor.add_prompts(5, points=[(x, y)], labels=[1], view=view)
    labels = predictor.predict().labels
    mostly = areas >= 0.5 * areas.max()
    for s, t in zip(*np.nonzero(mostly), strict=True):
        assert _iou(labels[s, t] == 5, lf.labels[s, t] == hidden) >= 0.9, (s, t)
    for s, t in zip(*np.nonzero(areas == 0), strict=True):
        assert not (labels[s, t] == 5).any(), f"mask where the object is hidden: view {(s, t)}"
    assert predictor.to_result().meta["objects"][0]["reference_view"] == list(view)


def test_negative_click_on_merged_neighbour_fixes_every_view(scene):
    lf = scene
    oracle = load_segmenter(
        "oracle", lightfield=lf, device="cpu", oracle_options={"merge_prob": 1.0}
    )
    predictor = LightFieldPredictor(oracle)
    predictor.set_lightfield(lf, disparity="gt")
    center = lf.labels[lf.center]
    ids, counts = np.unique(center[center > 1], return_counts=True)
    target = int(ids[np.argmax(counts)])
    x, y = _inner_pixel(center == target)
    predictor.add_prompts(1, points=[(x, y)], view=lf.center)
    _, merged, _ = predictor.predict_reference(1)
    neighbour_ids = set(np.unique(center[merged])) - {target}
    assert len(neighbour_ids) == 1, "the merging oracle adds one neighbour"
    (neighbour,) = neighbour_ids
    assert _iou(merged, center == target) < 0.95
    nx, ny = _inner_pixel(center == neighbour)
    predictor.add_prompts(1, points=[(nx, ny)], labels=[0], view=lf.center)
    labels = predictor.predict().labels
    visible = (lf.labels == target).sum(axis=(2, 3)) > 0
    for s, t in zip(*np.nonzero(visible), strict=True):
        assert _iou(labels[s, t] == 1, lf.labels[s, t] == target) >= 0.95, (s, t)


def test_incremental_edit_recomputes_one_object_only(scene):
    lf = scene
    oracle = load_segmenter("oracle", lightfield=lf, device="cpu")
    predictor = LightFieldPredictor(oracle)
    predictor.set_lightfield(lf, disparity="gt")
    rng = np.random.default_rng(0)
    height, width = lf.view_shape
    points = rng.uniform([0, 0], [width - 1, height - 1], size=(20, 2))
    for k, (x, y) in enumerate(points):
        predictor.add_prompts(k + 1, points=[(x, y)])
    first = predictor.predict()
    before = {i: first.masks[i].copy() for i in predictor.object_ids}
    counts = dict(predictor.decode_counts)
    assert all(counts[i] > 0 for i in predictor.object_ids)
    encoded = predictor.views_encoded
    # Edit object 7: only it is decoded again; the others' masks stay byte-identical.
    predictor.add_prompts(7, points=[(5.0, 5.0)], labels=[0])
    second = predictor.predict()
    for i in predictor.object_ids:
        if i == 7:
            assert predictor.decode_counts[i] > counts[i]
        else:
            assert predictor.decode_counts[i] == counts[i]
            assert np.array_equal(second.masks[i], before[i])
    assert predictor.views_encoded == encoded  # nothing encoded twice
    # ... and the labels equal a fresh full run with the same prompts (paint order kept).
    fresh = LightFieldPredictor(load_segmenter("oracle", lightfield=lf, device="cpu"))
    fresh.set_lightfield(lf, disparity="gt")
    for obj in predictor.objects.values():
        fresh.set_object(obj)
    assert np.array_equal(fresh.predict().labels, second.labels)
    # Removing an object removes its label everywhere and nothing else is recomputed.
    predictor.remove_object(3)
    third = predictor.predict()
    assert not (third.labels == 3).any()
    assert predictor.decode_counts == {**counts, 7: predictor.decode_counts[7]}


def test_coarse_to_fine_stages(scene):
    lf = scene
    predictor = LightFieldPredictor(load_segmenter("oracle", lightfield=lf, device="cpu"))
    predictor.set_lightfield(lf, disparity="gt")
    predictor.add_prompts(2, points=[(40, 30)], view=(0, 4))
    view, mask, score = predictor.predict_reference(2)
    assert view == (0, 4) and mask.shape == lf.view_shape and mask.any() and score == 1.0
    assert predictor.views_encoded == 1  # only the clicked view so far
    coarse = predictor.predict_coarse()
    assert coarse.stage == "coarse" and np.array_equal(coarse.labels[view] == 2, mask)
    refined = predictor.predict()
    assert refined.stage == "refined" and refined.labels.shape == lf.views.shape[:4]
    assert predictor.views_encoded == lf.num_views  # each view encoded once in all


def test_batch_path_is_the_predictor(scene):
    lf = scene
    oracle = load_segmenter("oracle", lightfield=lf, device="cpu")
    batch = segment(lf, model=oracle, disparity=lf.center_disparity, options=_QUIET)
    predictor = LightFieldPredictor(load_segmenter("oracle", lightfield=lf, device="cpu"))
    predictor.set_lightfield(lf, disparity=lf.center_disparity)
    ids = LightFieldMaskGenerator(predictor).generate()
    assert ids == list(range(1, batch.num_masks + 1))
    assert np.array_equal(predictor.predict().labels, batch.labels)
    assert batch.meta["views_encoded"] == lf.num_views


def test_reopened_result_reproduces_labels(scene, tmp_path):
    from lfsam.result import load_result, save_result

    lf = scene
    predictor = LightFieldPredictor(load_segmenter("oracle", lightfield=lf, device="cpu"))
    predictor.set_lightfield(lf, disparity="gt")
    predictor.add_prompts(3, points=[(40, 30), (10, 10)], labels=[1, 0], view=(1, 1))
    LightFieldMaskGenerator(predictor).generate()
    path = save_result(predictor.to_result(), tmp_path / "r.npz")
    result = load_result(path)
    again = LightFieldPredictor(load_segmenter("oracle", lightfield=lf, device="cpu"))
    again.set_lightfield(lf, disparity="gt")
    again.open_result(result)
    assert again.objects[3] == predictor.objects[3]
    assert np.array_equal(again.predict().labels, result.labels)


def test_prompt_errors(scene):
    lf = scene
    predictor = LightFieldPredictor(load_segmenter("oracle", lightfield=lf, device="cpu"))
    with pytest.raises(LfsamError, match="set_lightfield"):
        predictor.predict()
    predictor.set_lightfield(lf, disparity="gt")
    with pytest.raises(LfsamError, match="object 1: only negative points"):
        predictor.add_prompts(1, points=[(3, 3)], labels=[0])
    with pytest.raises(LfsamError, match="object 2: point 1 is tagged with view 9,9"):
        predictor.add_prompts(2, points=[(3, 3)], view=(9, 9))
    with pytest.raises(LfsamError, match="no object 4"):
        predictor.remove_object(4)


def test_absent_views_get_no_labels():
    lf = generate_scene(grid=(3, 3), size=(48, 64), seed=1)
    lf.present[0, 0] = False
    lf.views[0, 0] = 0
    predictor = LightFieldPredictor(load_segmenter("oracle", lightfield=lf, device="cpu"))
    predictor.set_lightfield(lf, disparity="gt")
    LightFieldMaskGenerator(predictor).generate()
    labels = predictor.predict().labels
    assert not labels[0, 0].any() and labels[1, 1].any()
    assert predictor.views_encoded == 8
    result = predictor.to_result()
    assert not result.present[0, 0] and result.present.sum() == 8


# --- any reference view: the convention round trip ---------------------------------------------
@pytest.fixture(scope="module")
def flat_scene():
    # no occlusion: a single slanted background plane
    return generate_scene(grid=(5, 5), size=(48, 64), seed=4, num_objects=0)


@settings(max_examples=15, deadline=None)
@given(
    a=st.tuples(st.integers(0, 4), st.integers(0, 4)),
    b=st.tuples(st.integers(0, 4), st.integers(0, 4)),
    box=st.tuples(st.integers(8, 28), st.integers(8, 40), st.integers(6, 12), st.integers(6, 16)),
)
def test_propagate_a_to_b_and_back_returns_the_mask(flat_scene, a, b, box):
    lf = flat_scene
    row, col, h, w = box
    mask = np.zeros(lf.view_shape, dtype=bool)
    mask[row : row + h, col : col + w] = True
    d_a = torch.as_tensor(lf.disparity[a])
    d_b = torch.as_tensor(lf.disparity[b])
    ab = propagate_masks(torch.as_tensor(mask)[None], d_a, b[0] - a[0], b[1] - a[1])
    back = propagate_masks(ab, d_b, a[0] - b[0], a[1] - b[1])[0].numpy()
    # Nothing occludes the plane; away from the frame border the round trip is exact up to
    # the boundary pixels that nearest-pixel rounding can move by one.
    from scipy import ndimage

    square = ndimage.generate_binary_structure(2, 2)  # one pixel in both axes
    inner = ndimage.binary_erosion(mask, square)
    outer = ndimage.binary_dilation(mask, square)
    assert back[inner].all() and not back[~outer].any()


# --- embedding cache (tiny SAM 2, random weights) ----------------------------------------------
@pytest.fixture(scope="module")
def tiny_scene():
    return generate_scene(grid=(3, 3), size=(48, 64), seed=5)


def _cached_run(lf, cache_dir, **kwargs):
    seg = load_segmenter("sam2-tiny-test", random_weights=True, device="cpu")
    predictor = LightFieldPredictor(seg, cache_dir=cache_dir, **kwargs)
    predictor.set_lightfield(lf, disparity="gt")
    predictor.add_prompts(1, points=[(30, 20)])
    predictor.add_prompts(2, box=(5, 5, 40, 30), view=(0, 2))
    return predictor, predictor.predict().labels


def test_disk_cache_second_run_encodes_nothing(tiny_scene, tmp_path):
    first, labels_a = _cached_run(tiny_scene, tmp_path / "cache")
    assert first.views_encoded == tiny_scene.num_views
    second, labels_b = _cached_run(tiny_scene, tmp_path / "cache")
    assert second.views_encoded == 0
    assert np.array_equal(labels_a, labels_b)
    _, labels_c = _cached_run(tiny_scene, None)
    assert np.array_equal(labels_a, labels_c)  # a cached run reproduces an uncached one


def test_corrupt_or_foreign_cache_entries_are_recomputed(tiny_scene, tmp_path):
    cache = tmp_path / "cache"
    _, labels_a = _cached_run(tiny_scene, cache)
    entries = sorted(cache.glob("*.npz"))
    entries[0].write_bytes(b"not an npz")
    entries[1].write_bytes(entries[2].read_bytes())  # another view's entry under this name
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        predictor, labels_b = _cached_run(tiny_scene, cache)
    assert predictor.views_encoded == 2
    assert sum("unreadable" in str(w.message) for w in caught) == 2
    assert np.array_equal(labels_a, labels_b)


def test_memory_budget_evicts_and_recomputes(tiny_scene):
    seg = load_segmenter("sam2-tiny-test", random_weights=True, device="cpu")
    predictor = LightFieldPredictor(seg, memory_budget_mb=0.0)
    predictor.set_lightfield(tiny_scene, disparity="gt")
    predictor.add_prompts(1, points=[(30, 20)])
    labels = predictor.predict().labels
    # only the last view and the pinned reference view (the center) are kept
    assert set(predictor.engine.store._memory) == {tiny_scene.center, (2, 2)}
    reference = LightFieldPredictor(load_segmenter("sam2-tiny-test", random_weights=True,
                                                   device="cpu"))
    reference.set_lightfield(tiny_scene, disparity="gt")
    reference.set_object(ObjectPrompts(1, (PointPrompt(30, 20),)))
    assert np.array_equal(reference.predict().labels, labels)


# --- automatic mode from several reference views (issue 16) -------------------------------------
def test_corner_references_find_the_hidden_objects():
    from lfsam.metrics import evaluate_result

    lf = generate_scene(grid=(5, 5), size=(96, 128), seed=0, hidden_objects=2)
    scores = {}
    for references in ("center", "corners"):
        result = segment(
            lf, model=load_segmenter("oracle", lightfield=lf, device="cpu"),
            disparity="gt", options=_from(references),
        )
        scores[references] = evaluate_result(result, lf, device="cpu")
        assert result.meta["references"] == references
    assert scores["center"]["recall"] < 1.0
    assert scores["corners"]["recall"] == 1.0
    assert scores["corners"]["aa"] >= scores["center"]["aa"]
    assert scores["corners"]["ue"] <= scores["center"]["ue"]


@pytest.mark.parametrize(
    ("seed", "references"),
    [(1, "corners"), (5, "corners"), (7, "corners"), (13, "corners"), (7, "ring")],
)
def test_extra_references_find_each_hidden_object_once(seed, references):
    """Hard scenes (oracle, ground-truth disparity): in seed 13 two hidden objects share one
    uncovered strip of a corner and a grid point finds only one (the other is found by a
    later round, at the deepest pixel no answer explains); in seeds 1, 5 and 7 a small
    object peeks out in two corners whose views of it do not carry into each other, so it is
    found twice and the two finds are merged, keeping the larger; with ``ring``, seed 7's
    object is first found as 4 pixels in (0, 2), and its 25 pixels in (0, 4) replace that find.
    Each hidden object is then recalled, by exactly one automatic object."""
    from lfsam.metrics import evaluate_result

    lf = generate_scene(grid=(5, 5), size=(96, 128), seed=seed, hidden_objects=2)
    result = segment(
        lf, model=load_segmenter("oracle", lightfield=lf, device="cpu"),
        disparity="gt", options=_from(references),
    )
    assert evaluate_result(result, lf, device="cpu")["recall"] == 1.0
    found = {}
    for entry in result.meta["objects"]:  # the ground-truth object each predicted one covers
        covered = lf.labels[result.labels == entry["id"]]
        found[entry["id"]] = int(np.bincount(covered).argmax())
    hidden = lf.meta["generator"]["hidden_labels"]
    assert sorted(v for v in found.values() if v in hidden) == sorted(hidden)
    assert result.num_masks == len(np.unique(lf.labels[lf.labels > 0]))
    assert sorted(found) == list(range(1, result.num_masks + 1))  # ids closed after merges


def test_extra_references_ask_nowhere_the_center_sees_and_change_no_label():
    """A scene without hidden objects: the corners' generator is asked only where the center
    view could not look, finds no new object, and every label stays as with ``center``."""
    lf = generate_scene(grid=(5, 5), size=(96, 128), seed=1)
    asked = []
    segmenter = load_segmenter("oracle", lightfield=lf, device="cpu")
    generate = segmenter.generate

    def counting_generate(embedding, image, points=None):
        asked.append(None if points is None else len(points))
        return generate(embedding, image, points=points)

    segmenter.generate = counting_generate
    results = {
        references: segment(lf, model=segmenter, disparity="gt", options=_from(references))
        for references in ("center", "corners")
    }
    assert np.array_equal(results["center"].labels, results["corners"].labels)
    extra = [n for n in asked if n is not None]
    # A corner asks only where no refined mask lands and the center view could not see (what
    # is left of frame-border strips and disocclusions, a small part of this scene, or nothing),
    # never at the whole grid.
    assert asked.count(None) == 2 and len(extra) <= 4 and all(n < 0.2 * 32 * 32 for n in extra)


def test_extra_reference_views_are_encoded_once_under_a_small_memory_budget():
    """The corners visited by the automatic mode are used before new encodes can evict them."""
    lf = generate_scene(grid=(5, 5), size=(96, 128), seed=1)
    segmenter = load_segmenter("oracle", lightfield=lf, device="cpu")
    one_view_mb = embedding_nbytes(segmenter.encode(lf.views[0, :1], keys=[(0, 0)])[0]) / 2**20
    predictor = LightFieldPredictor(segmenter, memory_budget_mb=6 * one_view_mb, progress=False)
    predictor.set_lightfield(lf, disparity="gt")
    LightFieldMaskGenerator(predictor, "corners").generate()
    predictor.predict()
    assert predictor.views_encoded == 25


def test_incremental_edit_gives_the_labels_of_a_fresh_full_run():
    """SAM 2 (tiny, random weights): adding a negative click to one of five objects and
    predicting again gives exactly the labels of a fresh predictor given the final prompts
    (a carried click of one object must not pad, and so change, another object's prompt)."""
    lf = generate_scene(grid=(3, 3), size=(48, 64), seed=0, num_objects=4)
    segmenter = load_segmenter("sam2-tiny-test", random_weights=True, device="cpu")
    clicks = np.random.default_rng(0).uniform([4, 4], [59, 43], size=(6, 2))

    def predictor_with_objects():
        predictor = LightFieldPredictor(segmenter, progress=False)
        predictor.set_lightfield(lf, disparity="gt")
        for k in range(5):
            predictor.add_prompts(k + 1, points=[clicks[k]], view=(0, 0) if k == 3 else lf.center)
        return predictor

    edited = predictor_with_objects()
    edited.predict()
    edited.add_prompts(2, points=[clicks[5]], labels=[0])
    incremental = edited.predict().labels
    fresh = predictor_with_objects()
    fresh.add_prompts(2, points=[clicks[5]], labels=[0])
    assert np.array_equal(incremental, fresh.predict().labels)


def test_source_features_are_computed_when_the_pipeline_needs_them(scene, monkeypatch):
    """An object's source feature (paper 3.3) is computed when the occluding step first needs
    it, for every reference decoded with it at once: a reference answer that is replaced
    before the pipeline runs (the tracker's refused prompts, docs/design.md section 10)
    never pays for it, and the features are those of the eager batch, number for number."""
    import lfsam.pipeline.engine as engine_module
    from lfsam.pipeline.occlusion import source_features

    lf = scene
    predictor = LightFieldPredictor(load_segmenter("oracle", lightfield=lf, device="cpu"))
    predictor.set_lightfield(lf, disparity="gt")
    batches = []
    real = engine_module.source_features

    def counted(segmenter, embedding, masks):
        batches.append(masks.shape[0])
        return real(segmenter, embedding, masks)

    monkeypatch.setattr(engine_module, "source_features", counted)
    labels = lf.labels[lf.center]
    objects = [np.argwhere(labels == k)[0] for k in np.unique(labels)[1:4]]
    for k, (row, col) in enumerate(objects):
        predictor.add_prompts(k + 1, points=[(float(col), float(row))])
    for _ in range(3):  # answers asked and replaced: no features for them
        predictor.predict_reference(1)
        predictor.add_prompts(1, points=[(float(objects[0][1]), float(objects[0][0]))])
    assert batches == []
    predictor.predict()
    assert sum(batches) == len(objects)
    table = predictor._table
    refs = [table[i].reference for i in predictor.object_ids]
    masks = torch.stack([r.mask for r in refs])
    eager = source_features(predictor.engine.segmenter, predictor.engine.embedding(lf.center),
                            masks)
    for k, ref in enumerate(refs):
        assert ref.pending is None
        assert torch.equal(ref.feature, eager[k])
