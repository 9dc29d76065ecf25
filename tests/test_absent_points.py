"""Absent points (label ``ABSENT_POINT``): prompts of different lengths in one decoder call.

A prompt padded with absent points must answer as the prompt without them (docs/design.md
section 3.5, "one decoder call for prompts of different lengths"). Expected values are the
unpadded prompts decoded by the same code; each SAM 2 test also checks that the padding,
attended to as SAM 2's own padding label -1, would change the answer (so it can fail).
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from lfsam.pipeline.occlusion import uniform_weights
from lfsam.pipeline.refinement import RefineRequest, refine_many
from lfsam.segmenters import Prompts, load_segmenter
from lfsam.segmenters.base import ABSENT_POINT
from lfsam.segmenters.oracle import OracleSegmenter
from lfsam.segmenters.sam2.decoder import (
    absent_tokens,
    decode_prompts,
    embed_prompts,
    prepare_image,
)
from lfsam.segmenters.sam2.multiview import decode_views, stack_states
from lfsam.synth import generate_scene

LOGIT_ATOL = 1e-4


@pytest.fixture(scope="module")
def tiny():
    return load_segmenter("sam2-tiny-test", device="cpu", random_weights=True).model


def _features(model, seed: int):
    gen = torch.Generator().manual_seed(seed)
    c, h = model.sam_mask_decoder.transformer_dim, model.image_size // 16
    embed = torch.randn(1, c, h, h, generator=gen)
    high = [torch.randn(1, c // 8, 4 * h, 4 * h, generator=gen),
            torch.randn(1, c // 4, 2 * h, 2 * h, generator=gen)]
    return embed, high


def _padded(coords, labels, where: list[int], seed: int):
    """The prompts with one absent point inserted before each position in ``where`` (at
    random coordinates: they must not matter)."""
    gen = torch.Generator().manual_seed(seed)
    n = coords.shape[0]
    c, lab = coords, labels
    for at in sorted(where, reverse=True):
        junk = torch.rand(n, 1, 2, generator=gen) * 100.0
        c = torch.cat([c[:, :at], junk, c[:, at:]], dim=1)
        lab = torch.cat([lab[:, :at], torch.full((n, 1), ABSENT_POINT, dtype=lab.dtype),
                         lab[:, at:]], dim=1)
    return c, lab


@pytest.mark.parametrize("with_box", [False, True])
@pytest.mark.parametrize("multimask", [True, False])
def test_absent_points_leave_the_answer_of_sam2s_decoder(tiny, with_box, multimask):
    embed, high = _features(tiny, 0)
    gen = torch.Generator().manual_seed(1)
    n, size = 5, float(tiny.image_size)
    coords = torch.rand(n, 2, 2, generator=gen) * size
    labels = torch.tensor([[1, 0], [1, 1], [1, 0], [1, 1], [1, -1]], dtype=torch.int32)
    boxes = None
    if with_box:
        boxes = torch.sort(torch.rand(n, 2, 2, generator=gen) * size, dim=1).values.reshape(n, 4)
    want_logits, want_iou = decode_prompts(tiny, embed, high, coords, labels, boxes, multimask)
    padded = _padded(coords, labels, [0, 1, 2, 2], seed=2)  # before, between and after
    logits, iou = decode_prompts(tiny, embed, high, *padded, boxes, multimask,
                                 absent_points=True)
    torch.testing.assert_close(logits, want_logits, atol=LOGIT_ATOL, rtol=0)
    torch.testing.assert_close(iou, want_iou, atol=1e-5, rtol=0)
    attended, _ = decode_prompts(tiny, embed, high, *padded, boxes, multimask)
    assert (attended - want_logits).abs().max() > 100 * LOGIT_ATOL  # SAM 2's padding is a token


def test_absent_tokens_follow_the_prompt_encoders_layout(tiny):
    labels = torch.tensor([[1, ABSENT_POINT, 0]])
    coords = torch.zeros(1, 3, 2)
    box = torch.tensor([[1.0, 2.0, 30.0, 40.0]])
    for boxes, expect in ((None, [0, 1, 0, 0]), (box, [0, 0, 0, 1, 0, 0])):
        mask = absent_tokens(tiny, labels, boxes)
        assert mask.tolist() == [[bool(x) for x in expect]]
        assert mask.shape[1] == embed_prompts(tiny, coords, labels, boxes).shape[1]
    assert absent_tokens(tiny, None, box) is None


def test_absent_points_across_views_in_one_pass(tiny):
    """decode_views: prompts of two views, one padded, one pass; each as decoded alone."""
    feats = [_features(tiny, seed) for seed in (3, 4)]
    states = [prepare_image(tiny, e, h) for e, h in feats]
    gen = torch.Generator().manual_seed(5)
    size = float(tiny.image_size)
    short = (torch.rand(2, 1, 2, generator=gen) * size, torch.ones(2, 1, dtype=torch.int32))
    long = (torch.rand(3, 3, 2, generator=gen) * size,
            torch.tensor([[1, 0, 1]] * 3, dtype=torch.int32))
    boxes = torch.sort(torch.rand(5, 2, 2, generator=gen) * size, dim=1).values.reshape(5, 4)
    want = [decode_prompts(tiny, *feats[0], *short, boxes[:2], True)[0],
            decode_prompts(tiny, *feats[1], *long, boxes[2:], True)[0]]
    short_padded = _padded(*short, [1, 1], seed=6)
    coords = torch.cat([short_padded[0], long[0]])
    labels = torch.cat([short_padded[1], long[1]])
    sparse = embed_prompts(tiny, coords, labels, boxes)
    views = torch.tensor([0, 0, 1, 1, 1])
    with torch.no_grad():
        got, _ = decode_views(tiny, stack_states(states), sparse, views, True, chunk_size=5,
                              absent=absent_tokens(tiny, labels, boxes))
        attended, _ = decode_views(tiny, stack_states(states), sparse, views, True, chunk_size=5)
    torch.testing.assert_close(got, torch.cat(want), atol=LOGIT_ATOL, rtol=0)
    assert (attended[:2] - want[0]).abs().max() > 100 * LOGIT_ATOL


def _scene_prompts(n_points: list[int], seed: int, absent_width: int | None = None) -> Prompts:
    """Point+box prompts on a 40 x 56 view with ``n_points[i]`` points each; padded with absent
    points to ``absent_width`` points (all must have the same count without it)."""
    rng = np.random.default_rng(seed)
    width = absent_width or max(n_points)
    points = rng.uniform(0, 1, (len(n_points), width, 2)) * [56.0, 40.0]
    labels = np.full((len(n_points), width), ABSENT_POINT)
    for i, count in enumerate(n_points):
        labels[i, :count] = rng.integers(0, 2, count)
        labels[i, 0] = 1
    corners = np.sort(rng.uniform(0, 1, (len(n_points), 2, 2)) * [56.0, 40.0], axis=1)
    return Prompts(points=points.astype(np.float32), point_labels=labels,
                   boxes=corners.reshape(-1, 4).astype(np.float32))


def _alone(batch: Prompts, i: int) -> Prompts:
    """Prompt ``i`` of ``batch`` without its absent points."""
    labels = np.asarray(batch.point_labels)
    count = int((labels[i] != ABSENT_POINT).sum())
    return Prompts(points=np.asarray(batch.points)[i : i + 1, :count],
                   point_labels=labels[i : i + 1, :count],
                   boxes=np.asarray(batch.boxes)[i : i + 1])


@pytest.mark.parametrize("model", ["sam2-tiny-test", "edgetam-tiny-test"])
def test_segmenters_answer_padded_prompts_as_the_prompts_alone(model):
    segmenter = load_segmenter(model, device="cpu", random_weights=True, cross_view_decode=True)
    assert segmenter.skips_absent_points
    lf = generate_scene(grid=(1, 2), size=(40, 56), seed=5, num_objects=3)
    embeddings = segmenter.encode(lf.views[0], keys=[(0, 0), (0, 1)])
    padded = [_scene_prompts([1, 3, 2], 7, absent_width=3), _scene_prompts([2, 1], 8, 3)]
    assert all(p.absent_points for p in padded)
    before = segmenter.decoder_calls
    many = segmenter.predict_many(embeddings, padded)
    assert segmenter.decoder_calls - before == 1
    for embedding, batch, got in zip(embeddings, padded, many, strict=True):
        single = segmenter.predict(embedding, batch)
        assert torch.equal(single.masks, got.masks)
        for i in range(len(batch)):
            alone = segmenter.predict(embedding, _alone(batch, i))
            torch.testing.assert_close(got.low_res_logits[i : i + 1], alone.low_res_logits,
                                       atol=LOGIT_ATOL, rtol=0)
            mismatch = (got.masks[i] != alone.masks[0]).float().mean().item()
            assert mismatch < 1e-3  # rounding may flip a pixel on a logit of about 0


def test_the_oracle_ignores_absent_points_exactly():
    lf = generate_scene(grid=(1, 1), size=(40, 56), seed=5, num_objects=4)
    oracle = OracleSegmenter(lf, boundary_jitter=1, merge_prob=0.5, seed=3)
    assert oracle.skips_absent_points
    embedding = oracle.encode(lf.views[0, :1], keys=[(0, 0)])[0]
    padded = _scene_prompts([1, 3, 2, 1], 9, absent_width=3)
    got = oracle.predict(embedding, padded)
    for i in range(len(padded)):
        alone = oracle.predict(embedding, _alone(padded, i))
        assert torch.equal(got.masks[i], alone.masks[0])


def test_prompts_know_whether_they_hold_absent_points():
    assert _scene_prompts([1, 2], 1, absent_width=2).absent_points
    assert not _scene_prompts([2, 2], 1).absent_points
    assert not Prompts(boxes=np.zeros((1, 4))).absent_points
    device = Prompts(points=torch.zeros(1, 2, 2), point_labels=torch.tensor([[1, ABSENT_POINT]]))
    assert device.absent_points and device.subset(slice(0, 1)).absent_points
    told = Prompts(points=torch.zeros(1, 1, 2), point_labels=torch.ones(1, 1), absent_points=False)
    assert told.absent_points is False


def test_refinement_pads_carried_clicks_into_one_call_for_sam2(monkeypatch):
    """Masks carrying 0, 1 and 2 clicks in two views: one predict_many call with the padding
    (against one per click count and view shape without it), the same refined masks."""
    lf = generate_scene(grid=(1, 2), size=(48, 64), seed=1, num_objects=4)
    segmenter = load_segmenter("sam2-tiny-test", device="cpu", random_weights=True,
                               cross_view_decode=True)
    embeddings = segmenter.encode(lf.views[0], keys=[(0, 0), (0, 1)])
    requests = []
    for t, embedding in enumerate(embeddings):
        ids = np.unique(lf.labels[0, t])[1:]
        coarse = torch.as_tensor(np.stack([lf.labels[0, t] == k for k in ids]))
        n = len(ids)
        points = np.zeros((n, 2, 2), np.float32)
        labels = np.full((n, 2), -1, np.int64)
        for k in range(n):
            rows, cols = np.nonzero(coarse[k].numpy())
            for j in range((k + t) % 3):
                points[k, j] = (cols[j], rows[j])
                labels[k, j] = 1
        requests.append(RefineRequest(embedding, coarse, uniform_weights(coarse),
                                      extra_points=(points, labels)))

    calls = []
    predict_many = segmenter.predict_many

    def counted(*args, **kwargs):
        calls.append(len(args[0]))
        return predict_many(*args, **kwargs)

    monkeypatch.setattr(segmenter, "predict_many", counted)
    merged = refine_many(segmenter, requests)
    assert calls == [2]  # both views, every click count, one call
    calls.clear()
    monkeypatch.setattr(segmenter, "skips_absent_points", False)
    grouped = refine_many(segmenter, requests)
    assert len(calls) == 3  # one call per click count (0, 1, 2), views together
    for a, b in zip(merged, grouped, strict=True):
        assert (a.masks != b.masks).float().mean().item() < 1e-3
        assert torch.equal(a.fallback, b.fallback)
        torch.testing.assert_close(a.iou, b.iou, atol=1e-3, rtol=0, equal_nan=True)


def test_the_compiled_pass_masks_absent_points():
    """``compile_decoder`` (traced by TorchDynamo, run eagerly): passes padded to one shape
    carry their absent-token masks along."""
    plain = load_segmenter("sam2-tiny-test", device="cpu", random_weights=True,
                           cross_view_decode=True, cross_view_rows=3)
    compiled = load_segmenter("sam2-tiny-test", device="cpu", random_weights=True,
                              cross_view_decode=True, cross_view_rows=3, compile_decoder="eager")
    lf = generate_scene(grid=(1, 2), size=(40, 56), seed=5, num_objects=3)
    embeddings = plain.encode(lf.views[0], keys=[(0, 0), (0, 1)])
    prompts = [_scene_prompts([1, 2], 3, absent_width=2), _scene_prompts([2, 1, 1], 4, 2)]
    want = plain.predict_many(embeddings, prompts)
    got = compiled.predict_many(embeddings, prompts)
    for a, b in zip(got, want, strict=True):
        assert torch.equal(a.masks, b.masks)
        torch.testing.assert_close(a.low_res_logits, b.low_res_logits, atol=1e-5, rtol=0)


@pytest.mark.cuda
@pytest.mark.parametrize("precision", ["float32", "bfloat16"])
def test_cuda_absent_points_leave_the_answer(precision):
    """On CUDA (``make gpu-check``), the cross-view pass and its autocast: padded prompts of two
    views in one call against each prompt alone (float32 logits within 1e-4; bfloat16 rounds
    the two batches differently, so only the masks, at most 1 % of pixels apart)."""
    segmenter = load_segmenter("sam2-tiny-test", device="cuda", random_weights=True,
                               precision=precision, cross_view_decode=True)
    lf = generate_scene(grid=(1, 2), size=(40, 56), seed=5, num_objects=3)
    embeddings = segmenter.encode(lf.views[0], keys=[(0, 0), (0, 1)])
    padded = [_scene_prompts([1, 3, 2], 7, absent_width=3), _scene_prompts([2, 1], 8, 3)]
    many = segmenter.predict_many(embeddings, padded)
    for embedding, batch, got in zip(embeddings, padded, many, strict=True):
        for i in range(len(batch)):
            alone = segmenter.predict(embedding, _alone(batch, i))
            if precision == "float32":
                torch.testing.assert_close(got.low_res_logits[i : i + 1], alone.low_res_logits,
                                           atol=LOGIT_ATOL, rtol=0)
            assert (got.masks[i] != alone.masks[0]).float().mean().item() <= 0.01
