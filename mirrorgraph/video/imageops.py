"""The two resamplings of the detection path, in numpy with their arithmetic stated.

BlazePose's inputs are an image resampled twice: the whole frame (or a tile)
shrunk into the detector's ``224 x 224`` letterbox, and a rotated square cut out
around a person for the landmark model (``256 x 256``). OpenCV's ``cv2.resize(...,
INTER_AREA)`` and ``cv2.warpAffine(..., INTER_LINEAR)`` on ``uint8`` images give
OpenCV's implementation, not a specification: ``warpAffine`` quantises source
coordinates to 1/32 px and its weights to 15 bits, and OpenCV 5.1 differs from earlier
versions by one grey level on 7-37 pixels of a 196,608-pixel crop (the Pose2Sim demo
frames). The landmark network is not smooth in its input: such a grey level can move
one landmark of a hand by 112 px a few frames later, through the tracker's next crop.

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
    h, w, c = image.shape
    M = np.asarray(M, float)
    flat = np.ascontiguousarray(image).reshape(h * w, c)
    u = np.arange(size, dtype=float)
    out = np.empty((size, size, c), np.float32)
    # a block of the crop's rows at a time: its samples, their source pixels and every
    # temporary stay in the CPU's cache (the whole crop's do not: a 700 px person's
    # source region is 1.5 MB), the same arithmetic element by element
    for r0 in range(0, size, CROP_BLOCK_ROWS):
        _warp_rows(flat, h, w, M, u, u[r0:r0 + CROP_BLOCK_ROWS],
                   out[r0:r0 + CROP_BLOCK_ROWS].reshape(-1, c))
    return out


#: Rows of a crop :func:`warp_crop` samples at once.
CROP_BLOCK_ROWS = 32


def _warp_rows(flat: np.ndarray, h: int, w: int, M: np.ndarray, u: np.ndarray, v: np.ndarray,
               out: np.ndarray) -> None:
    """:func:`warp_crop` on the crop's rows ``v`` (columns ``u``) of an ``(h * w, C)``
    image, into ``out`` ``(len(v) * len(u), C)`` float32."""
    x = (M[0, 0] * u[None, :] + M[0, 1] * v[:, None] + M[0, 2]).ravel()
    y = (M[1, 0] * u[None, :] + M[1, 1] * v[:, None] + M[1, 2]).ravel()
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0).astype(np.float32), (y - y0).astype(np.float32)
    x0, y0 = x0.astype(np.intp), y0.astype(np.intp)
    wx, wy = (1.0 - fx, fx), (1.0 - fy, fy)
    # every neighbour inside the image (most blocks): no masks
    inside = bool(x0.min() >= 0 and y0.min() >= 0 and x0.max() < w - 1 and y0.max() < h - 1)
    if not inside:
        in_x = ((x0 >= 0) & (x0 < w), (x0 >= -1) & (x0 < w - 1))
        in_y = ((y0 >= 0) & (y0 < h), (y0 >= -1) & (y0 < h - 1))
    first = y0 * w + x0
    term = np.empty_like(out)
    weight = np.empty(len(x), np.float32)
    # out = w00 p00 + w01 p01 + w10 p10 + w11 p11, each product and each sum rounded to
    # float32 in this order (the pinned tensors of tests/video/test_imageops.py); the
    # pixels are cast to float32 before the product, which is what numpy's product of
    # float32 and uint8 computes, without its slow mixed-type loop
    for k, (dy, dx) in enumerate(((0, 0), (0, 1), (1, 0), (1, 1))):
        np.multiply(wx[dx], wy[dy], out=weight)
        # one gather of whole pixels from the flattened image (outside: pixel 0, weight 0)
        index = first + (dy * w + dx)
        if not inside:
            outside = ~(in_x[dx] & in_y[dy])
            weight[outside] = 0.0
            index[outside] = 0
        into = out if k == 0 else term
        into[...] = np.take(flat, index, axis=0)
        np.multiply(into, weight[:, None], out=into)
        if k:
            np.add(out, term, out=out)
