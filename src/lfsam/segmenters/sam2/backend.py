"""The SAM 2 backend: Meta's image model behind lfsam's :class:`Segmenter` interface.

Each view is encoded once (:meth:`Sam2Segmenter.encode`: SAM 2's transforms, image encoder,
``_prepare_backbone_features`` and ``no_mem_embed``, exactly as ``SAM2ImagePredictor.set_image``),
and its embedding then serves every prompt batch (:meth:`~Sam2Segmenter.predict`: what
``SAM2ImagePredictor._predict`` computes, by the restructured decoder of
:mod:`lfsam.segmenters.sam2.decoder` that shares the image side across prompts), automatic mask
generation (:meth:`~Sam2Segmenter.generate`: ``SAM2AutomaticMaskGenerator`` fed the cached
embedding instead of re-encoding) and the features for semantic occluding
(:meth:`~Sam2Segmenter.sample_features`, :meth:`~Sam2Segmenter.feature_sums`,
:meth:`~Sam2Segmenter.feature_similarity`, paper section 3.3) (docs/design.md section 3, "efficiency
facts").
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from lfsam.devices import (
    CUDA_CROSS_VIEW_ROWS,
    default_encode_batch_size,
    default_prompt_batch_size,
)
from lfsam.errors import LfsamError
from lfsam.segmenters.base import MaskPrediction, Prompts, Segmenter, ViewEmbedding
from lfsam.segmenters.registry import DEFAULT_MODEL
from lfsam.segmenters.sam2.adapter import (
    CachedFeaturePredictor,
    backbone_features,
    image_transforms,
)
from lfsam.segmenters.sam2.automatic import PAPER_AMG_OPTIONS, AutomaticMaskGeneration
from lfsam.segmenters.sam2.build import (
    build_sam2,
    inference_context,
    make_image_predictor,
    precision_dtype,
)
from lfsam.segmenters.sam2.decoder import default_chunk_size, prepare_image
from lfsam.segmenters.sam2.features import FeatureSampling
from lfsam.segmenters.sam2.multiview import (
    compile_pass,
    decode_prompt_batches,
    prompt_shape,
    stack_states,
)

__all__ = ["PAPER_AMG_OPTIONS", "CachedFeaturePredictor", "Sam2Features", "Sam2Segmenter"]


@dataclass
class Sam2Features:
    """SAM 2's encoding of one view, as ``SAM2ImagePredictor`` keeps it in ``_features``.

    Parameters
    ----------
    image_embed : (1, C, H/16, W/16) tensor
        The image embedding after the neck, plus ``no_mem_embed`` (C = 256, 64 x 64 for a 1024
        input); what the mask decoder and semantic occluding use.
    high_res_feats : list of two tensors
        ``(1, C/8, H/4, W/4)`` and ``(1, C/4, H/8, W/8)`` (after the decoder's 1x1 convolutions);
        empty for a model without them (SAM v1 from ``transformers``, docs/design.md
        section 3.8).
    pixel_norms : (U * V,) tensor, optional
        Norm of the upsampled embedding at every pixel (semantic occluding), made on first use.
    decoder_state : ImageState, optional
        The decoder's prompt-independent image side
        (:func:`lfsam.segmenters.sam2.decoder.prepare_image`), kept when the segmenter's
        :attr:`Sam2Segmenter.keep_decoder_state` is on (interactive use: every edit decodes
        every view again).
    """

    image_embed: torch.Tensor
    high_res_feats: list[torch.Tensor]
    pixel_norms: torch.Tensor | None = None
    decoder_state: Any = None

    def as_predictor_features(self) -> dict[str, Any]:
        """The ``_features`` dict of ``SAM2ImagePredictor``."""
        return {"image_embed": self.image_embed, "high_res_feats": list(self.high_res_feats)}


class Sam2Segmenter(AutomaticMaskGeneration, FeatureSampling, Segmenter):
    """Meta's SAM 2 image model as an lfsam :class:`Segmenter`.

    ``keep_decoder_state`` (default on) keeps the decoder's prompt-independent image side with
    each embedding (:class:`Sam2Features`), so a view decoded again (an interactive edit) skips
    it; it about triples an embedding's memory, so batch runs, which decode each view once,
    build the segmenter with it off (:func:`lfsam.segment`).

    Parameters
    ----------
    model : SAM2Base
        From :func:`lfsam.segmenters.sam2.build.build_sam2` (any ``SAM2Base`` works; models not
        built there are described as far as known).
    amg_options : dict, optional
        Overrides of :data:`PAPER_AMG_OPTIONS` for :meth:`generate`; any keyword of
        ``sam2.automatic_mask_generator.SAM2AutomaticMaskGenerator`` (e.g. ``points_per_side``,
        ``points_per_batch``, ``crop_n_layers``, ``multimask_output``).
    max_prompts_per_batch : int, optional
        Prompts decoded together in :meth:`predict`; bounds memory (N x 3 x U x V logits).
        Default 128 on CUDA (the paper's 100 masks of a view in one decoder call; measured on
        an H100, docs/performance.md) and 64 elsewhere.
    encode_batch_size : int, optional
        Views run through the image encoder together in :meth:`encode`; default from the device
        (:func:`lfsam.devices.default_encode_batch_size`: batched on CUDA, 1 elsewhere).
    mask_threshold : float
        Logit threshold of the masks (SAM 2's default 0).
    keep_decoder_state : bool
        Keep the decoder's image side with each embedding (above).
    precision : {"auto", "float32", "bfloat16"}
        The arithmetic (:data:`lfsam.segmenters.sam2.build.PRECISIONS`): ``auto`` is bfloat16
        autocast on CUDA and float32 elsewhere; ``bfloat16`` autocasts on any device (about
        twice as fast on CPUs with native bfloat16; the masks differ slightly from float32's).
    cross_view_decode : bool, optional
        :meth:`predict_many` puts prompts of different views through one decoder pass
        (:func:`lfsam.segmenters.sam2.multiview.decode_views`). Default: on CUDA, where a
        decoder call per view is launch-bound; off elsewhere, where the decoder is
        compute-bound and view-by-view decoding keeps the masks bit for bit those of
        :meth:`predict` (the cross-view pass rounds differently, about 1e-7 in the logits).
    cross_view_rows : int, optional
        Prompts per cross-view decoder call; on CUDA also per decoder pass (default
        :data:`lfsam.devices.CUDA_CROSS_VIEW_ROWS` there, else :attr:`max_prompts_per_batch`
        with passes of :func:`~lfsam.segmenters.sam2.decoder.default_chunk_size`).
    compile_decoder : str, optional
        Compile the cross-view decoder pass with ``torch.compile`` and static shapes (every
        pass padded to the same number of prompts): a ``torch.compile`` mode,
        ``"reduce-overhead"`` (CUDA graphs: one launch per pass), ``"default"`` or
        ``"max-autotune"``, or ``"eager"`` (traced only; for tests). Off by default, on every
        device (compiling takes minutes on a CPU and its GPU gain is not measured yet).

    Examples
    --------
    >>> seg = Sam2Segmenter.from_name("sam2-tiny-test", device="cpu")  # doctest: +SKIP
    >>> emb = seg.encode(views[None])[0]  # doctest: +SKIP
    >>> pred = seg.predict(emb, Prompts(points=[[[40, 30]]], point_labels=[[1]]))  # doctest: +SKIP
    """

    skips_absent_points = True
    """Absent points are masked out as keys in every attention of the decoder
    (:func:`lfsam.segmenters.sam2.decoder.absent_tokens`)."""

    def __init__(
        self,
        model: torch.nn.Module,
        *,
        amg_options: dict[str, Any] | None = None,
        max_prompts_per_batch: int | None = None,
        encode_batch_size: int | None = None,
        mask_threshold: float = 0.0,
        keep_decoder_state: bool = True,
        precision: str = "auto",
        cross_view_decode: bool | None = None,
        cross_view_rows: int | None = None,
        compile_decoder: str | None = None,
    ) -> None:
        super().__init__()
        self.precision = str(precision)
        self.autocast = precision_dtype(model.device, self.precision)
        if encode_batch_size is None:
            encode_batch_size = default_encode_batch_size(model.device)
        if max_prompts_per_batch is None:
            max_prompts_per_batch = default_prompt_batch_size(model.device)
        if max_prompts_per_batch < 1 or encode_batch_size < 1 or (cross_view_rows or 1) < 1:
            raise LfsamError(
                "max_prompts_per_batch, encode_batch_size and cross_view_rows must be at least 1"
            )
        self.model = model.eval()
        info = dict(getattr(model, "lfsam_info", {}) or {})
        self.name = str(info.get("name", type(model).__name__))
        self.info = info
        self.device = model.device
        self.max_prompts_per_batch = int(max_prompts_per_batch)
        self.encode_batch_size = int(encode_batch_size)
        self.mask_threshold = float(mask_threshold)
        self.amg_options = self._check_amg_options(amg_options or {})
        self.points_per_side = int(self.amg_options.get("points_per_side") or 32)
        self.keep_decoder_state = bool(keep_decoder_state)
        if cross_view_decode is None:
            cross_view_decode = model.device.type == "cuda"
        self.cross_view_decode = bool(cross_view_decode)
        cuda = model.device.type == "cuda"
        self.cross_view_rows = int(
            cross_view_rows or (CUDA_CROSS_VIEW_ROWS if cuda else max_prompts_per_batch)
        )
        self.compile_decoder = compile_decoder
        self._compiled: Any = None
        self.decoder_calls = 0
        """Calls of the decoder by :meth:`predict` and :meth:`predict_many` (each one batch of
        prompts of one view, or of several views with :attr:`cross_view_decode`)."""
        self._predictor = make_image_predictor(
            model, CachedFeaturePredictor, mask_threshold=self.mask_threshold
        )
        self._generator: Any = None
        self.crop_encode_calls = 0
        """Image-encoder passes on generation crops (only with ``crop_n_layers > 0``)."""

    # --- construction -------------------------------------------------------------------------
    @classmethod
    def from_name(
        cls,
        name: str = DEFAULT_MODEL,
        *,
        checkpoint: str | os.PathLike | None = None,
        random_weights: bool = False,
        device: str | torch.device | None = None,
        seed: int = 0,
        **kwargs: Any,
    ) -> Sam2Segmenter:
        """Build the model with :func:`~lfsam.segmenters.sam2.build.build_sam2` and wrap it.

        Keyword arguments beyond those of ``build_sam2`` go to :class:`Sam2Segmenter`.
        """
        model = build_sam2(
            name, checkpoint=checkpoint, random_weights=random_weights, device=device, seed=seed
        )
        return cls(model, **kwargs)

    @property
    def random_weights(self) -> bool:
        """True if the model is untrained (its masks are meaningless; for tests and timing)."""
        return bool(self.info.get("random_weights", False))

    def describe(self) -> dict[str, Any]:
        """A JSON-ready description for result metadata (random weights are flagged)."""
        dtype = self.autocast
        return {
            "backend": "sam2",
            "name": self.name,
            "hub_id": self.info.get("hub_id"),
            "checkpoint": self.info.get("checkpoint"),
            "random_weights": self.random_weights,
            "seed": self.info.get("seed"),
            "device": str(self.device),
            "precision": "bfloat16 autocast" if dtype is not None else "float32",
            "params": int(sum(p.numel() for p in self.model.parameters())),
            "image_size": int(self.model.image_size),
            "amg_options": dict(self.amg_options),
            "max_prompts_per_batch": self.max_prompts_per_batch,
        }

    # --- encoding -----------------------------------------------------------------------------
    def encode(
        self, images: np.ndarray, keys: list[tuple[int, int]] | None = None
    ) -> list[ViewEmbedding]:
        """Run the image encoder once per view, in batches of :attr:`encode_batch_size`.

        Same transforms and features as ``SAM2ImagePredictor.set_image``: resize to the model's
        square input (no padding), ImageNet normalisation, backbone, ``_prepare_backbone_features``,
        ``no_mem_embed`` added to the lowest-resolution level.
        """
        images = _check_images(images)
        if keys is not None and len(keys) != len(images):
            raise LfsamError(f"got {len(images)} views but {len(keys)} keys; give one key per view")
        size = (int(images.shape[1]), int(images.shape[2]))
        out: list[ViewEmbedding] = []
        for start in range(0, len(images), self.encode_batch_size):
            chunk = images[start : start + self.encode_batch_size]
            for i, feats in enumerate(self._encode_batch(chunk)):
                key = None if keys is None else tuple(int(k) for k in keys[start + i])
                out.append(ViewEmbedding(image_size=size, key=key, data=feats))
            self.encode_calls += len(chunk)
        return out

    def _encode_batch(self, chunk: np.ndarray) -> list[Sam2Features]:
        model = self.model
        with inference_context(self.device, precision=self.precision):
            x = torch.from_numpy(np.ascontiguousarray(chunk)).to(self.device)
            x = x.permute(0, 3, 1, 2).float().div_(255.0)
            x = image_transforms(self._predictor).transforms(x)  # resize + normalise, as set_image
            return self._features_from_backbone(model.forward_image(x), len(chunk))

    def _features_from_backbone(self, backbone_out: dict[str, Any],
                                batch: int) -> list[Sam2Features]:
        """Per-view :class:`Sam2Features` of ``SAM2Base.forward_image``'s output for ``batch``
        views (``_prepare_backbone_features`` and ``no_mem_embed``, as ``set_image``)."""
        model = self.model
        vision_feats, feat_sizes = backbone_features(model, backbone_out)
        if model.directly_add_no_mem_embed:
            vision_feats[-1] = vision_feats[-1] + model.no_mem_embed
        levels = [
            feat.permute(1, 2, 0).reshape(batch, -1, *size)
            for feat, size in zip(vision_feats, feat_sizes, strict=True)
        ]
        views = []
        for i in range(batch):
            per_view = [level[i : i + 1] for level in levels]
            if batch > 1:  # do not keep the whole batch alive through one view
                per_view = [level.clone() for level in per_view]
            views.append(Sam2Features(image_embed=per_view[-1], high_res_feats=per_view[:-1]))
        return views

    def embedding_from_backbone(
        self, backbone_out: dict[str, Any], image_size: tuple[int, int],
        key: tuple[int, int] | None = None,
    ) -> ViewEmbedding:
        """The embedding of one view from an image-encoder pass made elsewhere:
        ``forward_image``'s output for that view's tensor as :meth:`encode` transforms it (SAM
        2's video memory encodes each frame's center view once and shares it, docs/design.md
        section 10). Equal to ``encode(view[None])[0]``; counted in :attr:`encode_calls`."""
        with inference_context(self.device, precision=self.precision):
            features = self._features_from_backbone(backbone_out, 1)[0]
        self.encode_calls += 1
        return ViewEmbedding(image_size=(int(image_size[0]), int(image_size[1])), key=key,
                             data=features)

    # --- on-disk cache ------------------------------------------------------------------------
    def cache_identity(self) -> str:
        """Model name, input size, precision, device type and a SHA-256 of every weight."""
        if getattr(self, "_weights_digest", None) is None:
            digest = hashlib.sha256()
            for name, tensor in sorted(self.model.state_dict().items()):
                digest.update(name.encode())
                flat = tensor.detach().cpu().contiguous().reshape(-1)
                digest.update(flat.view(torch.uint8).numpy().tobytes())
            self._weights_digest = digest.hexdigest()
        dtype = self.autocast
        return json.dumps(
            {
                "backend": "sam2",
                "name": self.name,
                "image_size": int(self.model.image_size),
                "precision": str(dtype) if dtype is not None else "float32",
                "device_type": self.device.type,
                "weights_sha256": self._weights_digest,
            },
            sort_keys=True,
        )

    def embedding_state(self, embedding: ViewEmbedding) -> dict[str, np.ndarray]:
        """The image embedding and both high-resolution levels, widened to float32 (exact)."""
        feats = self._view_features(embedding)
        tensors = [feats.image_embed, *feats.high_res_feats]
        state = {f"level{i}": t.detach().float().cpu().numpy() for i, t in enumerate(tensors)}
        state["dtype"] = np.array(str(feats.image_embed.dtype))
        return state

    def embedding_from_state(
        self, state: dict[str, np.ndarray], image_size: tuple[int, int], key: tuple[int, int]
    ) -> ViewEmbedding:
        """Inverse of :meth:`embedding_state` (checks the shapes against this model)."""
        dtype = getattr(torch, str(state["dtype"]).removeprefix("torch."))
        side = int(self.model.image_size)
        expected = [side // 16, side // 4, side // 8][: int(self.model.num_feature_levels)]
        if sum(key.startswith("level") for key in state) != len(expected):
            raise LfsamError(
                "embedding levels do not match this model; encode the view with this model"
            )
        levels = [
            torch.from_numpy(state[f"level{i}"]).to(self.device, dtype)
            for i in range(len(expected))
        ]
        if [int(level.shape[-1]) for level in levels] != expected:
            raise LfsamError(
                "embedding shapes do not match this model; encode the view with this model"
            )
        feats = Sam2Features(image_embed=levels[0], high_res_feats=levels[1:])
        return ViewEmbedding(image_size=tuple(image_size), key=tuple(key), data=feats)

    @staticmethod
    def _view_features(embedding: ViewEmbedding) -> Sam2Features:
        if not isinstance(embedding.data, Sam2Features):
            raise LfsamError(
                "this embedding was not made by the SAM 2 backend; encode the view with the "
                "same segmenter that decodes it"
            )
        return embedding.data

    # --- prompting ----------------------------------------------------------------------------
    def predict(
        self, embedding: ViewEmbedding, prompts: Prompts, multimask_output: bool = True
    ) -> MaskPrediction:
        """Decode N prompts on one view: prompt encoder + mask decoder, batched.

        Computes what ``SAM2ImagePredictor._predict`` computes (points and boxes merged as
        there: box corners first; a point label of -1 is SAM 2's padding point, one of
        :data:`~lfsam.segmenters.base.ABSENT_POINT` no point at all, masked out in the
        decoder's attention: :attr:`skips_absent_points`), through
        :meth:`CachedFeaturePredictor.predict_prompts`, i.e. the decoder of
        :mod:`lfsam.segmenters.sam2.decoder` that shares the prompt-independent part across
        prompts (issue #5). Prompts go through in groups of :attr:`max_prompts_per_batch`
        (which also caps how many the decoder takes at once).

        Returns
        -------
        MaskPrediction
            ``masks`` (N, K, U, V) bool (logits > threshold after SAM 2's post-processing:
            bilinear upsampling to the view), ``iou_predictions`` (N, K), ``low_res_logits``
            (N, K, image_size/4, image_size/4) float32, clamped to [-32, 32] as SAM 2 returns
            them; K = 3 with ``multimask_output`` else 1.
        """
        u_size, v_size = embedding.image_size
        k = 3 if multimask_output else 1
        n = len(prompts)
        low = int(self.model.image_size) // 4
        if n == 0:
            return MaskPrediction(
                masks=torch.zeros((0, k, u_size, v_size), dtype=torch.bool, device=self.device),
                iou_predictions=torch.zeros((0, k), device=self.device),
                low_res_logits=torch.zeros((0, k, low, low), device=self.device),
            )
        predictor = self._predictor
        feats = self._view_features(embedding)
        predictor.use_features(feats.as_predictor_features(), embedding.image_size)
        predictor.image_state = feats.decoder_state
        predictor.decode_chunk_size = min(
            self.max_prompts_per_batch, default_chunk_size(self.device)
        )
        masks, ious, logits = [], [], []
        try:
            with inference_context(self.device, inference_mode=False, precision=self.precision):
                for start in range(0, n, self.max_prompts_per_batch):
                    self.decoder_calls += 1
                    sub = prompts.subset(slice(start, start + self.max_prompts_per_batch))
                    coords, labels, boxes = self._prompt_tensors(sub, (u_size, v_size))
                    m, iou, lr = predictor.predict_prompts(
                        coords, labels, boxes, multimask_output=multimask_output,
                        absent_points=bool(sub.absent_points),
                    )
                    masks.append(m)
                    ious.append(iou.float())
                    logits.append(lr.float())
            if self.keep_decoder_state:
                feats.decoder_state = predictor.image_state
        finally:
            predictor.reset_predictor()
        return MaskPrediction(
            masks=torch.cat(masks),
            iou_predictions=torch.cat(ious),
            low_res_logits=torch.cat(logits),
        )

    def predict_many(
        self,
        embeddings: Sequence[ViewEmbedding],
        prompts: Sequence[Prompts],
        multimask_output: bool = True,
    ) -> list[MaskPrediction]:
        """Decode the prompts of several views, with :attr:`cross_view_decode` in one decoder
        call per :attr:`max_prompts_per_batch` prompts whatever their views (docs/design.md
        section 3.5, "batched decoder"); else, or for views of different sizes or prompts of
        different shapes, view by view (:meth:`predict`).

        The prompts may be device tensors (:class:`Prompts`): they are moved and transformed
        once for all views, the masks post-processed once, and no value is read back to the
        host.
        """
        sizes = {tuple(e.image_size) for e in embeddings}
        shapes = {prompt_shape(p) for p in prompts}
        if (not self.cross_view_decode or len(embeddings) < 2 or len(sizes) != 1
                or len(shapes) != 1 or len(embeddings) != len(prompts)):
            return super().predict_many(embeddings, prompts, multimask_output)
        hw = sizes.pop()
        with inference_context(self.device, inference_mode=False, precision=self.precision):
            states = []
            for embedding in embeddings:
                feats = self._view_features(embedding)
                state = feats.decoder_state
                if state is None:
                    state = prepare_image(self.model, feats.image_embed, feats.high_res_feats)
                    if self.keep_decoder_state:
                        feats.decoder_state = state
                states.append(state)
            cuda = self.device.type == "cuda"
            out, calls = decode_prompt_batches(
                self.model, stack_states(states), [self._prompt_tensors(p, hw) for p in prompts],
                multimask_output, self.cross_view_rows,
                self.cross_view_rows if cuda else default_chunk_size(self.device),
                image_transforms(self._predictor), hw, self.mask_threshold,
                compiled=self._compiled_pass(),
                absent_points=any(bool(p.absent_points) for p in prompts),
            )
        self.decoder_calls += calls
        return [MaskPrediction(*x) for x in out]

    def _compiled_pass(self) -> Any:
        """The compiled decoder pass of :attr:`compile_decoder` (made once), or None."""
        if self.compile_decoder is not None and self._compiled is None:
            self._compiled = compile_pass(self.compile_decoder)
        return self._compiled

    def _prompt_tensors(
        self, prompts: Prompts, hw: tuple[int, int]
    ) -> tuple[torch.Tensor | None, torch.Tensor | None, torch.Tensor | None]:
        """Prompts in model-input pixels, as ``SAM2ImagePredictor._prep_prompts`` makes them."""
        transforms = image_transforms(self._predictor)
        coords = labels = boxes = None
        if prompts.points is not None:
            pts = torch.as_tensor(prompts.points, dtype=torch.float32, device=self.device)
            coords = transforms.transform_coords(pts, normalize=True, orig_hw=hw)
            labels = torch.as_tensor(prompts.point_labels, dtype=torch.int, device=self.device)
        if prompts.boxes is not None:
            box = torch.as_tensor(prompts.boxes, dtype=torch.float32, device=self.device)
            boxes = transforms.transform_boxes(box, normalize=True, orig_hw=hw)
        return coords, labels, boxes


def _check_images(images: np.ndarray) -> np.ndarray:
    """Validate a batch of views ``(B, U, V, 3)`` uint8 (a single ``(U, V, 3)`` view is allowed)."""
    images = np.asarray(images)
    if images.ndim == 3:
        images = images[None]
    if images.ndim != 4 or images.shape[-1] != 3 or images.dtype != np.uint8:
        raise LfsamError(
            f"views to encode must be a (B, U, V, 3) uint8 array, got {images.shape} {images.dtype}"
        )
    if min(images.shape[:3]) < 1:
        raise LfsamError(f"views to encode are empty: shape {images.shape}")
    return images
