"""Small torch filters shared by the disparity estimators: Gaussian, box and guided smoothing.

All filters work on tensors of shape ``(..., rows, cols)`` on any device, are separable and use
reflected borders (replicated where an image is too small to reflect), so that a constant image
stays constant and there is no darkening at the frame border.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F

__all__ = [
    "box_blur",
    "box_blur_rect",
    "colour_guided_filter",
    "gaussian_blur",
    "gaussian_kernel1d",
    "guided_filter",
    "smooth_axis",
]


def gaussian_kernel1d(sigma: float, device: torch.device | None = None) -> torch.Tensor:
    """Normalised sampled Gaussian of standard deviation ``sigma``, radius ``ceil(3 sigma)``.

    Parameters
    ----------
    sigma : float
        Standard deviation in samples (> 0).
    device : torch.device, optional
        Device of the returned kernel.

    Returns
    -------
    kernel : torch.Tensor, shape (2 * radius + 1,), float32, summing to 1
    """
    radius = max(1, math.ceil(3.0 * sigma))
    x = torch.arange(-radius, radius + 1, dtype=torch.float32, device=device)
    kernel = torch.exp(-0.5 * (x / sigma) ** 2)
    return kernel / kernel.sum()


def smooth_axis(image: torch.Tensor, kernel: torch.Tensor, axis: int) -> torch.Tensor:
    """Correlate ``image`` with a 1-D odd-length ``kernel`` along ``axis`` (-1 or -2).

    Borders are reflected (replicated when the axis is shorter than the kernel radius). Computed
    as a weighted sum of shifted slices, one per tap: for the short kernels used here this is
    several times faster on a CPU than a one-channel ``conv2d``, on any device.

    Raises
    ------
    ValueError
        If ``axis`` is neither -1 nor -2 (a fault of the calling code).
    """
    if axis not in (-1, -2):
        raise ValueError("axis must be -1 (columns) or -2 (rows)")
    radius = kernel.numel() // 2
    shape = image.shape
    x = image.reshape(-1, 1, shape[-2], shape[-1])
    length = shape[axis]
    mode = "reflect" if length > radius else "replicate"
    pad = (radius, radius, 0, 0) if axis == -1 else (0, 0, radius, radius)
    x = F.pad(x, pad, mode=mode)
    taps = kernel.tolist()
    out = x.narrow(axis, 0, length) * taps[0]
    for offset in range(1, len(taps)):
        out.add_(x.narrow(axis, offset, length), alpha=taps[offset])
    return out.reshape(shape)


def gaussian_blur(image: torch.Tensor, sigma: float) -> torch.Tensor:
    """Isotropic Gaussian smoothing of the last two axes (``sigma`` in pixels; 0 = identity)."""
    if sigma <= 0:
        return image
    kernel = gaussian_kernel1d(sigma, image.device)
    return smooth_axis(smooth_axis(image, kernel, -1), kernel, -2)


#: :func:`box_blur` windows up to this radius are sums of shifted slices (measured faster on a CPU).
_SLICES_MAX_RADIUS = 2


def box_blur(image: torch.Tensor, radius: int) -> torch.Tensor:
    """Mean over a ``(2 radius + 1)^2`` window of the last two axes (borders replicated).

    Windows up to 5 x 5 add the shifted slices of the padded image in the window's row-major
    order, then divide: bit for bit ``avg_pool2d``'s sum, 3-5 times faster on a CPU (one
    vectorised addition per tap instead of a per-pixel window loop). Wider windows are
    separable running means (``avg_pool1d`` along each axis), whose cost grows only linearly
    with the window width.
    """
    if radius <= 0:
        return image
    shape = image.shape
    size = 2 * radius + 1
    if radius <= _SLICES_MAX_RADIUS:
        rows, cols = shape[-2], shape[-1]
        x = image.reshape(-1, 1, rows, cols)
        x = F.pad(x, (radius, radius, radius, radius), mode="replicate")[:, 0]
        out = x[:, :rows, :cols].clone()
        for i in range(size):
            for j in range(size):
                if i or j:
                    out.add_(x[:, i : i + rows, j : j + cols])
        return out.div_(size * size).reshape(shape)
    x = image.reshape(-1, shape[-2], shape[-1])
    x = F.pad(x, (radius, radius), mode="replicate")
    x = F.avg_pool1d(x, size, stride=1)
    x = x.transpose(1, 2)
    x = F.pad(x, (radius, radius), mode="replicate")
    x = F.avg_pool1d(x, size, stride=1).transpose(1, 2)
    return x.reshape(shape)


def guided_filter(
    guide: torch.Tensor, image: torch.Tensor, radius: int, eps: float
) -> torch.Tensor:
    """Edge-preserving smoothing of ``image`` steered by a gray ``guide`` (guided filter).

    In every ``(2 radius + 1)^2`` window the output is the least-squares affine function of the
    guide, ``q = a I + b`` with ``a = cov(I, p) / (var(I) + eps)``, ``b = mean(p) - a mean(I)``;
    the coefficients of all windows covering a pixel are averaged (He, Sun & Tang, "Guided image
    filtering", ECCV 2010 / TPAMI 2013, eqs. 7-8). Where the guide has an edge (``var(I) >> eps``)
    the output follows it; in flat regions it is the box mean. Its cost does not depend on the
    radius (box filters, :func:`box_blur`). As the cost-volume aggregation of local stereo
    (Hosni et al., "Fast cost-volume filtering for visual correspondence and beyond", TPAMI 2013;
    docs/design.md section 3.2) every slice ``image[k]`` is filtered with the same guide.

    Parameters
    ----------
    guide : torch.Tensor, shape (rows, cols)
        Gray guide image (intensities in [0, 1]).
    image : torch.Tensor, shape (..., rows, cols)
        What to smooth (e.g. a cost volume ``(D, rows, cols)``).
    radius : int
        Window radius in pixels (0 returns ``image``).
    eps : float
        Regulariser: guide variances well below it count as flat.

    Returns
    -------
    torch.Tensor, shape of ``image``
    """
    if radius <= 0:
        return image
    mean_i = box_blur(guide, radius)
    var_i = box_blur(guide * guide, radius) - mean_i * mean_i
    mean_p = box_blur(image, radius)
    a = (box_blur(image * guide, radius) - mean_i * mean_p) / (var_i + eps)
    b = mean_p - a * mean_i
    return box_blur(a, radius) * guide + box_blur(b, radius)


def _shrink_border(x: torch.Tensor, radius: int) -> torch.Tensor:
    """Divide the outermost ``radius`` positions of the last axis of ``x``, box means of a
    zero-padded ``2 radius + 1`` window, by the share of their window inside the frame (the
    positions further in have the whole window inside)."""
    length = x.shape[-1]
    position = torch.arange(length, device=x.device)
    share = ((position + radius).clamp(max=length - 1) - (position - radius).clamp(min=0) + 1)
    share = share.to(x.dtype) / (2 * radius + 1)
    if length <= 2 * radius:
        return x / share
    x[..., :radius] /= share[:radius]
    x[..., length - radius :] /= share[length - radius :]
    return x


def box_blur_rect(
    image: torch.Tensor, radius_rows: int, radius_cols: int, border: str = "replicate"
) -> torch.Tensor:
    """Mean over a ``(2 radius_rows + 1) x (2 radius_cols + 1)`` window of the last two axes.

    Separable running means (``avg_pool1d`` along each axis); a radius of 0 leaves that axis
    alone, so ``(0, r)`` is a horizontal line window and ``(r, 0)`` a vertical one (the oriented
    windows of :mod:`lfsam.disparity.aggregation`). At the frame's border, ``border="replicate"``
    repeats the outermost pixels (the outermost pixel then weighs ``(r + 1) / (2 r + 1)`` of a
    border pixel's window), ``border="shrink"`` takes the mean over the window's pixels inside
    the frame (the normalised box filter of He et al.'s guided filter, ``box(p) / box(1)``).

    Raises
    ------
    ValueError
        If ``border`` is neither ``"replicate"`` nor ``"shrink"`` (the caller's code is at fault).
    """
    if border not in ("replicate", "shrink"):
        raise ValueError(f"unknown border {border!r}: use 'replicate' or 'shrink'")
    shape = image.shape
    x = image.reshape(-1, shape[-2], shape[-1])
    mode = "replicate" if border == "replicate" else "constant"
    if radius_cols > 0:
        x = F.pad(x, (radius_cols, radius_cols), mode=mode)
        x = F.avg_pool1d(x, 2 * radius_cols + 1, stride=1)
        if border == "shrink":
            x = _shrink_border(x, radius_cols)
    if radius_rows > 0:
        x = x.transpose(1, 2)
        x = F.pad(x, (radius_rows, radius_rows), mode=mode)
        x = F.avg_pool1d(x, 2 * radius_rows + 1, stride=1)
        if border == "shrink":
            x = _shrink_border(x, radius_rows)
        x = x.transpose(1, 2)
    return x.reshape(shape)


def _inverse_3x3(m: torch.Tensor) -> torch.Tensor:
    """Inverse of symmetric positive definite 3x3 matrices stored as ``(3, 3, rows, cols)``
    (adjugate over determinant: no batched LAPACK call per pixel)."""
    a, b, c = m[0, 0], m[0, 1], m[0, 2]
    d, e, f = m[1, 1], m[1, 2], m[2, 2]
    c00, c01, c02 = d * f - e * e, c * e - b * f, b * e - c * d
    c11, c12, c22 = a * f - c * c, b * c - a * e, a * d - b * b
    det = a * c00 + b * c01 + c * c02
    rows = [[c00, c01, c02], [c01, c11, c12], [c02, c12, c22]]
    return torch.stack([torch.stack(row) for row in rows]) / det


def colour_guided_filter(
    guide: torch.Tensor,
    image: torch.Tensor,
    radius: tuple[int, int],
    eps: float,
    border: str = "replicate",
) -> torch.Tensor:
    """Edge-preserving smoothing of ``image`` steered by a colour ``guide`` (guided filter).

    The colour form of :func:`guided_filter` (He, Sun & Tang, TPAMI 2013, eqs. 13-16): in every
    window the output is the least-squares affine function of the three guide channels,
    ``q = a . I + b`` with ``a = (Sigma + eps U)^-1 cov(I, p)``; the coefficients of all windows
    covering a pixel are averaged. A colour guide keeps windows from crossing edges between
    surfaces of equal brightness but different hue, which a gray guide cannot see. Windows are
    rectangles (:func:`box_blur_rect`), so line windows are possible.

    Parameters
    ----------
    guide : torch.Tensor, shape (3, rows, cols)
        Colour guide image (intensities in [0, 1]).
    image : torch.Tensor, shape (D, rows, cols)
        What to smooth (e.g. a cost volume).
    radius : (int, int)
        Window radius along rows and along columns (pixels).
    eps : float
        Regulariser: guide variances well below it count as flat.
    border : {"replicate", "shrink"}
        How windows meet the frame's border (:func:`box_blur_rect`).

    Returns
    -------
    torch.Tensor, shape of ``image``
    """

    def box(x: torch.Tensor) -> torch.Tensor:
        return box_blur_rect(x, radius[0], radius[1], border)

    mean_i = box(guide)
    mean_p = box(image)
    sigma = torch.empty((3, 3, *guide.shape[1:]), dtype=guide.dtype, device=guide.device)
    for i in range(3):
        for j in range(i, 3):
            sigma[i, j] = box(guide[i] * guide[j]) - mean_i[i] * mean_i[j]
            sigma[j, i] = sigma[i, j]
        sigma[i, i] += eps
    inverse = _inverse_3x3(sigma)
    cov = [box(image * guide[i]) - mean_i[i] * mean_p for i in range(3)]
    out = None
    offset = mean_p
    for i in range(3):
        a_i = inverse[i, 0] * cov[0] + inverse[i, 1] * cov[1] + inverse[i, 2] * cov[2]
        offset = offset - a_i * mean_i[i]
        term = box(a_i) * guide[i]
        out = term if out is None else out + term
    return out + box(offset)
