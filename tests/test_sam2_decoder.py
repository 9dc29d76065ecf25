"""The shared-image SAM 2 mask decoder against Meta's own code path.

Every expected value comes from ``SAM2ImagePredictor._predict`` (prompt encoder +
``MaskDecoder.forward`` with the image repeated per prompt) run on the same image features, or
from Meta's ``MaskDecoder.predict_masks`` / ``_get_stability_scores``. Models are the tiny
random-weight SAM 2.1 (``sam2-tiny-test``) and copies of it with decoder switches toggled; one test
uses ``sam2.1-hiera-small`` (random weights) for the real widths (256 channels, 64 x 64 grid).
"""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from lfsam.errors import LfsamError
from lfsam.segmenters import Prompts, load_segmenter
from lfsam.segmenters.sam2.build import make_image_predictor
from lfsam.segmenters.sam2.decoder import (
    LOGIT_CLAMP,
    decode_prompts,
    embed_prompts,
    prepare_image,
    stability_scores,
)

LOGIT_ATOL = 1e-4  # float32 on CPU (task spec: low-res logits within 1e-4, IoU within 1e-5)
IOU_ATOL = 1e-5


# --- fixtures -------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def tiny():
    return load_segmenter("sam2-tiny-test", device="cpu", random_weights=True).model


