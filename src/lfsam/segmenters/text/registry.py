"""Which text detectors lfsam knows (``--text-model``): SAM 3, a tiny SAM 3 for tests, the
oracle (docs/design.md section 9).

``sam3`` is Meta's SAM 3 (Carion et al. 2025, "SAM 3: Segment Anything with Concepts") as
Hugging Face ``transformers`` ships it (``Sam3Model``, ``Sam3Processor``), weights from the
gated repository ``facebook/sam3``. ``sam3-tiny-test`` is the same architecture built from
``transformers``' own configuration classes at a tiny size (:data:`TINY_SAM3_SIZES`); it has no
published weights and runs with random ones, so the whole SAM 3 code path runs in tests on a
CPU in well under a second per view.
"""

from __future__ import annotations

from dataclasses import dataclass

from lfsam.errors import LfsamError

__all__ = [
    "DEFAULT_TEXT_MODEL",
    "DEFAULT_TEXT_THRESHOLD",
    "TEXT_MODELS",
    "TEXT_ORACLE",
    "TINY_SAM3_SIZES",
    "TINY_TEXT_TEST_MODEL",
    "TextModelSpec",
    "get_text_model_spec",
]

DEFAULT_TEXT_MODEL = "sam3"
"""SAM 3's concept detector (``facebook/sam3``)."""

TEXT_ORACLE = "oracle"
"""The ground-truth text detector (the default with ``--model oracle``)."""

TINY_TEXT_TEST_MODEL = "sam3-tiny-test"
"""A 0.26 M-parameter SAM 3 for tests (random weights)."""

DEFAULT_TEXT_THRESHOLD = 0.3
"""The score an instance needs by default: the default ``threshold`` of
``Sam3Processor.post_process_instance_segmentation`` (checked against it in
``tests/test_text_detectors.py``)."""

TINY_SAM3_SIZES = {
    "image_size": 112,  # 8 x 8 patches of 14 pixels
    "width": 32,  # every transformer's width
    "ffn": 64,
    "heads": 2,
    "vit_layers": 2,
    "window": 4,
    "text_vocab": 512,
    "queries": 16,
}
"""The tiny SAM 3's sizes (:func:`lfsam.segmenters.text.sam3.tiny_sam3_config`)."""


@dataclass(frozen=True)
class TextModelSpec:
    """One text detector: where its weights live and how big it is.

    Parameters
    ----------
    name : str
        ``--text-model`` name.
    hub_id : str or None
        Model-hub repository of the weights (None: none published).
    params : int
        Parameters of the architecture (``sum(p.numel())`` of the built model).
    gated : bool
        Whether the hub asks users to request access first.
    description : str
        One line for ``lfsam models``.
    """

    name: str
    hub_id: str | None
    params: int
    gated: bool = False
    description: str = ""

    @property
    def random_only(self) -> bool:
        """True if no published weights exist."""
        return self.hub_id is None


TEXT_MODELS: dict[str, TextModelSpec] = {
    spec.name: spec
    for spec in (
        TextModelSpec(
            DEFAULT_TEXT_MODEL, "facebook/sam3", 840_376_374, gated=True,
            description="SAM 3 concept detector (text prompts; gated weights)",
        ),
        TextModelSpec(
            TINY_TEXT_TEST_MODEL, None, 256_210,
            description="tiny SAM 3 for tests (random weights: no useful masks)",
        ),
    )
}
"""Every SAM 3 text detector by name (the oracle is not listed: it has no weights)."""


def get_text_model_spec(name: str) -> TextModelSpec:
    """The spec of a SAM 3 text detector.

    Raises
    ------
    LfsamError
        If the name is unknown (the message lists the known names).
    """
    try:
        return TEXT_MODELS[name]
    except KeyError:
        known = ", ".join([*TEXT_MODELS, TEXT_ORACLE])
        raise LfsamError(f"unknown text model {name!r}; choose one of: {known}") from None
