"""SAM 3's concept detector through Hugging Face ``transformers`` (docs/design.md section 9).

``Sam3Model`` with ``Sam3Processor`` (image resize and normalisation, CLIP tokenizer, and
``post_process_instance_segmentation``: instance masks at the view's size, scores, boxes) runs on
any torch device, CPU included. The trained model is loaded from a folder
(:func:`lfsam.segmenters.text.weights.resolve_text_weights`); ``random_weights=True`` builds the
same architecture untrained with a word-hashing tokenizer instead of CLIP's (whose vocabulary
files come with the weights), so it needs no file at all; ``sam3-tiny-test`` is that at the
sizes of :data:`lfsam.segmenters.text.registry.TINY_SAM3_SIZES`.
"""

from __future__ import annotations

import os
import zlib
from typing import Any

import numpy as np
import torch

from lfsam.devices import resolve_device
from lfsam.errors import LfsamError
from lfsam.segmenters.text.base import Detections, TextDetector, View
from lfsam.segmenters.text.registry import (
    DEFAULT_TEXT_THRESHOLD,
    TINY_SAM3_SIZES,
    TINY_TEXT_TEST_MODEL,
    get_text_model_spec,
)
from lfsam.segmenters.text.weights import resolve_text_weights

__all__ = ["Sam3TextDetector", "WordHashTokenizer", "import_sam3", "tiny_sam3_config"]

#: SAM 3 pads every phrase to this many tokens (``Sam3Processor``).
TEXT_LENGTH = 32
#: Mask logits above this are the instance (``post_process_instance_segmentation``'s default).
MASK_THRESHOLD = 0.5


def import_sam3() -> Any:
    """The ``transformers`` module, with SAM 3 in it.

    Raises
    ------
    LfsamError
        If ``transformers`` is missing or too old to have SAM 3.
    """
    try:
        import transformers
    except ImportError:
        raise LfsamError(
            "text prompts with SAM 3 need Hugging Face transformers; install it with "
            "pip install 'lfsam[text]' (or use --text-model oracle on a scene with categories)"
        ) from None
    if not hasattr(transformers, "Sam3Model"):
        raise LfsamError(
            f"transformers {transformers.__version__} has no SAM 3; upgrade it with "
            "pip install 'lfsam[text]'"
        )
    return transformers


def tiny_sam3_config() -> Any:
    """The configuration of ``sam3-tiny-test``: SAM 3's own configuration classes at the sizes
    of :data:`TINY_SAM3_SIZES` (a ViT of 8 x 8 patches, one-layer CLIP text encoder, DETR
    encoder and decoder, 16 queries)."""
    tf = import_sam3()
    from transformers.models.sam3 import configuration_sam3 as c

    k = TINY_SAM3_SIZES
    width, ffn, heads = k["width"], k["ffn"], k["heads"]
    side = k["image_size"] // 14
    vit = c.Sam3ViTConfig(
        hidden_size=width, intermediate_size=ffn, num_hidden_layers=k["vit_layers"],
        num_attention_heads=heads, image_size=k["image_size"], patch_size=14,
        window_size=k["window"], global_attn_indexes=[k["vit_layers"] - 1],
        pretrain_image_size=k["image_size"] // 2,
    )
    vocab = k["text_vocab"]
    text = tf.CLIPTextConfig(
        vocab_size=vocab, hidden_size=width, intermediate_size=ffn, projection_dim=width,
        num_hidden_layers=1, num_attention_heads=heads, max_position_embeddings=TEXT_LENGTH,
        bos_token_id=vocab - 2, eos_token_id=vocab - 1, pad_token_id=0,
    )
    layers = {"hidden_size": width, "num_attention_heads": heads, "intermediate_size": ffn}
    return tf.Sam3Config(
        vision_config=c.Sam3VisionConfig(
            backbone_config=vit, fpn_hidden_size=width,
            backbone_feature_sizes=[[side * 4] * 2, [side * 2] * 2, [side] * 2],
        ),
        text_config=text,
        geometry_encoder_config=c.Sam3GeometryEncoderConfig(num_layers=1, **layers),
        detr_encoder_config=c.Sam3DETREncoderConfig(num_layers=1, **layers),
        detr_decoder_config=c.Sam3DETRDecoderConfig(
            num_layers=1, num_queries=k["queries"], **layers
        ),
        mask_decoder_config=c.Sam3MaskDecoderConfig(hidden_size=width, num_attention_heads=heads),
    )


