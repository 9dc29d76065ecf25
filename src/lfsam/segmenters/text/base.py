"""The interface of a text detector and what it returns (docs/design.md section 9).

A detector looks at one view and a phrase (a noun phrase such as ``"red cup"``, a *concept* in
SAM 3's terms) and returns every instance it finds: one boolean mask per instance at the view's
resolution with the detector's score in [0, 1], best first. It knows nothing of light fields
beyond the view it is shown; carrying the instances into the other views is the pipeline's job
(:func:`lfsam.text_search.add_text`).
"""

from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import Any

import numpy as np

from lfsam.errors import LfsamError

__all__ = ["Detections", "TextDetector", "phrase_matches"]

View = tuple[int, int]


@dataclass(frozen=True)
class Detections:
    """The instances of one phrase found in one view.

    Parameters
    ----------
    phrase : str
    masks : (N, U, V) bool ndarray
        One non-empty mask per instance, best score first.
    scores : (N,) float32 ndarray
        The detector's score of each instance, in [0, 1].
    """

    phrase: str
    masks: np.ndarray
    scores: np.ndarray

    def __len__(self) -> int:
        return int(self.masks.shape[0])

    @classmethod
    def build(
        cls, phrase: str, masks: np.ndarray, scores: np.ndarray, view_shape: tuple[int, int]
    ) -> Detections:
        """Empty masks dropped, the rest sorted by score (best first; ties keep their order)."""
        masks = np.asarray(masks, dtype=bool).reshape(-1, *view_shape)
        scores = np.asarray(scores, dtype=np.float32).reshape(-1)
        keep = masks.reshape(len(masks), view_shape[0] * view_shape[1]).any(axis=1)
        masks, scores = masks[keep], scores[keep]
        order = np.argsort(-scores, kind="stable")
        return cls(phrase, masks[order], scores[order])


def _words(text: str) -> list[str]:
    """Lower-case words, a plural ``s`` dropped (``"discs"`` -> ``"disc"``)."""
    words = []
    for word in text.lower().replace("-", " ").replace("_", " ").split():
        if len(word) > 3 and word.endswith("s") and not word.endswith("ss"):
            word = word[:-1]
        words.append(word)
    return words


def phrase_matches(phrase: str, category: str) -> bool:
    """Whether ``phrase`` names ``category``: every word of the phrase is a word of the
    category, singular or plural (``"disc"``, ``"discs"`` and ``"brick disc"`` name
    ``"brick disc"``; ``"red disc"`` does not). The oracle's rule for a text prompt.

    Examples
    --------
    >>> phrase_matches("discs", "brick disc"), phrase_matches("gravel disc", "brick disc")
    (True, False)
    """
    wanted = _words(phrase)
    have = set(_words(category))
    return bool(wanted) and all(word in have for word in wanted)


class TextDetector(abc.ABC):
    """Finds every instance of a phrase in one view.

    Attributes
    ----------
    name : str
        The model's name (``--text-model``).
    random_weights : bool
        Whether the weights are untrained (speed tests only; recorded in results).
    default_threshold : float
        The score an instance needs when the caller gives no threshold.
    """

    name: str = "text-detector"
    random_weights: bool = False
    default_threshold: float = 0.5

    def detect(
        self,
        image: np.ndarray,
        phrase: str,
        *,
        view: View | None = None,
        threshold: float | None = None,
    ) -> Detections:
        """Every instance of ``phrase`` in ``image`` with a score of at least ``threshold``.

        Parameters
        ----------
        image : (U, V, 3) uint8 ndarray
            The view.
        phrase : str
            What to find.
        view : (s, t), optional
            Which view of the light field ``image`` is (the oracle needs it).
        threshold : float, optional
            Default :attr:`default_threshold`.

        Raises
        ------
        LfsamError
            A threshold outside [0, 1], an image that is not (U, V, 3) uint8, or what the
            backend cannot answer (e.g. the oracle on a light field without categories).
        """
        threshold = self.default_threshold if threshold is None else float(threshold)
        if not 0.0 <= threshold <= 1.0:
            raise LfsamError(f"the text threshold must be in [0, 1], got {threshold:g}")
        image = np.asarray(image)
        if image.ndim != 3 or image.shape[-1] != 3 or image.dtype != np.uint8:
            raise LfsamError(
                f"a text detector takes one (U, V, 3) uint8 view, got {image.dtype} {image.shape}"
            )
        return self._detect(image, phrase, view, threshold)

    @abc.abstractmethod
    def _detect(
        self, image: np.ndarray, phrase: str, view: View | None, threshold: float
    ) -> Detections:
        """The backend's answer (arguments checked)."""

    def describe(self) -> dict[str, Any]:
        """A JSON-ready description for result metadata."""
        return {
            "name": self.name,
            "random_weights": bool(self.random_weights),
            "default_threshold": self.default_threshold,
        }
