"""Small torch filters shared by the disparity estimators: Gaussian, box and guided smoothing.

All filters work on tensors of shape ``(..., rows, cols)`` on any device, are separable and use
reflected borders (replicated where an image is too small to reflect), so that a constant image
stays constant and there is no darkening at the frame border.
"""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import torch
import torch.nn.functional as F

__all__ = [
    "BAND_ELEMENTS",
    "BoxFilter",
    "ColourGuidedFilter",
    "box_blur",
    "box_blur_rect",
    "colour_guided_filter",
    "gaussian_blur",
    "gaussian_kernel1d",
    "guided_filter",
    "slice_chunks",
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
    """Isotropic Gaussian smoothing of the last two axes (``sigma`` in pixels; 0 = identity), a few
    slices at a time."""
    if sigma <= 0:
        return image
    kernel = gaussian_kernel1d(sigma, image.device)
    flat = image.reshape(-1, *image.shape[-2:])
    if flat.shape[0] == 1:
        return smooth_axis(smooth_axis(image, kernel, -1), kernel, -2)
    out = torch.empty_like(flat)
    # a few slices at a time: the intermediates stay in a CPU's cache (slice_chunks)
    for chunk in slice_chunks(flat.shape[0], flat[0].numel()):
        out[chunk] = smooth_axis(smooth_axis(flat[chunk], kernel, -1), kernel, -2)
    return out.reshape(image.shape)


def box_blur(image: torch.Tensor, radius: int) -> torch.Tensor:
    """Mean over a ``(2 radius + 1)^2`` window of the last two axes (borders replicated).

    Separable window sums, each axis summed by doubling (:class:`BoxFilter`): about
    ``2 log2(2 radius + 1)`` vectorised additions per axis, whatever the radius (a 5 x 5 window
    was 24 additions of shifted slices before, a wider one two ``avg_pool1d`` passes).
    """
    if radius <= 0:
        return image
    return BoxFilter(image.shape[-2:], radius, radius, "replicate", image.device)(image)


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


def _window_sums(x: torch.Tensor, size: int, dim: int) -> torch.Tensor:
    """Sums of ``size`` consecutive elements along ``dim`` (the output is ``size - 1`` shorter).

    Built from partial sums over windows of 1, 2, 4, ... elements (each the sum of two shifted
    copies of the previous one), of which those of the set bits of ``size`` are added: about
    ``2 log2(size)`` vectorised additions instead of ``size - 1``.
    """
    out_length = x.shape[dim] - size + 1
    total: torch.Tensor | None = None
    offset, width, partial = 0, 1, x
    while True:
        if size & width:
            part = partial.narrow(dim, offset, out_length)
            total = part.clone() if total is None else total.add_(part)
            offset += width
        if 2 * width > size:
            break
        length = partial.shape[dim] - width
        partial = partial.narrow(dim, 0, length) + partial.narrow(dim, width, length)
        width *= 2
    assert total is not None
    return total


def _inside_counts(length: int, radius: int, device: torch.device | None) -> torch.Tensor:
    """How many positions of the ``2 radius + 1`` window centred on each position of an axis of
    ``length`` lie on that axis."""
    position = torch.arange(length, device=device)
    inside = (position + radius).clamp(max=length - 1) - (position - radius).clamp(min=0) + 1
    return inside.float()


class BoxFilter:
    """Mean over a ``(2 radius_rows + 1) x (2 radius_cols + 1)`` window of the last two axes of
    images of one size, with the border rules of :func:`box_blur_rect`.

    The window sums are separable, each axis summed by doubling (:func:`_window_sums`); the
    normalisation (per position with ``border="shrink"``) is one precomputed factor. Applied to
    a few slices of a volume at a time (:class:`ColourGuidedFilter`), its intermediates stay in
    a CPU's cache (docs/design.md section 3.2, "Speed: cache-sized pieces").
    """

    def __init__(
        self,
        shape: tuple[int, int],
        radius_rows: int,
        radius_cols: int,
        border: str = "replicate",
        device: torch.device | None = None,
    ) -> None:
        """A filter for images of ``shape`` (rows, cols) on ``device``.

        Raises
        ------
        ValueError
            If ``border`` is neither ``"replicate"`` nor ``"shrink"`` (the caller's code is at
            fault).
        """
        if border not in ("replicate", "shrink"):
            raise ValueError(f"unknown border {border!r}: use 'replicate' or 'shrink'")
        rows, cols = shape
        self.radius_rows, self.radius_cols, self.border = radius_rows, radius_cols, border
        self.scale: torch.Tensor | float
        if border == "shrink":
            scale_rows = 1.0 / _inside_counts(rows, radius_rows, device)
            scale_cols = 1.0 / _inside_counts(cols, radius_cols, device)
            self.scale = scale_rows[:, None] * scale_cols[None, :]
        else:
            self.scale = 1.0 / ((2 * radius_rows + 1) * (2 * radius_cols + 1))

    def __call__(self, image: torch.Tensor) -> torch.Tensor:
        """The window means of ``image``, shape ``(..., rows, cols)``, as a new tensor."""
        shape = image.shape
        x = image.reshape(-1, shape[-2], shape[-1])
        rows, cols = self.radius_rows, self.radius_cols
        if rows <= 0 and cols <= 0:
            return image.clone()
        chunks = slice_chunks(x.shape[0], x[0].numel())
        if len(chunks) > 1:  # a few slices at a time, in a CPU's cache
            out = torch.empty_like(x)
            for chunk in chunks:
                out[chunk] = self._means(x[chunk])
            return out.reshape(shape)
        return self._means(x).reshape(shape)

    def _means(self, x: torch.Tensor) -> torch.Tensor:
        """The window means of ``x``, shape ``(N, rows, cols)``."""
        if _opencv_can_sum(x):
            return self._means_opencv(x)
        mode = "replicate" if self.border == "replicate" else "constant"
        rows, cols = self.radius_rows, self.radius_cols
        if cols > 0:
            x = _window_sums(F.pad(x, (cols, cols), mode=mode), 2 * cols + 1, -1)
        if rows > 0:
            x = _window_sums(F.pad(x, (0, 0, rows, rows), mode=mode), 2 * rows + 1, -2)
        return x.mul_(self.scale)

    def _means_opencv(self, x: torch.Tensor) -> torch.Tensor:
        """:meth:`_means` by OpenCV's box filter, one image at a time (CPU float32).

        ``cv2.boxFilter`` sums each window with running sums in SIMD code; unnormalised, with
        ``BORDER_REPLICATE`` (the frame's outermost pixels repeated) or ``BORDER_CONSTANT`` (zeros:
        the sums of the pixels inside, which :attr:`scale` turns into ``"shrink"``'s means), it
        gives the sums of :func:`_window_sums` on the padded image to float32 rounding (about
        1e-7 apart) in a fifth of the time (docs/design.md section 3.2, "Speed: cache-sized
        pieces").
        """
        import cv2

        threads = torch.get_num_threads()  # OpenCV's pool as wide as torch's (one per test worker)
        if cv2.getNumThreads() != threads:
            cv2.setNumThreads(threads)
        border = cv2.BORDER_REPLICATE if self.border == "replicate" else cv2.BORDER_CONSTANT
        size = (2 * self.radius_cols + 1, 2 * self.radius_rows + 1)  # (width, height)
        images = x.detach().contiguous().numpy()
        sums = np.empty_like(images)
        for image, out in zip(images, sums, strict=True):
            cv2.boxFilter(image, -1, size, dst=out, normalize=False, borderType=border)
        return torch.from_numpy(sums).mul_(self.scale)


_HAS_CV2 = importlib.util.find_spec("cv2") is not None
"""OpenCV is installed (the ``dev``, ``poses`` and ``render`` extras bring it; without it the
box sums are torch's, the same to float32 rounding)."""


def _opencv_can_sum(x: torch.Tensor) -> bool:
    """Whether :meth:`BoxFilter._means` hands ``x`` to OpenCV: a float32 CPU tensor outside
    autograd, with OpenCV installed (the torch sums are the path on a GPU and the fallback)."""
    return _HAS_CV2 and x.device.type == "cpu" and x.dtype == torch.float32 and not x.requires_grad


def box_blur_rect(
    image: torch.Tensor, radius_rows: int, radius_cols: int, border: str = "replicate"
) -> torch.Tensor:
    """Mean over a ``(2 radius_rows + 1) x (2 radius_cols + 1)`` window of the last two axes.

    Separable window sums (:class:`BoxFilter`); a radius of 0 leaves that axis alone,
    so ``(0, r)`` is a horizontal line window and ``(r, 0)`` a vertical one (the oriented
    windows of :mod:`lfsam.disparity.aggregation`). At the frame's border, ``border="replicate"``
    repeats the outermost pixels (the outermost pixel then weighs ``(r + 1) / (2 r + 1)`` of a
    border pixel's window), ``border="shrink"`` takes the mean over the window's pixels inside
    the frame (the normalised box filter of He et al.'s guided filter, ``box(p) / box(1)``).

    Raises
    ------
    ValueError
        If ``border`` is neither ``"replicate"`` nor ``"shrink"`` (the caller's code is at fault).
    """
    return BoxFilter(image.shape[-2:], radius_rows, radius_cols, border, image.device)(image)


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


#: Elements of one chunk of slices that :class:`ColourGuidedFilter` filters at a time (about
#: 1 MB of float32): its intermediates then stay in a CPU's cache. Measured on this project's
#: 2-core CPU on a (32, 512, 512) cost volume: 0.4 s per window in slices of one, 4.1 s over
#: the whole volume at once (docs/performance.md, "Depth in 8 seconds").
CHUNK_ELEMENTS = 1 << 18


#: Pixels of one band of rows in the loops that visit a window's offsets one by one (the joint
#: bilateral refinement, :mod:`lfsam.disparity.refine`, and the surface fit,
#: :mod:`lfsam.disparity.surface_fit`): their per-band maps then fit a CPU's cache (the two
#: bilateral passes on HCI antinous' 512 x 512 center view, one thread: 1.3 s in bands of 64
#: rows, 1.65 s over the whole image at once).
BAND_ELEMENTS = 1 << 15


def slice_chunks(count: int, slice_elements: int) -> list[slice]:
    """Consecutive chunks of ``count`` slices of ``slice_elements`` elements each, of about
    :data:`CHUNK_ELEMENTS` elements (at least one slice) per chunk (docs/design.md section 3.2,
    "Speed: cache-sized pieces")."""
    size = max(1, CHUNK_ELEMENTS // max(slice_elements, 1))
    return [slice(start, min(start + size, count)) for start in range(0, count, size)]


class ColourGuidedFilter:
    """Edge-preserving smoothing steered by a colour guide (guided filter), the guide's part
    computed once.

    The colour form of :func:`guided_filter` (He, Sun & Tang, TPAMI 2013, eqs. 13-16): in every
    window the output is the least-squares affine function of the three guide channels,
    ``q = a . I + b`` with ``a = (Sigma + eps U)^-1 cov(I, p)``, ``b = mean(p) - a . mean(I)``;
    the coefficients of all windows covering a pixel are averaged. A colour guide keeps windows
    from crossing edges between surfaces of equal brightness but different hue, which a gray
    guide cannot see. Windows are rectangles (:class:`BoxFilter`), so line windows are possible.

    Everything that depends on the guide only (its window means, ``(Sigma + eps U)^-1`` and
    ``(Sigma + eps U)^-1 mean(I)``) is computed when the filter is made; a volume is then
    filtered a few slices at a time (:func:`slice_chunks`; docs/design.md section 3.2, step 4 and
    "Speed: cache-sized pieces"), with
    ``a = (Sigma + eps U)^-1 mean(p I) - (Sigma + eps U)^-1 mean(I) mean(p)``.

    Parameters
    ----------
    guide : torch.Tensor, shape (3, rows, cols)
        Colour guide image (intensities in [0, 1]).
    radius : (int, int)
        Window radius along rows and along columns (pixels).
    eps : float
        Regulariser: guide variances well below it count as flat.
    border : {"replicate", "shrink"}
        How windows meet the frame's border (:func:`box_blur_rect`).
    """

    def __init__(
        self, guide: torch.Tensor, radius: tuple[int, int], eps: float, border: str = "replicate"
    ) -> None:
        self.guide = guide
        self.box = BoxFilter(tuple(guide.shape[1:]), radius[0], radius[1], border, guide.device)
        mean = self.box(guide)
        sigma = torch.empty((3, 3, *guide.shape[1:]), dtype=guide.dtype, device=guide.device)
        for i in range(3):
            for j in range(i, 3):
                sigma[i, j] = self.box(guide[i] * guide[j]) - mean[i] * mean[j]
                sigma[j, i] = sigma[i, j]
            sigma[i, i] += eps
        self.mean = mean
        self.inverse = _inverse_3x3(sigma)
        self.inverse_mean = torch.einsum("ijuv,juv->iuv", self.inverse, mean)

    def products(self, image: torch.Tensor) -> list[torch.Tensor]:
        """``image * I_j`` for the three guide channels (to share between filters of one guide,
        :meth:`apply`)."""
        return [image * self.guide[j] for j in range(3)]

    def apply(
        self, image: torch.Tensor, products: list[torch.Tensor] | None = None
    ) -> torch.Tensor:
        """The filtered ``image`` of shape ``(D, rows, cols)``, all at once (give it a chunk:
        :meth:`__call__`); ``products`` are its :meth:`products` when already at hand."""
        box, guide, inverse = self.box, self.guide, self.inverse
        products = self.products(image) if products is None else products
        mean_p = box(image)
        mean_products = [box(product) for product in products]
        offset = mean_p.clone()
        coefficients = []
        for i in range(3):
            a_i = mean_products[0] * inverse[i, 0]
            a_i.addcmul_(mean_products[1], inverse[i, 1]).addcmul_(mean_products[2], inverse[i, 2])
            a_i.addcmul_(mean_p, self.inverse_mean[i], value=-1.0)
            offset.addcmul_(a_i, self.mean[i], value=-1.0)
            coefficients.append(a_i)
        out = box(offset)
        for i in range(3):
            out.addcmul_(box(coefficients[i]), guide[i])
        return out

    def __call__(self, image: torch.Tensor) -> torch.Tensor:
        """The filtered ``image``, shape ``(D, rows, cols)`` (or ``(rows, cols)``), in chunks of
        slices (:func:`slice_chunks`)."""
        flat = image.reshape(-1, *image.shape[-2:])
        out = torch.empty_like(flat)
        for chunk in slice_chunks(flat.shape[0], flat[0].numel()):
            out[chunk] = self.apply(flat[chunk])
        return out.reshape(image.shape)


def colour_guided_filter(
    guide: torch.Tensor,
    image: torch.Tensor,
    radius: tuple[int, int],
    eps: float,
    border: str = "replicate",
) -> torch.Tensor:
    """Edge-preserving smoothing of ``image`` steered by a colour ``guide`` (guided filter;
    :class:`ColourGuidedFilter`, whose guide part is computed anew on every call).

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
    return ColourGuidedFilter(guide, radius, eps, border)(image)