def _features(model, seed: int = 0, scale: float = 1.0):
    """Random image features of the shapes ``SAM2ImagePredictor`` keeps for ``model``."""
    gen = torch.Generator().manual_seed(seed)
    c = model.sam_mask_decoder.transformer_dim
    h = model.image_size // 16
    embed = scale * torch.randn(1, c, h, h, generator=gen)
    high = [
        torch.randn(1, c // 8, 4 * h, 4 * h, generator=gen),
        torch.randn(1, c // 4, 2 * h, 2 * h, generator=gen),
    ]
    return embed, high


def _meta(model, embed, high, orig_hw=None):
    """Meta's image predictor holding ``embed``/``high`` as if ``set_image`` had made them."""
    predictor = make_image_predictor(model)
    predictor._features = {"image_embed": embed, "high_res_feats": high}
    low = model.image_size // 4
    predictor._orig_hw = [orig_hw or (low, low)]
    predictor._is_image_set = True
    return predictor


def _prompts(model, kind: str, n: int = 6, seed: int = 0):
    """Point/box tensors in model-input pixels; points carry some -1 padding and negatives."""
    gen = torch.Generator().manual_seed(seed)
    size = float(model.image_size)
    coords = torch.rand(n, 3, 2, generator=gen) * size
    labels = torch.randint(0, 2, (n, 3), generator=gen, dtype=torch.int32)
    labels[:, 0] = 1
    labels[::2, 2] = -1  # every other prompt has one point fewer (padding)
    corners = torch.sort(torch.rand(n, 2, 2, generator=gen) * size, dim=1).values
    boxes = corners.reshape(n, 4)  # x0, y0, x1, y1 with x0 <= x1, y0 <= y1
    if kind == "points":
        return coords, labels, None
    if kind == "boxes":
        return None, None, boxes
    return coords[:, :2], labels[:, :2], boxes


def _variant(model, **switches):
    """A copy of ``model`` with mask-decoder attributes changed (as the SAM 2 configs set them)."""
    other = copy.deepcopy(model)
    for name, value in switches.items():
        assert hasattr(other.sam_mask_decoder, name)
        setattr(other.sam_mask_decoder, name, value)
    return other


VARIANTS = {
    "sam2.1": {},  # object-score token, high-res features, dynamic multimask: all on
    "no-obj-score": {"pred_obj_scores": False},
    "no-high-res": {"use_high_res_features": False},
    "no-dynamic": {"dynamic_multimask_via_stability": False},
}


@pytest.fixture(scope="module")
def variants(tiny):
    return {name: _variant(tiny, **sw) if sw else tiny for name, sw in VARIANTS.items()}


# --- equality with Meta's path --------------------------------------------------------------
@pytest.mark.parametrize("multimask", [True, False])
@pytest.mark.parametrize("kind", ["points", "boxes", "points+boxes"])
@pytest.mark.parametrize("variant", list(VARIANTS))
def test_matches_sam2_image_predictor(variants, variant, kind, multimask):
    model = variants[variant]
    embed, high = _features(model, seed=1)
    coords, labels, boxes = _prompts(model, kind, seed=2)
    with torch.no_grad():
        _, iou_ref, low_ref = _meta(model, embed, high)._predict(
            coords, labels, boxes, multimask_output=multimask
        )
        low, iou = decode_prompts(model, embed, high, coords, labels, boxes, multimask)
    k = 3 if multimask else 1
    assert low.shape == (6, k, 64, 64) and iou.shape == (6, k)
    assert low_ref.std() > 0.01  # the comparison is not between near-constant maps
    torch.testing.assert_close(low, low_ref, atol=LOGIT_ATOL, rtol=0)
    torch.testing.assert_close(iou, iou_ref, atol=IOU_ATOL, rtol=0)


def test_variants_really_differ(variants):
    """Each switch changes the decoder's output, so the parametrised test checks each path."""
    outs = {}
    for name, model in variants.items():
        embed, high = _features(model, seed=1)
        coords, labels, boxes = _prompts(model, "points+boxes", seed=2)
        with torch.no_grad():
            outs[name] = decode_prompts(model, embed, high, coords, labels, boxes, False)[0]
    names = list(outs)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            assert not torch.allclose(outs[a], outs[b], atol=1e-3), (a, b)


def test_stability_scores_equal_meta(tiny):
    """The decoder's own stability score (no private sam2 name) equals ``_get_stability_scores``,
    also for masks empty at ``-delta`` (score 1) and logits exactly at the thresholds."""
    dec = tiny.sam_mask_decoder
    delta = dec.dynamic_multimask_stability_delta
    gen = torch.Generator().manual_seed(7)
    logits = 3 * torch.randn(5, 3, 16, 16, generator=gen)
    logits[0, 0] = -10.0  # nothing passes -delta
    logits[1, 1, :4] = delta  # on the thresholds
    logits[1, 1, 4:8] = -delta
    ours = stability_scores(dec, logits)
    assert ours.shape == (5, 3) and ours.dtype == torch.float32
    assert torch.equal(ours, dec._get_stability_scores(logits))
    assert ours[0, 0] == 1.0


def test_dynamic_multimask_takes_both_branches(tiny):
    """Single-mask output with the stability fallback: some prompts keep token 0, some do not.

    The threshold is set to the median stability of token 0 (both computed by Meta's
    ``predict_masks`` and ``_get_stability_scores``), so both branches of
    ``_dynamic_multimask_via_stability`` occur.
    """
    embed, high = _features(tiny, seed=3)
    coords, labels, boxes = _prompts(tiny, "points", n=8, seed=4)
    dec = tiny.sam_mask_decoder
    with torch.no_grad():
        sparse = embed_prompts(tiny, coords, labels, boxes)
        dense = tiny.sam_prompt_encoder.no_mask_embed.weight.reshape(1, -1, 1, 1)
        all_masks, all_iou, _, _ = dec.predict_masks(
            image_embeddings=embed,
            image_pe=tiny.sam_prompt_encoder.get_dense_pe(),
            sparse_prompt_embeddings=sparse,
            dense_prompt_embeddings=dense.expand(8, -1, *embed.shape[-2:]),
            repeat_image=True,
            high_res_features=high,
        )
        stability = dec._get_stability_scores(all_masks[:, 0:1])[:, 0]
    model = _variant(tiny, dynamic_multimask_stability_thresh=float(stability.median()))
    stable = stability >= model.sam_mask_decoder.dynamic_multimask_stability_thresh
    assert stable.any() and not stable.all()
    with torch.no_grad():
        _, iou_ref, low_ref = _meta(model, embed, high)._predict(
            coords, labels, boxes, multimask_output=False
        )
        low, iou = decode_prompts(model, embed, high, coords, labels, boxes, False)
    torch.testing.assert_close(low, low_ref, atol=LOGIT_ATOL, rtol=0)
    torch.testing.assert_close(iou, iou_ref, atol=IOU_ATOL, rtol=0)
    best = all_iou[:, 1:].argmax(dim=1) + 1
    expected = torch.where(stable, 0, best)
    picked = all_masks[torch.arange(8), expected].clamp(-LOGIT_CLAMP, LOGIT_CLAMP)
    torch.testing.assert_close(low[:, 0], picked, atol=LOGIT_ATOL, rtol=0)


def test_clamp_matches_predictor_and_unclamped_logits_are_returned_on_request(tiny):
    """Large logits (hypernetwork scaled up): clamped as ``_predict`` returns them, and the
    unclamped values equal the logits ``_predict`` post-processes (``return_logits``)."""
    model = _variant(tiny)
    with torch.no_grad():
        for mlp in model.sam_mask_decoder.output_hypernetworks_mlps:
            mlp.layers[-1].weight.mul_(200.0)
    embed, high = _features(model, seed=5)
    coords, labels, boxes = _prompts(model, "points+boxes", seed=6)
    predictor = _meta(model, embed, high)  # orig size = low-res size: interpolation is identity
    with torch.no_grad():
        raw_ref, iou_ref, low_ref = predictor._predict(
            coords, labels, boxes, multimask_output=True, return_logits=True
        )
        low, iou = decode_prompts(model, embed, high, coords, labels, boxes, True)
        raw, _ = decode_prompts(model, embed, high, coords, labels, boxes, True, clamp=False)
    assert raw_ref.abs().max() > 2 * LOGIT_CLAMP  # clamping matters here
    assert low.abs().max() == LOGIT_CLAMP
    torch.testing.assert_close(low, low_ref, atol=LOGIT_ATOL, rtol=0)
    torch.testing.assert_close(iou, iou_ref, atol=IOU_ATOL, rtol=0)
    torch.testing.assert_close(raw, raw_ref, atol=1e-3, rtol=1e-5)


def test_padding_point_position_is_ignored(tiny):
    """A label -1 point is "not a point": moving it changes nothing; a real point does."""
    embed, high = _features(tiny, seed=7)
    coords = torch.tensor([[[100.0, 60.0], [0.0, 0.0]], [[100.0, 60.0], [200.0, 150.0]]])
    pad = torch.tensor([[1, -1], [1, -1]], dtype=torch.int32)
    neg = torch.tensor([[1, -1], [1, 0]], dtype=torch.int32)
    with torch.no_grad():
        a = decode_prompts(tiny, embed, high, coords, pad, None, True)[0]
        b = decode_prompts(tiny, embed, high, coords, neg, None, True)[0]
    torch.testing.assert_close(a[0], a[1], atol=1e-6, rtol=0)
    assert not torch.allclose(b[0], b[1], atol=1e-3)


@pytest.mark.parametrize(("chunk_size", "tile_rows"), [(1, 1), (3, 5), (7, 16), (2, 100)])
def test_chunks_and_tiles_do_not_change_results(tiny, chunk_size, tile_rows):
    embed, high = _features(tiny, seed=8)
    coords, labels, boxes = _prompts(tiny, "points+boxes", n=7, seed=9)
    with torch.no_grad():
        ref = decode_prompts(tiny, embed, high, coords, labels, boxes, True, chunk_size=64)
        state = prepare_image(tiny, embed, high)
        got = decode_prompts(
            tiny,
            embed,
            high,
            coords,
            labels,
            boxes,
            True,
            chunk_size=chunk_size,
            state=state,
            tile_rows=tile_rows,
        )
    torch.testing.assert_close(got[0], ref[0], atol=1e-5, rtol=0)
    torch.testing.assert_close(got[1], ref[1], atol=1e-6, rtol=0)


def test_bf16_autocast_error_is_that_of_metas_path(tiny):
    """Under bf16 autocast (what the backend uses on CUDA) the result stays as close to the
    float32 result as Meta's own path under the same autocast."""
    embed, high = _features(tiny, seed=10)
    coords, labels, boxes = _prompts(tiny, "points+boxes", seed=11)
    with torch.no_grad():
        exact = decode_prompts(tiny, embed, high, coords, labels, boxes, True)[0]
        with torch.autocast("cpu", dtype=torch.bfloat16):
            _, _, meta16 = _meta(tiny, embed, high)._predict(
                coords, labels, boxes, multimask_output=True
            )
            ours16 = decode_prompts(tiny, embed, high, coords, labels, boxes, True)[0]
    meta_err = (meta16.float() - exact).abs().mean()
    ours_err = (ours16.float() - exact).abs().mean()
    assert torch.isfinite(ours16).all()
    assert ours_err <= 2 * meta_err + 1e-3


# --- errors and edge cases ------------------------------------------------------------------
def test_rejects_what_it_does_not_do(tiny):
    embed, high = _features(tiny)
    coords, labels, boxes = _prompts(tiny, "points+boxes", n=2)
    with pytest.raises(LfsamError, match="mask prompts"):
        decode_prompts(tiny, embed, high, coords, labels, boxes, True, mask_input=torch.zeros(1))
    with pytest.raises(LfsamError, match="at least 1"):
        decode_prompts(tiny, embed, high, coords, labels, boxes, True, chunk_size=0)
    with pytest.raises(LfsamError, match="one box per prompt"):
        decode_prompts(tiny, embed, high, coords, labels, boxes[:1], True)
    with pytest.raises(LfsamError, match="points, a box"):
        decode_prompts(tiny, embed, high, None, None, None, True)
    with pytest.raises(LfsamError, match="one image embedding"):
        decode_prompts(tiny, embed.expand(2, -1, -1, -1), high, coords, labels, boxes, True)
    with pytest.raises(LfsamError, match="high-resolution"):
        decode_prompts(tiny, embed, None, coords, labels, boxes, True)


def test_no_prompts_gives_empty_outputs(tiny):
    embed, high = _features(tiny)
    with torch.no_grad():
        low, iou = decode_prompts(tiny, embed, high, None, None, torch.zeros(0, 4), False)
    assert low.shape == (0, 1, 64, 64) and iou.shape == (0, 1)


# --- through the segmenter -------------------------------------------------------------------
def test_segmenter_masks_come_from_unclamped_logits(tiny):
    """``Sam2Segmenter.predict`` thresholds the upsampled *unclamped* logits, as ``_predict``.

    With large logits, upsampling clamped logits would flip pixels (checked first), so equal
    masks show the segmenter post-processes the right tensor; its low-res logits are clamped.
    """
    from lfsam.segmenters.base import ViewEmbedding
    from lfsam.segmenters.sam2.backend import Sam2Features, Sam2Segmenter

    model = _variant(tiny)
    with torch.no_grad():
        for mlp in model.sam_mask_decoder.output_hypernetworks_mlps:
            mlp.layers[-1].weight.mul_(200.0)
    seg = Sam2Segmenter(model, max_prompts_per_batch=3)
    u_size, v_size = 37, 53
    embed, high = _features(model, seed=12)
    emb = ViewEmbedding(image_size=(u_size, v_size), data=Sam2Features(embed, high))
    rng = np.random.default_rng(13)
    pts = rng.uniform((0, 0), (v_size - 1, u_size - 1), size=(7, 1, 2))
    prompts = Prompts(points=pts, point_labels=np.ones((7, 1)))
    pred = seg.predict(emb, prompts, multimask_output=True)

    predictor = _meta(model, embed, high, orig_hw=(u_size, v_size))
    coords, labels, _ = seg._prompt_tensors(prompts, (u_size, v_size))
    with torch.no_grad():
        masks, iou, low = predictor._predict(coords, labels, None, multimask_output=True)
        from_clamped = predictor._transforms.postprocess_masks(low, (u_size, v_size)) > 0
    assert not torch.equal(from_clamped, masks)  # clamping before upsampling would matter
    assert torch.equal(pred.masks, masks)
    torch.testing.assert_close(pred.iou_predictions, iou, atol=IOU_ATOL, rtol=0)
    torch.testing.assert_close(pred.low_res_logits, low, atol=LOGIT_ATOL, rtol=0)


def test_hiera_small_matches_sam2_image_predictor():
    """The real decoder widths (sam2.1-hiera-small, random weights): 256 channels, 8 heads,
    64 x 64 embedding, 1024-pixel input."""
    model = load_segmenter("sam2.1-hiera-small", device="cpu", random_weights=True).model
    embed, high = _features(model, seed=14)
    coords, labels, boxes = _prompts(model, "points+boxes", n=3, seed=15)
    with torch.no_grad():
        _, iou_ref, low_ref = _meta(model, embed, high)._predict(
            coords, labels, boxes, multimask_output=True
        )
        low, iou = decode_prompts(model, embed, high, coords, labels, boxes, True)
    assert low.shape == (3, 3, 256, 256)
    torch.testing.assert_close(low, low_ref, atol=LOGIT_ATOL, rtol=0)
    torch.testing.assert_close(iou, iou_ref, atol=IOU_ATOL, rtol=0)
