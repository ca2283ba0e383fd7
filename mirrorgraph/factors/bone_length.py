"""Constant bone lengths over time (the paper's ``L_var``), one factor per frame.

MirrorCalib (Liao, Zheng and Mitchell, sec. "Refining 2D joint locations",
eq. ``L_var``) penalises the variation of every bone's length over the
recording relative to its mean. In a factor graph the natural form is a length
``L_k`` per bone, shared by all frames, and per frame ``t`` the residuals

    r_k^t = |X_a^t - X_b^t| - L_k,      k over the bones seen in frame t,

with standard deviation ``sigma`` (length unit of the scene). Keeping all bones
of a frame in one factor keeps the number of Python callbacks per
linearisation at one per frame.

The lengths are the entries of one vector variable ``L`` (``n`` entries, one
per bone of the skeleton in use): a Python factor pays ~2 us per key for
each Jacobian it hands to GTSAM, so one key for all lengths instead of one
per bone halves the cost of these callbacks (measured: 22 us instead of 41 us
per frame).

Keys: the ``m`` points of the frame (:class:`gtsam.Point3`, world frame) then
``L``. Jacobians: ``dr_k / dX_a = u_k^T``, ``dr_k / dX_b = -u_k^T`` with
``u_k = (X_a - X_b) / |X_a - X_b|``, ``dr_k / dL = -e_{i_k}^T`` (``i_k`` the entry of bone ``k``).
"""

from __future__ import annotations

import gtsam
import numpy as np

__all__ = ["BoneLengthFactor"]


class BoneLengthFactor:
    """All bones of one frame against the shared bone-length variables.

    Args:
        sigma: standard deviation of a bone's length about its constant value,
            length unit of the scene (metres when the scale is metric).
    """

    def __init__(self, sigma: float) -> None:
        self.sigma = float(sigma)

    @staticmethod
    def evaluate(Xa: np.ndarray, Xb: np.ndarray, L: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Residuals and Jacobians, vectorised over bones.

        Args:
            Xa, Xb: ``(B, 3)`` end points of each bone (world frame).
            L: ``(B,)`` bone lengths.

        Returns:
            ``r`` (B,), ``dr/dXa`` (B, 3), ``dr/dXb`` (B, 3); ``dr/dL`` is ``-1``.
        """
        diff = np.asarray(Xa, dtype=float) - np.asarray(Xb, dtype=float)
        length = np.sqrt(np.einsum("bi,bi->b", diff, diff))
        unit = diff / np.maximum(length, 1e-12)[:, None]
        return length - np.asarray(L, dtype=float), unit, -unit

    def make(self, point_keys: list[int], bones: np.ndarray, length_key: int,
             length_index: np.ndarray, num_lengths: int,
             sigmas: np.ndarray | None = None) -> gtsam.CustomFactor:
        """The factor of one frame.

        Args:
            point_keys: ``m`` keys of the frame's points.
            bones: ``(B, 2)`` int, each bone's end points as indices into ``point_keys``.
            length_key: key of the length vector ``L``.
            length_index: ``(B,)`` int, each bone's entry in ``L``.
            num_lengths: size ``n`` of ``L``.
            sigmas: ``(B,)`` standard deviation of each bone's residual in this frame
                (default: :attr:`sigma` for all).
        """
        bones = np.asarray(bones, dtype=int).reshape(-1, 2)
        point_keys = [int(k) for k in point_keys]
        B, m = len(bones), len(point_keys)
        rows = np.arange(B)
        ia, ib = bones[:, 0], bones[:, 1]
        li = np.asarray(length_index, dtype=int)
        dL = np.zeros((B, int(num_lengths)))
        dL[rows, li] = -1.0
        evaluate = self.evaluate
        atPoint3 = gtsam.Values.atPoint3

        def error(this: gtsam.CustomFactor, values: gtsam.Values, H) -> np.ndarray:
            X = np.array([atPoint3(values, k) for k in point_keys])
            r, Ja, _ = evaluate(X[ia], X[ib], values.atVector(length_key)[li])
            if H is not None:
                J = np.zeros((m, B, 3))
                J[ia, rows] = Ja
                J[ib, rows] = -Ja
                for i in range(m):
                    H[i] = J[i]
                H[m] = dL
            return r

        noise = (gtsam.noiseModel.Isotropic.Sigma(B, self.sigma) if sigmas is None
                 else gtsam.noiseModel.Diagonal.Sigmas(np.asarray(sigmas, dtype=float)))
        return gtsam.CustomFactor(noise, point_keys + [int(length_key)], error)
