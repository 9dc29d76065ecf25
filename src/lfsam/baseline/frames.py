"""Light-field views as SAM 2 video frames, straight from memory.

Meta's ``SAM2VideoPredictor.init_state`` reads a video from a folder of JPEG files
(``sam2.utils.misc.load_video_frames``): each frame is resized to the model's square input with
PIL (``Image.resize``, bicubic for RGB), scaled to [0, 1], and normalised with the ImageNet mean
and standard deviation. The video baseline (paper section 4) feeds the views in snake order
through exactly that transform, without the lossy JPEG round trip, and builds the inference state
the predictor expects around the resulting tensor (:func:`init_video_state`).

Two frame transforms are offered:

``"video"`` (default)
    ``load_video_frames`` bit for bit: PIL bicubic resize of the uint8 view, ``/ 255`` in float64,
    then float32 normalisation on the model's device.
``"image"``
    The image predictor's transform (``sam2.utils.transforms.SAM2Transforms``: torchvision
    ``Resize`` of the float view, then ``Normalize``), batched on the model's device: the encoder
    then sees exactly the tensors LFSAM's :class:`~lfsam.segmenters.sam2.backend.Sam2Segmenter`
    encodes.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

import numpy as np
import torch

from lfsam.errors import LfsamError
from lfsam.segmenters.sam2.adapter import IMAGENET_MEAN, IMAGENET_STD

__all__ = ["FRAME_TRANSFORMS", "IMAGENET_MEAN", "IMAGENET_STD", "init_video_state", "video_frames"]

FRAME_TRANSFORMS = ("video", "image")
"""Names of the frame transforms of :func:`video_frames`."""

_IMAGE_CHUNK = 8  # views resized together by the "image" transform (bounds the float buffers)


def video_frames(
    views: np.ndarray,
    image_size: int,
    device: torch.device | str = "cpu",
    transform: str = "video",
) -> torch.Tensor:
    """Resize and normalise uint8 views into SAM 2's video-frame tensor.

    Parameters
    ----------
    views : (F, U, V, 3) uint8 ndarray
        The frames in video order (for the baseline: the views in snake order).
    image_size : int
        The model's square input side (``model.image_size``: 1024 for the published models).
    device : torch.device or str
        Where the frames live (the model's device, as ``init_state`` without offloading).
    transform : {"video", "image"}
        ``"video"``: ``sam2.utils.misc.load_video_frames`` without the JPEG files (PIL bicubic
        resize); ``"image"``: ``SAM2Transforms`` of the image predictor (torchvision resize).

    Returns
    -------
    frames : (F, 3, image_size, image_size) float32 tensor on ``device``

    Raises
    ------
    LfsamError
        If ``views`` is not a (F, U, V, 3) uint8 array or ``transform`` is unknown.
    """
    views = np.asarray(views)
    if views.ndim != 4 or views.shape[-1] != 3 or views.dtype != np.uint8 or len(views) == 0:
        raise LfsamError(
            f"video frames must be a non-empty (F, U, V, 3) uint8 array, got {views.shape} "
            f"{views.dtype}"
        )
    device = torch.device(device)
    if transform == "video":
        return _pil_frames(views, image_size, device)
    if transform == "image":
        return _torch_frames(views, image_size, device)
    raise LfsamError(
        f"unknown frame transform {transform!r}; use one of {', '.join(FRAME_TRANSFORMS)}"
    )


def _pil_frames(views: np.ndarray, image_size: int, device: torch.device) -> torch.Tensor:
    """``load_video_frames_from_jpg_images`` on in-memory views (same operations, same order)."""
    from PIL import Image

    frames = torch.zeros(len(views), 3, image_size, image_size, dtype=torch.float32)
    for n, view in enumerate(views):  # one C-level resize per view, as sam2 does per file
        resized = np.asarray(Image.fromarray(view).resize((image_size, image_size)))
        frames[n] = torch.from_numpy(resized / 255.0).permute(2, 0, 1)
    frames = frames.to(device)
    mean = torch.tensor(IMAGENET_MEAN, dtype=torch.float32, device=device)[:, None, None]
    std = torch.tensor(IMAGENET_STD, dtype=torch.float32, device=device)[:, None, None]
    frames -= mean
    frames /= std
    return frames


def _torch_frames(views: np.ndarray, image_size: int, device: torch.device) -> torch.Tensor:
    """``SAM2Transforms`` (resize + normalise) of the image predictor, in batches on ``device``.

    The same torchvision modules as ``SAM2Transforms.transforms``, run eagerly instead of through
    ``torch.jit.script`` (seconds of compilation per call on a CPU; the tests check equality).
    """
    from torchvision.transforms import Normalize, Resize

    transforms = torch.nn.Sequential(
        Resize((image_size, image_size)), Normalize(IMAGENET_MEAN, IMAGENET_STD)
    )
    out = torch.empty(len(views), 3, image_size, image_size, dtype=torch.float32, device=device)
    for start in range(0, len(views), _IMAGE_CHUNK):
        chunk = torch.from_numpy(np.ascontiguousarray(views[start : start + _IMAGE_CHUNK]))
        chunk = chunk.to(device).permute(0, 3, 1, 2).float().div_(255.0)
        out[start : start + len(chunk)] = transforms(chunk)
    return out


def init_video_state(
    predictor: Any,
    frames: torch.Tensor,
    video_size: tuple[int, int],
    *,
    offload_state_to_cpu: bool = False,
) -> dict[str, Any]:
    """The inference state of ``SAM2VideoPredictor.init_state``, for frames already in memory.

    Same keys and meaning as ``init_state`` of ``sam2`` 1.1 (checked against it in the tests):
    the frames, the original frame size (masks are returned at that size), devices, and the
    empty per-object input, output and tracking tables. Unlike ``init_state``, no frame is
    encoded here; the first prompt encodes its frame.

    Parameters
    ----------
    predictor : SAM2VideoPredictor
        The video model (its device is the compute device).
    frames : (F, 3, S, S) float tensor
        From :func:`video_frames`; or anything with ``len``, ``device`` and frame indexing
        (:mod:`lfsam.video.memory.sam2_memory` holds one frame at a time).
    video_size : (U, V)
        Pixel rows and columns of the original views.
    offload_state_to_cpu : bool
        Keep tracking outputs in CPU memory (``init_state``'s option of the same name).

    Returns
    -------
    state : dict
        For ``add_new_mask``, ``propagate_in_video`` and ``reset_state``.
    """
    device = predictor.device
    return {
        "images": frames,
        "num_frames": len(frames),
        "offload_video_to_cpu": frames.device.type == "cpu" and device.type != "cpu",
        "offload_state_to_cpu": offload_state_to_cpu,
        "video_height": int(video_size[0]),
        "video_width": int(video_size[1]),
        "device": device,
        "storage_device": torch.device("cpu") if offload_state_to_cpu else device,
        "point_inputs_per_obj": {},
        "mask_inputs_per_obj": {},
        "cached_features": {},
        "constants": {},
        "obj_id_to_idx": OrderedDict(),
        "obj_idx_to_id": OrderedDict(),
        "obj_ids": [],
        "output_dict_per_obj": {},
        "temp_output_dict_per_obj": {},
        "frames_tracked_per_obj": {},
    }
