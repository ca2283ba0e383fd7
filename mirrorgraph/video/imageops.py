"""The two resamplings of the detection path, in numpy with their arithmetic stated.

BlazePose's inputs are an image resampled twice: the whole frame (or a tile)
shrunk into the detector's ``224 x 224`` letterbox, and a rotated square cut out
around a person for the landmark model (``256 x 256``). Both were OpenCV calls
(``cv2.resize(..., INTER_AREA)``, ``cv2.warpAffine(..., INTER_LINEAR)``) on
``uint8`` images, whose results are OpenCV's implementation, not a specification:
``warpAffine`` quantises source coordinates to 1/32 px and its weights to 15 bits,
and OpenCV 5.1 reimplemented it, moving a few pixels of each crop by one grey level
(measured on the Pose2Sim demo frames: 7-37 pixels of 196,608 a crop, ``|d| = 1``).
The landmark network is not smooth in its input: those few grey levels moved one
landmark of a hand by 112 px a few frames later, through the tracker's next crop.

Here each step is the textbook operation in floating point, with no rounding to
``uint8`` (the networks take ``float32``), so that the same frame gives the same
tensor whatever OpenCV is installed:

* :func:`area_resize`: box-filter (area-average) resampling: each output pixel is
  the mean of the input over the rectangle it covers, fractional pixels weighted by
  the area they overlap (what ``INTER_AREA`` approximates when shrinking;
  Wolberg, *Digital Image Warping*, 1990, sec. 6.2).
* :func:`warp_crop`: bilinear sampling of an affine map, zero outside the image
  (``BORDER_CONSTANT`` 0), pixel centres at integer coordinates (OpenCV's and
  numpy's convention; Szeliski, *Computer Vision*, 2nd ed., sec. 3.6.1).

Frames: image pixels, origin at the top-left pixel's centre, x right, y down.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

__all__ = ["area_weights", "area_resize", "warp_crop"]


@lru_cache(maxsize=64)
def _area_matrix(n_in: int, n_out: int):
    import scipy.sparse as sp                  # only the video path needs it
    return sp.csr_matrix(area_weights(n_in, n_out).astype(np.float32))


def area_weights(n_in: int, n_out: int) -> np.ndarray:
    """``(n_out, n_in)`` box-filter weights of one axis resampled from ``n_in`` to ``n_out``.

    Output pixel ``j`` covers ``[j, j + 1) * n_in / n_out`` in input pixels; its weight
    on input pixel ``i`` is the length of ``[i, i + 1)`` inside that interval over the
    interval's length, so each row sums to one (also when enlarging, where an output
    pixel lies inside one input pixel or straddles two).
    """
    if n_in < 1 or n_out < 1:
        raise ValueError(f"area_weights: sizes must be positive, got {n_in} -> {n_out}")
    edges = np.arange(n_out + 1) * (n_in / n_out)
    lo, hi = edges[:-1, None], edges[1:, None]
    i = np.arange(n_in)[None, :]
    overlap = np.clip(np.minimum(hi, i + 1) - np.maximum(lo, i), 0.0, None)
    return overlap / (hi - lo)


def area_resize(image: np.ndarray, width: int, height: int) -> np.ndarray:
    """An image resampled to ``width x height`` by area averaging (:func:`area_weights`
    along each axis; the 2D box filter is their product).

    Args:
        image: ``(H, W, C)`` (any real dtype; ``uint8`` frames as they are decoded).
        width, height: output size in pixels.

    Returns:
        ``(height, width, C)`` ``float32``, in the input's units (0-255 for ``uint8``),
        not rounded.
    """
    h, w, c = image.shape
    rows = _area_matrix(h, height) @ image.reshape(h, w * c).astype(np.float32, copy=False)
    cols = rows.reshape(height, w, c).transpose(1, 0, 2).reshape(w, height * c)
    out = _area_matrix(w, width) @ cols
    return np.ascontiguousarray(out.reshape(width, height, c).transpose(1, 0, 2))


def warp_crop(image: np.ndarray, M: np.ndarray, size: int) -> np.ndarray:
    """The ``size x size`` crop whose pixel ``(u, v)`` is the image bilinearly sampled at
    ``M @ (u, v, 1)``, zero where the four neighbours fall outside the image.

    Args:
        image: ``(H, W, C)`` (any real dtype).
        M: ``(2, 3)`` affine map from crop pixels to image pixels (the map
            :func:`mirrorgraph.video.blazepose.crop_matrix` returns; OpenCV's
            ``warpAffine`` with ``WARP_INVERSE_MAP`` takes the same matrix).
        size: side of the square crop, pixels.

    Returns:
        ``(size, size, C)`` ``float32``, in the input's units, not rounded.
    """
    h, w = image.shape[:2]
    M = np.asarray(M, float)
    u = np.arange(size, dtype=float)
    x = M[0, 0] * u[None, :] + M[0, 1] * u[:, None] + M[0, 2]        # (size, size)
    y = M[1, 0] * u[None, :] + M[1, 1] * u[:, None] + M[1, 2]
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0).astype(np.float32), (y - y0).astype(np.float32)
    x0, y0 = x0.astype(np.intp), y0.astype(np.intp)
    out = np.zeros((size, size, image.shape[2]), np.float32)
    for dy, wy in ((0, 1.0 - fy), (1, fy)):
        for dx, wx in ((0, 1.0 - fx), (1, fx)):
            xi, yi = x0 + dx, y0 + dy
            inside = (xi >= 0) & (xi < w) & (yi >= 0) & (yi < h)
            weight = np.where(inside, wx * wy, np.float32(0.0))
            px = image[np.clip(yi, 0, h - 1), np.clip(xi, 0, w - 1)]
            out += weight[..., None] * px
    return out
