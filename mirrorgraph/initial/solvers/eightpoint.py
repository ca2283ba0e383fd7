"""Reference estimators from MirrorCalib (Liao, Zheng and Mitchell), for comparison.

* :func:`fundamental_eight_point` — the paper's *Baseline1*: the normalised
  eight-point algorithm without mirror constraint (OpenCV ``FM_8POINT``),
  nine unknowns, rank 2 enforced.
* :func:`fundamental_reflective_eight_point` — the paper's "modified
  eight-point algorithm" (sec. "Eight-point algorithm for solving reflective
  fundamental matrix", eq. 5-7): six unknowns ``x_1..x_6`` of
  ``F' = [[0, x1, x2], [-x1, 0, x3], [x4, x5, x6]]`` in normalised coordinates,
  one normalisation per view, ``F = T'^T F' T``.

Both give a fundamental matrix in pixels with ``u'^T F u = 0``; the pose comes
from :func:`mirrorgraph.geometry.decompose_reflective_essential` applied to
``E = K^T F K``. Neither is the design of mirrorgraph (see
:mod:`.reflective`); they are kept so that users and benchmarks can compare.
"""

from __future__ import annotations

import cv2
import numpy as np

from ...errors import DegenerateGeometryError
from .normalization import SimilarityNormalizer


def fundamental_eight_point(u: np.ndarray, u_mirror: np.ndarray) -> np.ndarray:
    """OpenCV's normalised eight-point ``F`` (3, 3) with ``u'^T F u = 0``.

    Args:
        u, u_mirror: ``(N, 2)`` pixel pairs, ``N >= 8``.

    Raises:
        DegenerateGeometryError: fewer than 8 pairs or OpenCV finds no solution.
    """
    if len(u) < 8:
        raise DegenerateGeometryError(f"the eight-point algorithm needs 8 pairs, got {len(u)}")
    F, _ = cv2.findFundamentalMat(np.ascontiguousarray(u, dtype=np.float64),
                                  np.ascontiguousarray(u_mirror, dtype=np.float64),
                                  cv2.FM_8POINT)
    if F is None or F.shape != (3, 3):
        raise DegenerateGeometryError("the eight-point algorithm found no fundamental matrix")
    return F / np.linalg.norm(F)


def fundamental_reflective_eight_point(u: np.ndarray, u_mirror: np.ndarray) -> np.ndarray:
    """The paper's 6-unknown reflective eight-point ``F`` (3, 3), pixels.

    Each pair gives the row ``[u'v - v'u, u', v', u, v, 1]`` (normalised
    coordinates, eq. 5); ``f'`` is the right singular vector of the smallest
    singular value; ``F = T'^T F' T`` (eq. 7). Ambiguity noted: the paper
    normalises "the real view and its virtual view" separately, so ``T`` is
    fitted to the direct-view points and ``T'`` to the mirror-view points.

    Args:
        u, u_mirror: ``(N, 2)`` pixel pairs, ``N >= 6``.
    """
    if len(u) < 6:
        raise DegenerateGeometryError(
            f"the reflective eight-point algorithm needs 6 pairs, got {len(u)}")
    T = SimilarityNormalizer.fit(u)
    Tm = SimilarityNormalizer.fit(u_mirror)
    a, b = T.apply(u), Tm.apply(u_mirror)
    x, y = a[:, 0], a[:, 1]
    xm, ym = b[:, 0], b[:, 1]
    A = np.stack([xm * y - ym * x, xm, ym, x, y, np.ones_like(x)], axis=1)
    _, _, Vt = np.linalg.svd(A, full_matrices=False)
    x1, x2, x3, x4, x5, x6 = Vt[-1]
    Fn = np.array([[0.0, x1, x2], [-x1, 0.0, x3], [x4, x5, x6]])
    F = Tm.matrix.T @ Fn @ T.matrix
    return F / np.linalg.norm(F)
