"""Where the pipeline's disparity comes from: estimated, ground truth, a file or an array.

The one resolver of the package (docs/design.md sections 3.2 and 8): every command and entry point
that consumes disparity (``lfsam segment --disparity``, ``lfsam evaluate``, :func:`lfsam.segment`,
the interactive predictor through :class:`~lfsam.disparity.views.ViewDisparities`) names its
source the same way and asks for the view it needs:

- ``"estimate"``: the default estimator (:data:`lfsam.disparity.methods.DEFAULT_METHOD`, the
  occlusion-aware cost volume, without its fusion with the structure tensor:
  :data:`CARRYING_OPTIONS`) run for that view;
- ``"gt"``: the light field's ground truth of that view; with a center-only ground truth, the
  center map forward-warped into the view
  (:func:`~lfsam.disparity.center_warp.warp_center_disparity`);
- a ``.npy`` file or a NumPy array holding a ``(U, V)`` map of the center view (forward-warped
  for another view) or an ``(S, T, U, V)`` map of every view.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from lfsam.disparity.center_warp import warp_center_disparity
from lfsam.disparity.epi import resolve_view
from lfsam.disparity.methods import estimate_disparity
from lfsam.errors import LfsamError
from lfsam.lightfield import LightField

__all__ = ["load_disparity_spec", "resolve_disparity", "resolve_view_disparity"]

#: Options of the default estimator when its map carries masks (``--disparity estimate`` of the
#: segmentation commands): the occlusion-aware cost volume without its fusion with the structure
#: tensor. The fusion lowers the depth errors of ``lfsam disparity`` (docs/performance.md,
#: "Disparity estimation") but the masks carried with it are worse: on 9x9 synthetic scenes
#: (oracle, estimated disparity) 13% more wrong pixels in the views filled by
#: ``--refine-views sparse`` and a lower SIoU with every view refined (docs/design.md
#: section 3.2). It also keeps the single feature scale (``wide_feature_radius=None``): the
#: second, wider scale (issue 45, third round) roughly doubles the estimate's time and has not
#: been measured on carried masks, so segmentation keeps the estimate it was measured with; nor
#: the fifth round's local surface fit (``surface_fit=False``), not measured on carried masks
#: either.
CARRYING_OPTIONS: dict[str, bool | None] = {
    "fusion": False,
    "wide_feature_radius": None,
    "surface_fit": False,
}

DisparitySpec = str | os.PathLike | np.ndarray


def _check_map(array: np.ndarray, lightfield: LightField, what: str) -> np.ndarray:
    """``array`` as float32 if it is a finite ``(U, V)`` or ``(S, T, U, V)`` disparity map of
    ``lightfield`` (non-finite values in absent views of a partial grid are allowed)."""
    size = lightfield.view_shape
    full = lightfield.grid_shape + size
    if array.shape not in (size, full):
        raise LfsamError(
            f"{what} has shape {array.shape}, but the light field is "
            f"{full[0]}x{full[1]} views of {size[0]}x{size[1]}; give a (U, V) map of the center "
            f"view or an (S, T, U, V) map of every view"
        )
    if not (np.issubdtype(array.dtype, np.number) or array.dtype == bool):
        raise LfsamError(f"{what} does not hold numbers (dtype {array.dtype})")
    array = array.astype(np.float32)
    used = array if array.ndim == 2 else array[lightfield.present]
    bad = int(np.count_nonzero(~np.isfinite(used)))
    if bad:
        raise LfsamError(
            f"{what} has {bad} non-finite values (NaN or inf); fill them (e.g. from neighbours) "
            "before use, or use --disparity estimate"
        )
    return array


def load_disparity_spec(
    spec: DisparitySpec, lightfield: LightField
) -> tuple[str | np.ndarray, str]:
    """Check a disparity source and read it if it is a file.

    Parameters
    ----------
    spec : {"estimate", "gt"}, path to a .npy, or ndarray
    lightfield : LightField

    Returns
    -------
    spec : {"estimate", "gt"} or ndarray
        The keyword, or the checked float32 ``(U, V)`` / ``(S, T, U, V)`` map.
    name : str
        ``"estimate"``, ``"gt"``, ``"file:PATH"`` or ``"array"``.

    Raises
    ------
    LfsamError
        Unknown keyword, file missing or unreadable, wrong shape, non-numeric or non-finite map.
    """
    if isinstance(spec, np.ndarray):
        return _check_map(spec, lightfield, "disparity array"), "array"
    spec_text = str(spec)
    if spec_text in ("estimate", "gt"):
        return spec_text, spec_text
    path = Path(spec_text)
    if path.suffix.lower() != ".npy":
        raise LfsamError(
            f"--disparity must be 'estimate', 'gt' or a .npy file, got {spec_text!r}"
        )
    if not path.is_file():
        raise LfsamError(f"disparity file {spec_text!r} not found")
    try:
        array = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise LfsamError(f"cannot read disparity file {spec_text!r}: {exc}") from None
    return _check_map(array, lightfield, f"disparity file {spec_text!r}"), f"file:{path}"


def _from_map(
    array: np.ndarray,
    lightfield: LightField,
    view: tuple[int, int],
    name: str,
    device: str | None,
) -> tuple[np.ndarray, str, np.ndarray | None]:
    """The disparity of ``view`` from a checked ``(U, V)`` center or ``(S, T, U, V)`` map."""
    if array.ndim == 4:
        if not lightfield.present[view]:
            raise LfsamError(
                f"view {view} is absent from this partial grid; choose a view that exists"
            )
        return array[view], name, None
    if view == lightfield.center:
        return array, name, None
    center = lightfield.center
    offset = (view[0] - center[0], view[1] - center[1])
    disparity, holes = warp_center_disparity(array, offset, device=device)
    note = (
        f"{name} (center map forward-warped to view ({view[0]}, {view[1]}) with a z-buffer; "
        f"{int(holes.sum())} hole pixels filled along the epipolar line, farther side first)"
    )
    return disparity, note, holes


def resolve_view_disparity(
    spec: str | np.ndarray,
    lightfield: LightField,
    *,
    view: tuple[int, int],
    device: str | None = None,
    name: str | None = None,
) -> tuple[np.ndarray, str, np.ndarray | None]:
    """:func:`resolve_disparity` for a spec already checked by :func:`load_disparity_spec`,
    also returning the hole pixels of a forward warp (None when nothing was warped)."""
    if isinstance(spec, np.ndarray):
        return _from_map(spec, lightfield, view, name or "array", device)
    if spec == "estimate":
        estimate = estimate_disparity(lightfield, device=device, view=view,
                                      **CARRYING_OPTIONS)
        low, high = estimate.disparity_range
        where = "" if view == lightfield.center else f" view ({view[0]}, {view[1]})"
        return (
            np.asarray(estimate.disparity, dtype=np.float32),
            f"estimate{where} [{low:.2f}, {high:.2f}]",
            None,
        )
    if spec == "gt":
        if lightfield.disparity is None:
            raise LfsamError(
                "this light field has no ground-truth disparity; use --disparity estimate or "
                "--disparity FILE.npy"
            )
        disparity, source, holes = _from_map(
            lightfield.disparity, lightfield, view, "gt", device
        )
        if holes is not None:
            source = source.replace("center map", "center ground truth", 1)
        return np.asarray(disparity, dtype=np.float32), source, holes
    raise LfsamError(f"--disparity must be 'estimate', 'gt' or a .npy file, got {spec!r}")


def resolve_disparity(
    spec: DisparitySpec,
    lightfield: LightField,
    *,
    view: tuple[int, int] | None = None,
    device: str | None = None,
) -> tuple[np.ndarray, str]:
    """The disparity of one view named by ``spec``, in the package convention.

    Parameters
    ----------
    spec : {"estimate", "gt"}, path to a .npy, or ndarray
        ``"estimate"``: the default estimator (:func:`lfsam.disparity.estimate_disparity`, the
        occlusion-aware cost volume) for the view;
        ``"gt"``: the light field's ground truth of the view (a center-only ground truth is
        forward-warped into another view with a z-buffer, holes filled from the farther side);
        otherwise a ``.npy`` file or an array holding a ``(U, V)`` map of the center view
        (forward-warped likewise for another view) or an ``(S, T, U, V)`` map of every view, in
        the convention of :mod:`lfsam.geometry`.
    lightfield : LightField
    view : (s, t), optional
        The view (0-based view row and column, docs/design.md section 8); default the center.
    device : str, optional
        Where the estimator and warps run.

    Returns
    -------
    disparity : (U, V) float32 ndarray
    source : str
        A short description for result metadata (e.g. ``"estimate [-2.10, 1.90]"``, ``"gt"``,
        ``"file:/path/disp.npy"``, ``"array"``; a forward warp says so).

    Raises
    ------
    LfsamError
        View outside the grid or absent, ground truth absent, file missing or unreadable, a map
        of the wrong shape or with non-finite values.

    Examples
    --------
    >>> from lfsam.synth import generate_scene
    >>> lf = generate_scene(grid=(3, 3), size=(24, 32), num_objects=1)
    >>> disparity, source = resolve_disparity("gt", lf, view=(0, 0))
    >>> disparity.shape, source
    ((24, 32), 'gt')
    """
    reference = resolve_view(lightfield.grid_shape, view)
    checked, name = load_disparity_spec(spec, lightfield)
    disparity, source, _ = resolve_view_disparity(
        checked, lightfield, view=reference, device=device, name=name
    )
    return disparity, source
