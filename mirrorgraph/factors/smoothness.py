"""Temporal smoothness of every joint (the paper's ``L_smooth``), aware of frame gaps.

MirrorCalib (Liao, Zheng and Mitchell, eq. ``L_smooth``) penalises the second
derivative of the 3D joint positions, approximated by central finite
differences. Frames may be missing (the joint not seen in both views, an
outlier, a frame the detector skipped), so the difference uses the actual
frame-number spacing. For three consecutive estimates of one joint at frame
numbers ``f0 < f1 < f2``, ``h1 = f1 - f0``, ``h2 = f2 - f1``, the non-uniform
central second difference (exact for quadratics)

    a = 2 / (h1 + h2) * ((X2 - X1) / h2 - (X1 - X0) / h1)
      = c0 X0 + c1 X1 + c2 X2,   c0 = 2 / (h1 (h1 + h2)),  c2 = 2 / (h2 (h1 + h2)),
                                 c1 = -(c0 + c2),

is the acceleration in length per frame^2 (``X2 - 2 X1 + X0`` when ``h1 = h2 = 1``).
No factor spans a gap longer than ``max_gap`` frames: across a long gap the
motion is unknown and a finite difference would be meaningless.

The residual ``a / sigma`` (3,) is linear in the points, so the factor is a
C++ :class:`gtsam.JacobianFactor` ``[c0 I, c1 I, c2 I]`` wrapped in a
:class:`gtsam.LinearContainerFactor` (exact at every linearisation point; no
Python callback). Keys: the three :class:`gtsam.Point3` of the joint, world frame.
"""

from __future__ import annotations

import gtsam
import numpy as np

__all__ = ["SmoothnessFactor"]


class SmoothnessFactor:
    """Second difference of one joint's position over three of its frames.

    Args:
        sigma: standard deviation of the acceleration, length unit of the scene
            per frame^2.
        max_gap: largest frame-number step a factor may span (frames).
    """

    def __init__(self, sigma: float, max_gap: int = 4) -> None:
        self.sigma = float(sigma)
        self.max_gap = int(max_gap)
        self._noise = gtsam.noiseModel.Isotropic.Sigma(3, self.sigma)

    @staticmethod
    def coefficients(frames: np.ndarray) -> np.ndarray:
        """``(..., 3)`` weights ``c0, c1, c2`` for frame numbers ``(..., 3)`` (increasing)."""
        f = np.asarray(frames, dtype=float)
        h1 = f[..., 1] - f[..., 0]
        h2 = f[..., 2] - f[..., 1]
        c0 = 2.0 / (h1 * (h1 + h2))
        c2 = 2.0 / (h2 * (h1 + h2))
        return np.stack([c0, -(c0 + c2), c2], axis=-1)

    @classmethod
    def evaluate(cls, X: np.ndarray, frames: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
        """Acceleration and its Jacobian, vectorised.

        Args:
            X: ``(..., 3, 3)`` positions of the joint at the three frames (rows).
            frames: ``(..., 3)`` frame numbers.

        Returns:
            ``a`` (..., 3) (length per frame^2) and ``da/dX`` (..., 3, 9), the
            blocks ``[c0 I, c1 I, c2 I]``.
        """
        c = cls.coefficients(frames)
        a = np.einsum("...k,...ki->...i", c, np.asarray(X, dtype=float))
        J = np.einsum("...k,ij->...ikj", c, np.eye(3)).reshape(c.shape[:-1] + (3, 9))
        return a, J

    def triples(self, frame_ids: np.ndarray) -> np.ndarray:
        """Consecutive triples usable for a factor, as indices into ``frame_ids``.

        Args:
            frame_ids: ``(N,)`` increasing frame numbers at which the joint is estimated.

        Returns:
            ``(M, 3)`` int indices ``(i, i + 1, i + 2)`` whose two steps are both
            ``<= max_gap``.
        """
        f = np.asarray(frame_ids, dtype=np.int64)
        if len(f) < 3:
            return np.zeros((0, 3), dtype=int)
        step = np.diff(f)
        ok = (step[:-1] <= self.max_gap) & (step[1:] <= self.max_gap)
        i = np.flatnonzero(ok)
        return np.stack([i, i + 1, i + 2], axis=1)

    def make(self, keys: list[int], frames: np.ndarray, linearization_point: gtsam.Values
             ) -> gtsam.LinearContainerFactor:
        """The factor on three points of one joint.

        Args:
            keys: the three point keys, in frame order.
            frames: ``(3,)`` their frame numbers.
            linearization_point: a :class:`gtsam.Values` holding the three points
                (only those are read); the factor is exact anywhere.
        """
        c = self.coefficients(np.asarray(frames, dtype=float))
        X = np.array([linearization_point.atPoint3(int(k)) for k in keys])
        a = c @ X
        eye = np.eye(3)
        jf = gtsam.JacobianFactor(int(keys[0]), c[0] * eye, int(keys[1]), c[1] * eye,
                                  int(keys[2]), c[2] * eye, -a, self._noise)
        return gtsam.LinearContainerFactor(jf, linearization_point)

    def add_many(self, graph: gtsam.NonlinearFactorGraph, keys: np.ndarray, frames: np.ndarray,
                 X: np.ndarray, linearization_point: gtsam.Values) -> None:
        """Add one factor per row, as :meth:`make` but vectorised.

        Args:
            keys: ``(M, 3)`` point keys; frames: ``(M, 3)`` frame numbers.
            X: ``(M, 3, 3)`` the points' values in ``linearization_point``.
            linearization_point: :class:`gtsam.Values` holding the points.
        """
        keys = np.asarray(keys, dtype=np.uint64)
        if len(keys) == 0:
            return
        c = self.coefficients(frames)                                         # (M, 3)
        a = np.einsum("mk,mki->mi", c, np.asarray(X, dtype=float))             # (M, 3)
        # the blocks of each distinct coefficient triple made once (most triples have
        # unit steps: one triple), the factors collected in a linear graph and wrapped
        # by GTSAM at once (LinearContainerFactor.ConvertLinearGraph: the same factors)
        uniq, which = np.unique(c, axis=0, return_inverse=True)
        blocks = [[ck * np.eye(3) for ck in row] for row in uniq]
        noise, make = self._noise, gtsam.JacobianFactor
        linear = gtsam.GaussianFactorGraph()
        rhs = -a
        for i, ((k0, k1, k2), u) in enumerate(zip(keys.tolist(), which.ravel().tolist())):
            b0, b1, b2 = blocks[u]
            linear.push_back(make(k0, b0, k1, b1, k2, b2, rhs[i], noise))
        graph.push_back(gtsam.LinearContainerFactor.ConvertLinearGraph(linear,
                                                                       linearization_point))