class WordHashTokenizer:
    """The tiny model's tokenizer: each lower-case word -> a fixed id by CRC-32, between a
    begin and an end token, padded to :data:`TEXT_LENGTH` (deterministic, no vocabulary file)."""

    def __init__(self, vocab_size: int) -> None:
        self.vocab_size = int(vocab_size)

    def __call__(self, texts: list[str], **_: Any) -> dict[str, torch.Tensor]:
        ids = torch.zeros(len(texts), TEXT_LENGTH, dtype=torch.long)
        mask = torch.zeros_like(ids)
        words_room = self.vocab_size - 3
        for row, text in enumerate(texts):
            words = [1 + zlib.crc32(w.encode()) % words_room for w in text.lower().split()]
            tokens = [self.vocab_size - 2, *words[: TEXT_LENGTH - 2], self.vocab_size - 1]
            ids[row, : len(tokens)] = torch.tensor(tokens)
            mask[row, : len(tokens)] = 1
        return {"input_ids": ids, "attention_mask": mask}


class Sam3TextDetector(TextDetector):
    """SAM 3's concept detector (``--text-model sam3`` or ``sam3-tiny-test``).

    Parameters
    ----------
    name : str
        ``sam3`` or ``sam3-tiny-test``.
    checkpoint : path, optional
        A local copy of the hub repository (``--text-checkpoint DIR``).
    random_weights : bool
        The architecture untrained (seeded); required for ``sam3-tiny-test`` without a copy.
    device : str or torch.device, optional
        Default ``auto`` (:func:`lfsam.devices.resolve_device`).
    seed : int
        Seed of random weights.

    Raises
    ------
    LfsamError
        ``transformers`` missing, or weights that cannot be had (one line saying how to get
        them; :func:`lfsam.segmenters.text.weights.resolve_text_weights`).
    """

    default_threshold = DEFAULT_TEXT_THRESHOLD

    def __init__(
        self,
        name: str,
        *,
        checkpoint: str | os.PathLike | None = None,
        random_weights: bool = False,
        device: str | torch.device | None = None,
        seed: int = 0,
    ) -> None:
        get_text_model_spec(name)
        folder = None
        if checkpoint is not None or not random_weights:
            folder = resolve_text_weights(name, checkpoint)  # fails at once, before any import
        tf = import_sam3()
        self.name = name
        self.random_weights = folder is None
        self.device = resolve_device(device)
        self.seed = int(seed)
        if folder is not None:
            self.model = tf.Sam3Model.from_pretrained(str(folder))
            processor = tf.Sam3Processor.from_pretrained(str(folder))
            self.image_processor, self.tokenizer = processor.image_processor, processor.tokenizer
        else:
            config = tiny_sam3_config() if name == TINY_TEXT_TEST_MODEL else tf.Sam3Config()
            with torch.random.fork_rng(devices=[]):
                torch.manual_seed(self.seed)
                self.model = tf.Sam3Model(config)
            side = int(config.vision_config.image_size)
            self.image_processor = tf.Sam3ImageProcessor(size={"height": side, "width": side})
            # random weights: CLIP's vocabulary would add nothing but a download
            self.tokenizer = WordHashTokenizer(config.text_config.vocab_size)
        self.model.to(self.device).eval()

    def _detect(
        self, image: np.ndarray, phrase: str, view: View | None, threshold: float
    ) -> Detections:
        height, width = image.shape[:2]
        pixels = self.image_processor(image, return_tensors="pt")["pixel_values"]
        text = self.tokenizer(
            [phrase], padding="max_length", max_length=TEXT_LENGTH, return_tensors="pt"
        )
        inputs = {
            "pixel_values": pixels.to(self.device),
            "input_ids": text["input_ids"].to(self.device),
            "attention_mask": text["attention_mask"].to(self.device),
        }
        with torch.inference_mode():
            outputs = self.model(**inputs)
        (found,) = self.image_processor.post_process_instance_segmentation(
            outputs, threshold=threshold, mask_threshold=MASK_THRESHOLD,
            target_sizes=[(height, width)],
        )
        return Detections.build(
            phrase, found["masks"].cpu().numpy(), found["scores"].float().cpu().numpy(),
            (height, width),
        )

    def describe(self) -> dict[str, Any]:
        """A JSON-ready description for result metadata."""
        return {**super().describe(), "backend": "sam3 (transformers)", "device": str(self.device),
                "seed": self.seed}

