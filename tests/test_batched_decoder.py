"""The batched decoder (issue 44; docs/design.md section 3.5): prompts of several views through
one decoder call, prompts kept on the device.

Every expected value comes from the per-view path (``decode_prompts`` of each view,
``Segmenter.predict`` view by view, a pipeline run decoding view by view) on the same tiny
random-weight SAM 2.1 (``sam2-tiny-test``) or the oracle.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch

from lfsam.api import RunOptions, SegmentOptions, segment
from lfsam.errors import LfsamError
from lfsam.pipeline import PipelineConfig
from lfsam.prompts import ObjectPrompts, PointPrompt
from lfsam.segmenters import Prompts, load_segmenter
from lfsam.segmenters.sam2.decoder import decode_prompts, embed_prompts, prepare_image
from lfsam.segmenters.sam2.multiview import decode_views, stack_states
from lfsam.synth import generate_scene


@pytest.fixture(scope="module")
def tiny():
    return load_segmenter("sam2-tiny-test", device="cpu", random_weights=True).model


def _views(model, count: int, n: int):
    """Random features of ``count`` images and ``n`` point+box prompts on each."""
    gen = torch.Generator().manual_seed(3)
    c, h, size = model.sam_mask_decoder.transformer_dim, model.image_size // 16, model.image_size
    feats, prompts = [], []
    for _ in range(count):
        embed = torch.randn(1, c, h, h, generator=gen)
        high = [torch.randn(1, c // 8, 4 * h, 4 * h, generator=gen),
                torch.randn(1, c // 4, 2 * h, 2 * h, generator=gen)]
        coords = torch.rand(n, 2, 2, generator=gen) * size
        labels = torch.tensor([[1, 0]] * n, dtype=torch.int32)
        corners = torch.sort(torch.rand(n, 2, 2, generator=gen) * size, dim=1).values
        feats.append((embed, high))
        prompts.append((coords, labels, corners.reshape(n, 4)))
    return feats, prompts


@pytest.mark.parametrize("chunk_size", [1, 2, 5, 64])
def test_decode_views_equals_decoding_each_view(tiny, chunk_size):
    feats, prompts = _views(tiny, count=3, n=4)
    with torch.no_grad():
        expected = [decode_prompts(tiny, e, h, *p, True)
                    for (e, h), p in zip(feats, prompts, strict=True)]
        states = [prepare_image(tiny, e, h) for e, h in feats]
        sparse = torch.cat([embed_prompts(tiny, *p) for p in prompts])
        views = torch.repeat_interleave(torch.arange(3), 4)
        # prompts of the views interleaved: every chunk mixes views
        order = torch.arange(12).view(3, 4).t().reshape(-1)
        logits, iou = decode_views(tiny, states, sparse[order], views[order], True, chunk_size)
    want = torch.cat([x[0] for x in expected])[order]
    want_iou = torch.cat([x[1] for x in expected])[order]
    torch.testing.assert_close(logits, want, atol=1e-5, rtol=0)
    torch.testing.assert_close(iou, want_iou, atol=1e-6, rtol=0)
    assert torch.equal(logits > 0, want > 0)


def test_decode_views_checks_its_input(tiny):
    feats, prompts = _views(tiny, count=2, n=2)
    with torch.no_grad():
        states = [prepare_image(tiny, e, h) for e, h in feats]
        sparse = embed_prompts(tiny, *prompts[0])
        with pytest.raises(LfsamError, match="view indices"):
            decode_views(tiny, states, sparse, torch.zeros(3, dtype=torch.long), True, 2)
        with pytest.raises(LfsamError, match="no image states"):
            stack_states([])
        empty, ious = decode_views(tiny, states, sparse[:0], torch.zeros(0, dtype=torch.long),
                                   False, 2)
    assert empty.shape[:2] == (0, 1) and ious.shape == (0, 1)


def _embeddings(segmenter, count: int):
    lf = generate_scene(grid=(1, count), size=(40, 56), seed=5, num_objects=3)
    return lf, segmenter.encode(lf.views[0], keys=[(0, t) for t in range(count)])


def _device_prompts(n: int, seed: int) -> Prompts:
    gen = torch.Generator().manual_seed(seed)
    points = torch.rand(n, 1, 2, generator=gen) * torch.tensor([56.0, 40.0])
    corners = torch.sort(torch.rand(n, 2, 2, generator=gen) * torch.tensor([56.0, 40.0]), dim=1)
    return Prompts(points=points, point_labels=torch.ones(n, 1, dtype=torch.int64),
                   boxes=corners.values.reshape(n, 4))


@pytest.mark.parametrize("model", ["sam2-tiny-test", "edgetam-tiny-test"])
def test_predict_many_across_views_gives_the_masks_of_predict(model):
    segmenter = load_segmenter(model, device="cpu", random_weights=True, cross_view_decode=True)
    _, embeddings = _embeddings(segmenter, 3)
    prompts = [_device_prompts(n, seed) for seed, n in enumerate((3, 1, 4))]
    assert isinstance(prompts[0].points, torch.Tensor)  # tensors stay tensors
    before = segmenter.decoder_calls
    many = segmenter.predict_many(embeddings, prompts)
    assert segmenter.decoder_calls - before == 1  # the three views in one decoder call
    for embedding, batch, got in zip(embeddings, prompts, many, strict=True):
        want = segmenter.predict(embedding, batch)
        assert torch.equal(got.masks, want.masks)
        torch.testing.assert_close(got.iou_predictions, want.iou_predictions, atol=1e-6,
                                   rtol=0)
        torch.testing.assert_close(got.low_res_logits, want.low_res_logits, atol=1e-5, rtol=0)


def test_the_default_predict_many_decodes_view_by_view():
    lf = generate_scene(grid=(1, 2), size=(40, 56), seed=5, num_objects=3)
    oracle = load_segmenter("oracle", lightfield=lf)
    embeddings = oracle.encode(lf.views[0], keys=[(0, 0), (0, 1)])
    prompts = [_device_prompts(2, 1), _device_prompts(3, 2)]
    many = oracle.predict_many(embeddings, prompts)
    for embedding, batch, got in zip(embeddings, prompts, many, strict=True):
        assert torch.equal(got.masks, oracle.predict(embedding, batch).masks)
    with pytest.raises(LfsamError, match="one Prompts per view"):
        oracle.predict_many(embeddings, prompts[:1])


def _run(lf, model, refine_views, batch, **options):
    segmenter = load_segmenter(model, lightfield=lf, **options)
    config = PipelineConfig(refine_views=refine_views, encode_batch_size=batch)
    prompts = [ObjectPrompts(i + 1, (PointPrompt(x, y),))
               for i, (x, y) in enumerate([(14, 12), (40, 20), (28, 33)])]
    result = segment(lf, None if model == "oracle" else prompts, model=segmenter,
                     disparity="gt", options=SegmentOptions(pipeline=config,
                                                            run=RunOptions(progress=False)))
    return result, segmenter


@pytest.mark.parametrize("refine_views", ["all", "sparse"])
def test_pipeline_labels_with_views_decoded_together_equal_view_by_view(refine_views):
    lf = generate_scene(grid=(5, 5), size=(40, 56), seed=2, num_objects=3)
    tiny = {"random_weights": True, "device": "cpu"}
    one, per_view = _run(lf, "sam2-tiny-test", refine_views, 1, cross_view_decode=False, **tiny)
    many, batched = _run(lf, "sam2-tiny-test", refine_views, 6, cross_view_decode=True, **tiny)
    assert batched.decoder_calls < per_view.decoder_calls  # views really shared calls
    assert not one.fallback.all()  # refinement kept refined masks: the comparison means something
    np.testing.assert_array_equal(many.labels, one.labels)
    np.testing.assert_array_equal(many.fallback, one.fallback)
    np.testing.assert_allclose(many.refine_iou, one.refine_iou, atol=1e-6)


def test_oracle_labels_do_not_depend_on_how_views_are_batched():
    lf = generate_scene(grid=(5, 5), size=(40, 56), seed=2, num_objects=3)
    one, _ = _run(lf, "oracle", "all", 1)
    many, _ = _run(lf, "oracle", "all", 6)
    np.testing.assert_array_equal(many.labels, one.labels)
    np.testing.assert_array_equal(many.refine_iou, one.refine_iou)


def test_dense_mask_iou_counts_as_the_sparse_one():
    gen = torch.Generator().manual_seed(4)
    cand = torch.rand(6, 3, 9, 13, generator=gen) > 0.5
    ref = torch.rand(6, 9, 13, generator=gen) > 0.6
    ref[2] = False  # an empty reference
    region = torch.rand(9, 13, generator=gen) > 0.2
    from lfsam.pipeline.refinement import mask_iou

    for reg in (None, region):
        assert torch.equal(mask_iou(cand, ref, reg, dense=True), mask_iou(cand, ref, reg,
                                                                          dense=False))


def test_compiled_decoder_pass_with_static_shapes_gives_the_same_masks():
    """``compile_decoder``: TorchDynamo traces the pass (the ``eager`` backend: no C++ compiler
    needed, seconds on a CPU); passes padded to one shape, the padding dropped."""
    plain = load_segmenter("sam2-tiny-test", device="cpu", random_weights=True,
                           cross_view_decode=True, cross_view_rows=3)
    compiled = load_segmenter("sam2-tiny-test", device="cpu", random_weights=True,
                              cross_view_decode=True, cross_view_rows=3, compile_decoder="eager")
    _, embeddings = _embeddings(plain, 2)
    prompts = [_device_prompts(n, seed) for seed, n in enumerate((2, 3))]  # passes of 3 and 2
    want = plain.predict_many(embeddings, prompts)
    got = compiled.predict_many(embeddings, prompts)
    for a, b in zip(got, want, strict=True):
        assert a.masks.shape == b.masks.shape
        assert torch.equal(a.masks, b.masks)
        torch.testing.assert_close(a.low_res_logits, b.low_res_logits, atol=1e-5, rtol=0)


@pytest.mark.cuda
def test_cuda_views_decoded_together_match_view_by_view_and_the_cpu():
    """On CUDA (``make gpu-check``), float32: the cross-view decoder's labels against view by
    view on the GPU and against the CPU (float rounding differs between the three, so a few
    pixels on a mask's edge may flip: at most 0.1 %)."""
    lf = generate_scene(grid=(5, 5), size=(40, 56), seed=2, num_objects=3)
    gpu = {"random_weights": True, "device": "cuda", "precision": "float32"}
    together, batched = _run(lf, "sam2-tiny-test", "all", 6, cross_view_decode=True, **gpu)
    apart, per_view = _run(lf, "sam2-tiny-test", "all", 6, cross_view_decode=False, **gpu)
    cpu, _ = _run(lf, "sam2-tiny-test", "all", 1, random_weights=True, device="cpu")
    assert batched.decoder_calls < per_view.decoder_calls
    assert (together.labels == apart.labels).mean() >= 0.999
    assert (together.labels == cpu.labels).mean() >= 0.999
