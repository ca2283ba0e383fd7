"""Left/right symmetry of the body (the paper's ``L_sym``).

MirrorCalib (Liao, Zheng and Mitchell, eq. ``L_sym``) penalises, in every frame,
the difference between the length of a bone and of its counterpart on the
other side. With one length per bone shared over time (the entries of the
length vector ``L``, :mod:`mirrorgraph.factors.bone_length`) this is a single
factor per pair:

    r = L[i_left] - L[i_right],       dr/dL = e_left^T - e_right^T,

standard deviation ``sigma`` (length unit of the scene). Key: ``L``.
"""

from __future__ import annotations

import gtsam
import numpy as np

__all__ = ["SymmetryFactor"]



class SymmetryFactor:
    """Equal length of a left and a right bone.

    Args:
        sigma: standard deviation of the left/right difference, length unit of
            the scene (a healthy adult's limbs differ by a few millimetres).
    """

    def __init__(self, sigma: float) -> None:
        self.sigma = float(sigma)

    @staticmethod
    def evaluate(L: np.ndarray, left: int, right: int) -> tuple[np.ndarray, np.ndarray]:
        """Residual ``(1,)`` and its Jacobian ``(1, n)`` w.r.t. the length vector ``L`` (n,)."""
        L = np.asarray(L, dtype=float)
        J = np.zeros((1, len(L)))
        J[0, left], J[0, right] = 1.0, -1.0
        return np.array([L[left] - L[right]]), J

    def make(self, length_key: int, left: int, right: int) -> gtsam.CustomFactor:
        """The factor on entries ``left`` and ``right`` of the length vector."""
        evaluate = self.evaluate

        def error(this: gtsam.CustomFactor, values: gtsam.Values, H) -> np.ndarray:
            r, J = evaluate(values.atVector(length_key), left, right)
            if H is not None:
                H[0] = J
            return r

        return gtsam.CustomFactor(gtsam.noiseModel.Isotropic.Sigma(1, self.sigma),
                                  [int(length_key)], error)
