"""The SAM 2 backend on the tiny random-weight model: the official code path, encoded once.

Expected values come from Meta's own ``SAM2ImagePredictor`` and ``SAM2AutomaticMaskGenerator``
run the usual way (encoding the image themselves), or from decoding prompts one at a time.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
import torch.nn.functional as F
from hypothesis import given, settings
from hypothesis import strategies as st
from sam2.automatic_mask_generator import SAM2AutomaticMaskGenerator

from lfsam.errors import LfsamError
from lfsam.segmenters import Prompts, ViewEmbedding, load_segmenter
from lfsam.segmenters.sam2.backend import PAPER_AMG_OPTIONS, Sam2Features, Sam2Segmenter
from lfsam.segmenters.sam2.build import make_image_predictor

U, V = 32, 48  # a non-square view: the resize to the square input stretches each axis
AMG = {"points_per_side": 4, "pred_iou_thresh": 0.0, "stability_score_thresh": 0.0}


@pytest.fixture(scope="module")
def seg() -> Sam2Segmenter:
    segmenter = load_segmenter("sam2-tiny-test", device="cpu", amg_options=AMG, encode_batch_size=2)
    assert isinstance(segmenter, Sam2Segmenter)
    return segmenter


@pytest.fixture(scope="module")
def views() -> np.ndarray:
    rng = np.random.default_rng(7)
    base = rng.integers(0, 256, (3, U, V, 3), dtype=np.uint8)
    base[:, 8:20, 10:30] = (200, 40, 40)  # a flat object so masks have structure
    return base


@pytest.fixture(scope="module")
def embeddings(seg, views):
    return seg.encode(views, keys=[(0, 0), (0, 1), (0, 2)])


def _prompts(kind: str, n: int, seed: int = 0) -> Prompts:
    rng = np.random.default_rng(seed)
    points = rng.uniform((0, 0), (V - 1, U - 1), size=(n, 2, 2))
    labels = rng.integers(0, 2, size=(n, 2))
    labels[:, 0] = 1
    corners = np.sort(rng.uniform(0, min(U, V) - 1, size=(n, 2, 2)), axis=1)
    # x0, y0, x1, y1 with x0 <= x1 and y0 <= y1
    boxes = np.stack([corners[:, 0, 0], corners[:, 0, 1], corners[:, 1, 0], corners[:, 1, 1]], 1)
    if kind == "points":
        return Prompts(points=points, point_labels=labels)
    if kind == "boxes":
        return Prompts(boxes=boxes)
    return Prompts(points=points[:, :1], point_labels=labels[:, :1], boxes=boxes)


# --- encoding -------------------------------------------------------------------------------
def test_encode_matches_sam2_image_predictor(seg, views, embeddings):
    predictor = make_image_predictor(seg.model)
    assert [e.key for e in embeddings] == [(0, 0), (0, 1), (0, 2)]
    for view, emb in zip(views, embeddings, strict=True):
        predictor.set_image(view)
        expected = predictor._features
        assert emb.image_size == (U, V)
        assert emb.data.image_embed.shape == (1, 32, 16, 16)
        torch.testing.assert_close(emb.data.image_embed, expected["image_embed"])
        for got, want in zip(emb.data.high_res_feats, expected["high_res_feats"], strict=True):
            torch.testing.assert_close(got, want)


def test_encode_batches_do_not_change_features(seg, views, embeddings):
    assert seg.encode_batch_size == 2  # the three views went through as 2 + 1
    single = load_segmenter("sam2-tiny-test", device="cpu", encode_batch_size=1)
    for view, emb in zip(views, embeddings, strict=True):
        alone = single.encode(view[None])[0]
        torch.testing.assert_close(alone.data.image_embed, emb.data.image_embed)


def test_encode_rejects_bad_input(seg):
    with pytest.raises(LfsamError, match="uint8"):
        seg.encode(np.zeros((1, U, V, 3), dtype=np.float32))
    with pytest.raises(LfsamError, match="one key per view"):
        seg.encode(np.zeros((2, U, V, 3), dtype=np.uint8), keys=[(0, 0)])


# --- prompting ------------------------------------------------------------------------------
@pytest.mark.parametrize("multimask", [True, False])
@pytest.mark.parametrize("kind", ["points", "boxes", "points+boxes"])
def test_batched_decode_equals_single_decodes(seg, embeddings, kind, multimask):
    n = 6
    prompts = _prompts(kind, n)
    batch = seg.predict(embeddings[0], prompts, multimask_output=multimask)
    k = 3 if multimask else 1
    assert batch.masks.shape == (n, k, U, V) and batch.masks.dtype == torch.bool
    assert batch.iou_predictions.shape == (n, k)
    assert batch.low_res_logits.shape == (n, k, 64, 64)
    assert batch.masks.any() and not batch.masks.all()
    for i in range(n):
        one = seg.predict(embeddings[0], prompts.subset(slice(i, i + 1)), multimask)
        assert torch.equal(one.masks[0], batch.masks[i])
        torch.testing.assert_close(one.iou_predictions[0], batch.iou_predictions[i])
        torch.testing.assert_close(one.low_res_logits[0], batch.low_res_logits[i])


@pytest.mark.parametrize("kind", ["points", "points+boxes"])
def test_decode_matches_sam2_image_predictor(seg, views, embeddings, kind):
    prompts = _prompts(kind, 3, seed=1)
    ours = seg.predict(embeddings[1], prompts, multimask_output=True)
    predictor = make_image_predictor(seg.model)
    predictor.set_image(views[1])
    for i in range(3):
        masks, scores, logits = predictor.predict(
            point_coords=prompts.points[i],
            point_labels=prompts.point_labels[i],
            box=None if prompts.boxes is None else prompts.boxes[i],
            multimask_output=True,
        )
        assert np.array_equal(ours.masks[i].numpy(), masks.astype(bool))
        np.testing.assert_allclose(ours.iou_predictions[i].numpy(), scores, atol=1e-5)
        np.testing.assert_allclose(ours.low_res_logits[i].numpy(), logits, atol=1e-4)


def test_chunked_decode_equals_one_chunk(seg, embeddings):
    prompts = _prompts("points+boxes", 7, seed=2)
    whole = seg.predict(embeddings[2], prompts)
    seg.max_prompts_per_batch = 3
    try:
        chunked = seg.predict(embeddings[2], prompts)
    finally:
        seg.max_prompts_per_batch = 64
    assert torch.equal(chunked.masks, whole.masks)
    torch.testing.assert_close(chunked.iou_predictions, whole.iou_predictions)


def test_padding_points_are_ignored(seg, embeddings):
    """Label -1 marks "not a point" (SAM's padding), so prompts of different lengths batch."""
    point = [20.0, 10.0]
    pad_here = Prompts(points=[[point, [0.0, 0.0]]], point_labels=[[1, -1]])
    pad_there = Prompts(points=[[point, [40.0, 25.0]]], point_labels=[[1, -1]])
    negative = Prompts(points=[[point, [40.0, 25.0]]], point_labels=[[1, 0]])
    a = seg.predict(embeddings[0], pad_here)
    b = seg.predict(embeddings[0], pad_there)
    c = seg.predict(embeddings[0], negative)
    assert torch.equal(a.masks, b.masks)
    torch.testing.assert_close(a.low_res_logits, b.low_res_logits)
    assert not torch.allclose(b.low_res_logits, c.low_res_logits)


def test_returned_tensors_are_ordinary(seg, embeddings):
    pred = seg.predict(embeddings[0], _prompts("points", 2))
    pred.masks[0, 0, 0, 0] = True  # in-place edits work (not inference-mode tensors)
    pred.iou_predictions += 1
    assert pred.iou_predictions.dtype == torch.float32
    none = Prompts(boxes=np.zeros((0, 4)))
    assert seg.predict(embeddings[0], none).masks.shape == (0, 3, U, V)


# --- automatic generation -------------------------------------------------------------------
@pytest.mark.filterwarnings("ignore:.*torch.jit.script:FutureWarning")
def test_generate_matches_official_generator_without_reencoding(seg, views, embeddings):
    official = SAM2AutomaticMaskGenerator(seg.model, **{**PAPER_AMG_OPTIONS, **AMG})
    official.predictor = make_image_predictor(seg.model)
    records = official.generate(views[0])
    assert records, "thresholds at 0 must keep some masks"

    calls = {"views": 0}
    forward = seg.model.forward_image

    def counting(x):
        calls["views"] += x.shape[0]
        return forward(x)

    seg.model.forward_image = counting
    try:
        auto = seg.generate(embeddings[0], views[0])
    finally:
        del seg.model.forward_image
    assert calls["views"] == 0
    assert auto.masks.shape == (len(records), U, V) and auto.masks.dtype == bool
    expected = np.stack([r["segmentation"] for r in records])
    assert np.array_equal(auto.masks, expected)
    np.testing.assert_allclose(auto.scores, [r["predicted_iou"] for r in records], atol=1e-5)


def test_generate_defaults_are_the_papers():
    # paper section 4 / docs/design.md section 3.1: 64 points per side, IoU 0.88, stability 0.95,
    # offset 1.0, NMS 0.7, no minimum area
    assert PAPER_AMG_OPTIONS == {
        "points_per_side": 64,
        "pred_iou_thresh": 0.88,
        "stability_score_thresh": 0.95,
        "stability_score_offset": 1.0,
        "box_nms_thresh": 0.7,
        "min_mask_region_area": 0,
    }
    with pytest.raises(LfsamError, match="points_per_sid"):
        load_segmenter("sam2-tiny-test", device="cpu", amg_options={"points_per_sid": 8})


def test_generate_checks_the_image(seg, embeddings):
    with pytest.raises(LfsamError, match="uint8 image"):
        seg.generate(embeddings[0], np.zeros((U + 1, V, 3), np.uint8))


# --- features -------------------------------------------------------------------------------
def test_sample_features_is_bilinear_upsampling_at_pixels(seg, embeddings):
    emb = embeddings[2]
    full = F.interpolate(emb.data.image_embed, size=(U, V), mode="bilinear", align_corners=False)
    rng = np.random.default_rng(3)
    rows = rng.integers(0, U, 50)
    cols = rng.integers(0, V, 50)
    rc = torch.as_tensor(np.stack([rows, cols], 1), dtype=torch.float32)
    feats = seg.sample_features(emb, rc)
    assert feats.shape == (50, 32) and feats.dtype == torch.float32
    torch.testing.assert_close(feats, full[0, :, rows, cols].T, atol=1e-5, rtol=1e-5)


def test_sample_features_hits_cell_centres_exactly(seg, embeddings):
    """A pixel at the centre of embedding cell (i, j) gets exactly that cell's vector."""
    emb = embeddings[1]
    h = w = 16
    i, j = np.meshgrid(np.arange(1, h - 1), np.arange(1, w - 1), indexing="ij")
    rows = (i + 0.5) * U / h - 0.5  # each axis scaled separately (no padding)
    cols = (j + 0.5) * V / w - 0.5
    rc = torch.as_tensor(np.stack([rows.ravel(), cols.ravel()], 1), dtype=torch.float32)
    feats = seg.sample_features(emb, rc)
    expected = emb.data.image_embed[0, :, i.ravel(), j.ravel()].T
    torch.testing.assert_close(feats, expected, atol=1e-5, rtol=1e-5)


# --- encoded once ---------------------------------------------------------------------------
def test_each_view_is_encoded_once(views):
    seg = load_segmenter("sam2-tiny-test", device="cpu", amg_options=AMG)
    passes = {"views": 0}
    forward = seg.model.forward_image

    def counting(x):
        passes["views"] += x.shape[0]
        return forward(x)

    seg.model.forward_image = counting
    embs = seg.encode(views[:2], keys=[(0, 0), (0, 1)])
    assert seg.encode_calls == 2 and passes["views"] == 2
    for emb, view in zip(embs, views[:2], strict=True):
        for kind in ("points", "boxes", "points+boxes"):
            seg.predict(emb, _prompts(kind, 3), multimask_output=kind != "boxes")
        seg.generate(emb, view)
        seg.sample_features(emb, torch.tensor([[1.0, 2.0], [30.0, 40.0]]))
    assert seg.encode_calls == 2 and passes["views"] == 2
    assert seg.crop_encode_calls == 0


def test_generation_crops_are_encoded_and_counted_apart(views, embeddings):
    seg = load_segmenter(
        "sam2-tiny-test",
        device="cpu",
        amg_options={**AMG, "points_per_side": 2, "crop_n_layers": 1},
    )
    emb = seg.encode(views[:1])[0]
    seg.generate(emb, views[0])
    assert seg.encode_calls == 1
    assert seg.crop_encode_calls == 4  # the four crops of layer 1; the whole view is reused


def test_describe_flags_random_weights(seg):
    info = seg.describe()
    assert seg.random_weights is True and info["random_weights"] is True
    assert info["name"] == "sam2-tiny-test" and info["backend"] == "sam2"
    assert info["device"] == "cpu" and info["params"] == 883_914
    assert info["amg_options"]["points_per_side"] == AMG["points_per_side"]


@settings(max_examples=20, deadline=None)
@given(u_size=st.integers(5, 300), v_size=st.integers(5, 300), seed=st.integers(0, 99))
def test_sample_features_geometry_for_any_view_size(seg, u_size, v_size, seed):
    """Pixel -> embedding mapping per axis: bilinear upsampling, exact at the cell centres."""
    gen = torch.Generator().manual_seed(seed)
    embed = torch.randn(1, 5, 16, 16, generator=gen)
    emb = ViewEmbedding(image_size=(u_size, v_size), data=Sam2Features(embed, []))
    full = F.interpolate(embed, size=(u_size, v_size), mode="bilinear", align_corners=False)
    rows = torch.randint(0, u_size, (40,), generator=gen)
    cols = torch.randint(0, v_size, (40,), generator=gen)
    got = seg.sample_features(emb, torch.stack([rows, cols], 1).float())
    torch.testing.assert_close(got, full[0, :, rows, cols].T, atol=1e-5, rtol=1e-5)
    i, j = torch.randint(0, 16, (2, 30), generator=gen)
    centres = torch.stack([(i + 0.5) * u_size / 16 - 0.5, (j + 0.5) * v_size / 16 - 0.5], 1)
    torch.testing.assert_close(
        seg.sample_features(emb, centres), embed[0, :, i, j].T, atol=1e-5, rtol=1e-5
    )
