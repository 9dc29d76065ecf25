"""Speed of the shared-image mask decoder against Meta's ``SAM2ImagePredictor._predict`` (issue #5).

LFSAM decodes N prompts per view (refinement, paper section 3.4; docs/design.md section 3.5), so
the decoder's cost per view is N decoder passes. Meta's batched path repeats the image embedding
once per prompt and runs the whole two-way transformer and upscaling on N copies of it;
:func:`lfsam.segmenters.sam2.decoder.decode_prompts` shares the prompt-independent part (see its
module docstring). This script prints, for one encoded view and N prompts (one point and one box
each, the refinement's prompt shape), with random weights (speed does not depend on them):

- Meta's ``_predict`` with all N prompts in one batch, and one prompt at a time;
- ``decode_prompts`` for several chunk sizes, and ``Sam2Segmenter.predict`` end to end (decoder +
  the same post-processing as ``_predict``: upsampling to the view and threshold);
- the speed-up over Meta's batched and one-at-a-time paths, the decoder time over one
  image-encoder pass, and the largest absolute difference of the low-resolution logits.

With ``--generate``, it also times automatic mask generation (``Sam2Segmenter.generate``, the
paper's settings: 64 x 64 points) on the same view, once through our decoder and once with
Meta's own ``SAM2ImagePredictor._predict`` (single runs: minutes on a CPU).

Every time is the minimum of ``--repeats`` runs after one warm-up run (other work on the machine
only ever adds time). Run: ``.venv/bin/python benchmarks/bench_decoder.py [--model
sam2.1-hiera-small] [--size 240x320] [--prompts 16] [--repeats 3] [--chunks 1,2,4,8]
[--generate]``.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np
import torch
from sam2.sam2_image_predictor import SAM2ImagePredictor

from lfsam.segmenters import Prompts, load_segmenter
from lfsam.segmenters.sam2.build import inference_context
from lfsam.segmenters.sam2.decoder import decode_prompts, default_chunk_size, prepare_image


def best_time(fn: Callable[[], object], repeats: int) -> float:
    """Minimum wall-clock seconds of ``repeats`` calls after one warm-up call."""
    fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def grid_prompts(n: int, u_size: int, v_size: int) -> Prompts:
    """N prompts on a grid over the view: one positive point and a box around it each."""
    side = int(np.ceil(np.sqrt(n)))
    xs = np.linspace(0.1 * v_size, 0.9 * v_size, side)
    ys = np.linspace(0.1 * u_size, 0.9 * u_size, side)
    pts = np.array([(x, y) for x in xs for y in ys], dtype=np.float32)[:n]
    half = 0.08 * min(u_size, v_size)
    boxes = np.concatenate([pts - half, pts + half], axis=1)
    return Prompts(points=pts[:, None], point_labels=np.ones((n, 1), np.int64), boxes=boxes)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="sam2.1-hiera-small")
    parser.add_argument("--size", default="240x320", help="view size, rows x columns")
    parser.add_argument("--prompts", type=int, default=16)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--chunks", default="1,2,4,8", help="decode_prompts chunk sizes to time")
    parser.add_argument("--single-mask", action="store_true", help="K = 1 instead of 3")
    parser.add_argument("--device", default=None)
    parser.add_argument("--generate", action="store_true",
                        help="also time automatic mask generation, ours vs Meta's decoder")
    args, _ = parser.parse_known_args()  # run_all.py may pass one extra argument
    u_size, v_size = (int(s) for s in args.size.lower().split("x"))
    multimask = not args.single_mask
    chunks = [int(c) for c in args.chunks.split(",")]

    # no decoder state kept with the embedding: every Sam2Segmenter.predict below does the
    # decoder's image side again, as the decode_prompts rows it is compared with do
    seg = load_segmenter(args.model, random_weights=True, device=args.device,
                         keep_decoder_state=False)
    model, device = seg.model, seg.device
    rng = np.random.default_rng(0)
    view = rng.integers(0, 256, (u_size, v_size, 3), dtype=np.uint8)
    view[u_size // 4 : u_size // 2, v_size // 4 : v_size // 2] = (200, 40, 40)
    encode_s = best_time(lambda: seg.encode(view[None]), args.repeats)
    emb = seg.encode(view[None])[0]
    feats = emb.data
    prompts = grid_prompts(args.prompts, u_size, v_size)
    n = len(prompts)
    coords, labels, boxes = seg._prompt_tensors(prompts, (u_size, v_size))

    predictor = seg._predictor
    predictor.use_features(feats.as_predictor_features(), emb.image_size)
    # Meta's own method (the segmenter's predictor class routes _predict through ours)
    meta_predict = SAM2ImagePredictor._predict
    with inference_context(device, inference_mode=False):

        def meta_batched():
            return meta_predict(predictor, coords, labels, boxes, multimask_output=multimask)

        def meta_single():
            return [
                meta_predict(
                    predictor,
                    coords[i : i + 1],
                    labels[i : i + 1],
                    boxes[i : i + 1],
                    multimask_output=multimask,
                )
                for i in range(n)
            ]

        def ours(chunk: int) -> Callable[[], object]:
            def run():
                state = prepare_image(model, feats.image_embed, feats.high_res_feats)
                return decode_prompts(
                    model,
                    feats.image_embed,
                    feats.high_res_feats,
                    coords,
                    labels,
                    boxes,
                    multimask,
                    chunk_size=chunk,
                    state=state,
                )

            return run

        batched_s = best_time(meta_batched, args.repeats)
        single_s = best_time(meta_single, args.repeats)
        ours_s = {c: best_time(ours(c), args.repeats) for c in chunks}
        _, iou_ref, low_ref = meta_batched()
        low_single = torch.cat([out[2] for out in meta_single()])
        low, iou = ours(default_chunk_size(device))()
        masks_ref = meta_batched()[0]
        masks_single = torch.cat([out[0] for out in meta_single()])
    predictor.reset_predictor()
    predict_s = best_time(lambda: seg.predict(emb, prompts, multimask), args.repeats)
    pred = seg.predict(emb, prompts, multimask)

    k = 3 if multimask else 1
    threads = torch.get_num_threads() if device.type == "cpu" else "-"
    print(
        f"model {args.model} (random weights) on {device} ({threads} threads), view "
        f"{u_size}x{v_size}, {n} prompts (1 point + 1 box each), K={k}; "
        f"times are the minimum of {args.repeats} runs after a warm-up"
    )
    print(f"{'what':46s} {'seconds':>8s} {'x Meta batched':>14s} {'x Meta single':>13s}")
    rows = [
        ("image encoder, one pass (reference)", encode_s),
        ("Meta _predict, all prompts in one batch", batched_s),
        ("Meta _predict, one prompt at a time", single_s),
    ]
    rows += [(f"decode_prompts, chunk {c}", s) for c, s in ours_s.items()]
    rows.append(
        (f"Sam2Segmenter.predict (chunk {default_chunk_size(device)}, + post-proc.)", predict_s)
    )
    for name, secs in rows:
        print(f"{name:46s} {secs:8.3f} {batched_s / secs:14.2f} {single_s / secs:13.2f}")
    best_chunk = min(ours_s, key=ours_s.get)
    print(
        f"best chunk {best_chunk}: {ours_s[best_chunk]:.3f} s = {ours_s[best_chunk] / n * 1e3:.1f} "
        f"ms per prompt, {ours_s[best_chunk] / encode_s:.3f} x one encoder pass"
    )
    print(
        f"max |low-res logits - Meta batched| = {(low - low_ref).abs().max().item():.2e}, "
        f"- Meta single = {(low - low_single).abs().max().item():.2e} "
        f"(Meta batched - single = {(low_ref - low_single).abs().max().item():.2e}); "
        f"max |IoU - Meta| = {(iou - iou_ref).abs().max().item():.2e}; "
        f"mask pixels differing from Meta batched: {(pred.masks != masks_ref).sum().item()} "
        f"of {masks_ref.numel()} (Meta single vs batched: "
        f"{(masks_single != masks_ref).sum().item()})"
    )
    if args.generate:
        time_generation(seg, emb, view)
    return 0


def time_generation(seg, emb, view: np.ndarray) -> None:
    """Automatic mask generation on one view through our decoder and through Meta's."""
    predictor = seg._mask_generator().predictor
    start = time.perf_counter()
    ours = seg.generate(emb, view)
    ours_s = time.perf_counter() - start
    # the same generator, its predictor's _predict swapped back to Meta's own method
    predictor._predict = SAM2ImagePredictor._predict.__get__(predictor)
    try:
        start = time.perf_counter()
        meta = seg.generate(emb, view)
        meta_s = time.perf_counter() - start
    finally:
        del predictor._predict
    same = ours.masks.shape == meta.masks.shape and bool((ours.masks == meta.masks).all())
    print(
        f"automatic generation ({seg.amg_options.get('points_per_side')}^2 points): ours "
        f"{ours_s:.1f} s, Meta's decoder {meta_s:.1f} s ({meta_s / ours_s:.1f}x); "
        f"{len(ours.masks)} vs {len(meta.masks)} masks, identical: {same}"
    )


if __name__ == "__main__":
    raise SystemExit(main())
