"""Refining a few views (issue 24): the view pattern, the fill from refined views, and the
predictor, API and CLI with ``refine_views`` (docs/design.md section 3.7)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

import lfsam
from lfsam.api import RunOptions, SegmentOptions
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField
from lfsam.metrics.accuracy import per_view_iou
from lfsam.pipeline import PipelineConfig
from lfsam.pipeline.fill import fill_from_sources, source_knowledge
from lfsam.pipeline.sparse import (
    check_refine_views,
    nearest_sources,
    refined_views,
    select_views,
    sparse_view_count,
)
from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.synth import generate_scene
from lfsam.warp import forward_warp

QUIET = RunOptions(progress=False)


def options(refine_views="all", **kw) -> SegmentOptions:
    return SegmentOptions(pipeline=PipelineConfig(refine_views=refine_views, **kw), run=QUIET)


# --- the view pattern ------------------------------------------------------------------------
def test_sparse_counts_of_the_issue():
    assert sparse_view_count(81) == 13  # at most 17 (issue 24)
    assert sparse_view_count(25) == 9
    assert sparse_view_count(9) == 9
    assert refined_views("sparse", np.ones((3, 3), bool), (1, 1)) is None  # the whole grid
    assert len(refined_views("sparse", np.ones((9, 9), bool), (4, 4))) == 13
    assert len(refined_views("sparse", np.ones((5, 5), bool), (2, 2))) == 9
    assert refined_views("all", np.ones((9, 9), bool), (4, 4)) is None


def test_check_refine_views_forms():
    assert check_refine_views("all") == "all"
    assert check_refine_views("sparse") == "sparse"
    assert check_refine_views("9") == 9
    assert check_refine_views(13) == 13
    for bad in ("0", 0, -3, "some", True, 2.5):
        with pytest.raises(LfsamError, match="refine_views must be"):
            check_refine_views(bad)
    with pytest.raises(LfsamError, match="refine_views"):
        PipelineConfig(refine_views="every")
    assert PipelineConfig(refine_views="5").refine_views == 5


@settings(max_examples=60, deadline=None)
@given(
    s=st.integers(1, 11), t=st.integers(1, 11), count=st.integers(1, 40),
    seed=st.integers(0, 10_000), holes=st.floats(0.0, 0.5),
)
def test_select_views_properties(s, t, count, seed, holes):
    rng = np.random.default_rng(seed)
    present = rng.random((s, t)) >= holes
    center = (s // 2, t // 2)
    present[center] = True
    chosen = select_views(present, count, [center])
    assert chosen[0] == center
    assert len(chosen) == len(set(chosen)) == min(count, int(present.sum()))
    assert all(present[v] for v in chosen)
    coords = np.argwhere(present)
    (s0, t0), (s1, t1) = coords.min(0), coords.max(0)
    if count >= 5:
        for corner in ((s0, t0), (s0, t1), (s1, t0), (s1, t1)):
            if present[corner]:
                assert (int(corner[0]), int(corner[1])) in chosen
    assert select_views(present, count, [center]) == chosen  # deterministic


def test_select_views_spreads_evenly():
    """Every view of a 9x9 grid is within 2 view steps of one of the 13 sparse views (and of
    the 17 views the issue allows at most), and the pattern is symmetric under the grid's
    flips."""
    grid = np.ones((9, 9), bool)
    for count in (13, 17):
        _check_spread(set(select_views(grid, count, [(4, 4)])))


def _check_spread(chosen: set) -> None:
    for s in range(9):
        for t in range(9):
            assert min(math.hypot(s - a, t - b) for a, b in chosen) <= 2
    assert {(8 - s, t) for s, t in chosen} == chosen
    assert {(s, 8 - t) for s, t in chosen} == chosen


def test_nearest_sources_order():
    sources = [(0, 0), (0, 4), (2, 2), (4, 4)]
    assert nearest_sources((1, 1), sources, 2) == [(0, 0), (2, 2)]
    assert (2, 2) not in nearest_sources((2, 2), sources)


# --- the fill --------------------------------------------------------------------------------
def _rect_scene(grid, size, depth, box):
    """A fronto-parallel rectangle (label 2) at integer disparity ``depth`` > 0 in front of a
    background (label 1) at disparity 0 (which never moves: no strip enters at the frame
    border), exact in every view; views textured with noise."""
    (s_count, t_count), (height, width) = grid, size
    center = (s_count // 2, t_count // 2)
    u0, v0, u1, v1 = box
    labels = np.ones((s_count, t_count, height, width), np.int32)
    disparity = np.zeros(labels.shape, np.float32)
    for s in range(s_count):
        for t in range(t_count):
            du, dv = -depth * (s - center[0]), -depth * (t - center[1])
            labels[s, t, u0 + du : u1 + du, v0 + dv : v1 + dv] = 2
            disparity[s, t, u0 + du : u1 + du, v0 + dv : v1 + dv] = depth
    rng = np.random.default_rng(0)
    views = rng.integers(0, 255, (*labels.shape, 3), dtype=np.uint8)
    return LightField(views=views, disparity=disparity, labels=labels)


@settings(max_examples=40, deadline=None)
@given(
    grid=st.sampled_from([(5, 5), (3, 5), (7, 7), (5, 3)]),
    depth=st.sampled_from([1, 2, 3]),
    u0=st.integers(10, 14), v0=st.integers(10, 18), h=st.integers(3, 8), w=st.integers(3, 8),
    count=st.sampled_from([5, 9, "sparse"]),
)
def test_fill_is_exact_for_a_fronto_parallel_object(grid, depth, u0, v0, h, w, count):
    """With ground-truth disparity every filled view equals the ground truth exactly: the
    object moves by whole pixels, and background it uncovers comes from a source that sees it.
    (With the corners among the refined views every view lies between refined ones, so a
    convex object never hides a pixel from all of them; with refined views on one side only,
    e.g. N = 3, a strip can be hidden from all and is a guess.)"""
    lf = _rect_scene(grid, (32, 40), depth, (u0, v0, u0 + h, v0 + w))
    center = lf.center
    prompts = [
        ObjectPrompts(1, (PointPrompt(v0 + w // 2, u0 + h // 2),)),
        ObjectPrompts(2, (PointPrompt(1, 1),)),
    ]
    result = lfsam.segment(
        lf, prompts, model="oracle", disparity="gt", options=options(count)
    )
    expected = np.where(lf.labels == 2, 1, 2)
    assert np.array_equal(result.labels, expected)
    flags = np.array(result.meta["refined_views"])
    assert flags[center]
    assert result.meta["views_encoded"] == int(flags.sum())


def test_disocclusion_is_filled_from_the_other_side():
    """Background uncovered in the target view but hidden in the left source comes from the
    right source; with the left source alone it is wrong."""
    lf = _rect_scene((1, 3), (8, 20), 2, (2, 8, 6, 12))
    gt_disp = torch.from_numpy(lf.disparity)
    masks = torch.from_numpy(lf.labels == 2)[..., None, :, :]  # (1, 3, 1, U, V)
    target = (0, 1)
    sources = [(0, 0), (0, 2)]
    warps = [forward_warp(gt_disp[s], 0, target[1] - s[1]) for s in sources]
    fallback = torch.zeros((1, 8, 20), dtype=torch.bool)
    truth = masks[target]
    both = fill_from_sources(
        [masks[s] for s in sources], [gt_disp[s] for s in sources], warps, [1.0, 1.0],
        fallback, 0.2,
    )
    assert torch.equal(both.masks, truth)
    left = fill_from_sources([masks[sources[0]]], [gt_disp[sources[0]]], warps[:1], [1.0],
                             fallback, 0.2)
    assert not torch.equal(left.masks, truth)
    knowledge = source_knowledge(warps, (8, 20))
    # the left source sees the uncovered strip only as holes, the right one landed there
    uncovered = (knowledge[0] < 2) & (knowledge[1] == 2)
    assert uncovered.any()
    assert torch.equal(both.masks[0][uncovered], truth[0][uncovered])


def test_fill_keeps_the_fallback_where_no_source_sees():
    one = torch.ones((1, 4))
    warps = [forward_warp(one, 0, 2)]  # shifts left by 2: the right two pixels are unseen
    fallback = torch.tensor([[[False, False, True, False]]])
    masks = torch.ones((1, 1, 4), dtype=torch.bool)
    out = fill_from_sources([masks], [one], warps, [1.0], fallback, 0.2)
    assert out.masks.tolist() == [[[True, True, True, False]]]
    assert out.voters[0, 0].tolist() == [True, True, False, False]



@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 6))
def test_guided_votes_do_not_depend_on_batching(seed, count):
    """The contested votes of several objects filtered together (one box) or box by box give
    each object the answer it gets alone."""
    from lfsam.pipeline.fill import _guide_contested

    gen = torch.Generator().manual_seed(seed)
    height, width = 30, 40
    share = torch.zeros((count, height, width))
    for k in range(count):
        r0, c0 = (int(x) for x in torch.randint(0, 25, (2,), generator=gen))
        h, w = (int(x) for x in torch.randint(2, 20, (2,), generator=gen))
        block = share[k, r0 : r0 + h, c0 : c0 + w]
        block.copy_(torch.rand(block.shape, generator=gen).round(decimals=1))
    guide = torch.rand((height, width), generator=gen)
    together = share > 0.5
    _guide_contested(together, share, guide)
    for k in range(count):
        alone = share[k : k + 1] > 0.5
        _guide_contested(alone, share[k : k + 1], guide)
        assert torch.equal(together[k], alone[0])

# --- the pipeline with sparse refinement -------------------------------------------------------
@pytest.fixture(scope="module")
def scene():
    return generate_scene(grid=(5, 5), size=(48, 64), seed=3, num_objects=3)


def test_every_view_selected_gives_the_labels_of_all(scene):
    full = lfsam.segment(scene, model="oracle", disparity="gt", options=options("all"))
    every = lfsam.segment(scene, model="oracle", disparity="gt", options=options(25))
    assert np.array_equal(full.labels, every.labels)
    assert every.meta["views_encoded"] == 25
    assert np.array(every.meta["refined_views"]).all()


@pytest.mark.parametrize("disparity", ["gt", "estimate"])
def test_sparse_is_accurate_and_encodes_few_views(scene, disparity):
    full = lfsam.segment(scene, model="oracle", disparity=disparity, options=options("all"))
    sparse = lfsam.segment(scene, model="oracle", disparity=disparity, options=options("sparse"))
    assert sparse.meta["views_encoded"] == 9
    assert sparse.meta["config"]["refine_views"] == "sparse"
    flags = np.array(sparse.meta["refined_views"])
    assert flags.sum() == 9 and flags[0, 0] and flags[2, 2] and flags[4, 4]
    acc_full = per_view_iou(full.labels, scene.labels)
    acc_sparse = per_view_iou(sparse.labels, scene.labels)
    assert acc_sparse.mean >= 0.97
    assert acc_sparse.mean >= acc_full.mean - 0.02
    # the refined views hold what refinement gives there, the others are filled
    assert np.array_equal(sparse.labels[flags], full.labels[flags])


def test_an_object_prompted_outside_the_pattern_is_refined_in_its_view(scene):
    outer = (1, 3)  # not among the 9 views of 5x5 sparse
    mask = scene.labels[outer] == scene.labels[outer][24, 40]
    u, v = np.argwhere(mask)[len(np.argwhere(mask)) // 2]
    prompts = [ObjectPrompts(1, (PointPrompt(float(v), float(u), view=outer),))]
    result = lfsam.segment(scene, prompts, model="oracle", disparity="gt",
                           options=options("sparse"))
    flags = np.array(result.meta["refined_views"])
    assert flags[outer] and flags.sum() == 10
    assert result.meta["views_encoded"] == 10
    assert np.array_equal(result.labels[outer] == 1, mask)


def test_predictor_finishes_the_remaining_views(scene):
    from lfsam.predictor import LightFieldPredictor
    from lfsam.segmenters import load_segmenter

    predictor = LightFieldPredictor(load_segmenter("oracle", lightfield=scene),
                                    PipelineConfig(refine_views="sparse"))
    predictor.set_lightfield(scene, disparity="gt")
    predictor.add_prompts(1, points=[(40.0, 24.0)])
    predictor.add_prompts(2, points=[(5.0, 5.0)])
    sparse = predictor.predict().labels.copy()
    assert predictor.views_encoded == 9
    assert predictor.refined_views.sum() == 9
    predictor.set_refine_views("all")
    finished = predictor.predict().labels
    assert predictor.views_encoded == 25  # the 9 are not encoded again
    assert predictor.refined_views.all()
    fresh = LightFieldPredictor(load_segmenter("oracle", lightfield=scene))
    fresh.set_lightfield(scene, disparity="gt")
    fresh.add_prompts(1, points=[(40.0, 24.0)])
    fresh.add_prompts(2, points=[(5.0, 5.0)])
    assert np.array_equal(finished, fresh.predict().labels)
    assert not np.array_equal(sparse, finished)


def test_incremental_edit_equals_a_fresh_sparse_run(scene):
    """Objects are filled one at a time with the same answer as all together."""
    from lfsam.predictor import LightFieldPredictor
    from lfsam.segmenters import load_segmenter

    def run(edits):
        predictor = LightFieldPredictor(load_segmenter("oracle", lightfield=scene),
                                        PipelineConfig(refine_views="sparse"))
        predictor.set_lightfield(scene, disparity="gt")
        for obj_id, xy in edits:
            predictor.add_prompts(obj_id, points=[xy])
            predictor.predict()
        return predictor.predict().labels

    stepwise = run([(1, (40.0, 24.0)), (2, (5.0, 5.0))])
    together = LightFieldPredictor(load_segmenter("oracle", lightfield=scene),
                                   PipelineConfig(refine_views="sparse"))
    together.set_lightfield(scene, disparity="gt")
    together.add_prompts(1, points=[(40.0, 24.0)])
    together.add_prompts(2, points=[(5.0, 5.0)])
    assert np.array_equal(stepwise, together.predict().labels)


def test_masks_in_view_matches_the_full_pass(scene):
    from lfsam.predictor import LightFieldPredictor
    from lfsam.segmenters import load_segmenter

    predictor = LightFieldPredictor(load_segmenter("oracle", lightfield=scene),
                                    PipelineConfig(refine_views="sparse"))
    predictor.set_lightfield(scene, disparity="gt")
    predictor.add_prompts(1, points=[(40.0, 24.0)])
    single = predictor.masks_in_view([1], (1, 2))  # a filled view
    labels = predictor.predict().labels
    assert np.array_equal(single[0], labels[1, 2] == 1)


def test_video_baseline_refuses_refine_views(scene):
    with pytest.raises(LfsamError, match="needs --method lfsam"):
        lfsam.segment(scene, model="oracle", disparity="gt", options=SegmentOptions(
            pipeline=PipelineConfig(refine_views="sparse"),
            run=RunOptions(method="video-baseline", progress=False)))


# --- CLI -------------------------------------------------------------------------------------
def test_cli_segment_sparse(tmp_path, capsys):
    from lfsam.cli.main import main

    scene_dir = tmp_path / "scene"
    assert main(["synth", str(scene_dir), "--grid", "5x5", "--size", "48x64", "--objects", "2",
                 "--seed", "1"]) == 0
    out = tmp_path / "r.npz"
    assert main(["segment", str(scene_dir), "--auto", "--model", "oracle", "--disparity", "gt",
                 "--refine-views", "sparse", "--quiet", "--out", str(out)]) == 0
    result = lfsam.load_result(out)
    assert result.meta["views_encoded"] == 9
    assert np.array(result.meta["refined_views"]).sum() == 9
    capsys.readouterr()
    with pytest.raises(SystemExit) as exit_info:
        main(["segment", str(scene_dir), "--auto", "--model", "oracle", "--refine-views", "0",
              "--out", str(tmp_path / "x.npz")])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "--refine-views" in err and "all, sparse or a number" in err
    assert not (tmp_path / "x.npz").exists()
    summary = json.loads(json.dumps(result.meta["config"]))
    assert summary["refine_views"] == "sparse"


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 4), st.integers(1, 4), st.booleans())
def test_fill_without_host_checks_gives_the_same_masks(seed, sources, objects, guided):
    """The GPU form of the fill (every source's vote computed, none asked first whether it
    votes anywhere, holes filled densely: no host round trips, issue 44) gives the CPU form's
    masks and voters."""
    from lfsam.pipeline import fill as fill_module

    rng = np.random.default_rng(seed)
    size = (int(rng.integers(4, 16)), int(rng.integers(4, 16)))
    offsets = [(int(rng.integers(-2, 3)), int(rng.integers(-2, 3))) for _ in range(sources)]
    disparities = [torch.as_tensor(rng.uniform(-1.5, 1.5, size), dtype=torch.float32)
                   for _ in offsets]
    warps = [forward_warp(d, s, t) for d, (s, t) in zip(disparities, offsets, strict=True)]
    masks = [torch.as_tensor(rng.random((objects, *size)) < 0.4) for _ in offsets]
    fallback = torch.as_tensor(rng.random((objects, *size)) < 0.3)
    guide = torch.as_tensor(rng.random(size), dtype=torch.float32) if guided else None
    distances = [1.0 + float(rng.random()) for _ in offsets]
    cpu = fill_from_sources(masks, disparities, warps, distances, fallback, 0.2, guide=guide,
                            contested=0.2)
    original = fill_module._skip_idle_sources
    try:
        fill_module._skip_idle_sources = lambda device: False
        gpu = fill_from_sources(masks, disparities, warps, distances, fallback, 0.2,
                                guide=guide, contested=0.2)
    finally:
        fill_module._skip_idle_sources = original
    assert torch.equal(cpu.masks, gpu.masks)
    assert torch.equal(cpu.voters, gpu.voters)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_reach_boxes_in_one_copy_match_the_flagged_lines(seed):
    """Each object's box (first to one past the last flagged row and column, widened by the
    filter's reach, clipped to the view), read back in one copy, is the box its flags give."""
    from lfsam.pipeline.fill import GUIDE_RADIUS, _reach_boxes

    rng = np.random.default_rng(seed)
    count, height, width = (int(v) for v in rng.integers(1, 12, 3))
    flags = torch.as_tensor(rng.random((count, height, width)) < rng.random() * 0.2)
    rows, cols = flags.any(dim=2), flags.any(dim=1)
    found, *boxes = _reach_boxes(rows, cols)
    reach = 2 * GUIDE_RADIUS
    for k in range(count):
        assert found[k] == bool(flags[k].any())
        if not found[k]:
            continue
        r = np.flatnonzero(rows[k].numpy())
        c = np.flatnonzero(cols[k].numpy())
        assert boxes[k] == (max(r[0] - reach, 0), min(r[-1] + reach + 1, height),
                            max(c[0] - reach, 0), min(c[-1] + reach + 1, width))
