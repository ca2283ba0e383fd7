"""Anthropometric proportions (the paper's ``L_anth``).

MirrorCalib (Liao, Zheng and Mitchell, eq. ``L_anth``) penalises
``(l_k / l_femur - sigma_k)^2`` with ``sigma_k`` the average length of bone ``k``
relative to the femur. The ratios here come from D. A. Winter, *Biomechanics and
Motor Control of Human Movement*, 4th ed., Wiley 2009, Fig. 4.1
(:func:`mirrorgraph.anthropometry.femur_ratios`). With shared bone-length
lengths (entries of the length vector ``L``) the prior is one factor per
(non-femur) bone:

    r_k = L_k / Lbar_femur - rho_k,      Lbar_femur = mean of the femur lengths,

dimensionless, standard deviation ``sigma`` (individual proportions differ from
the population mean by a few percent per segment). Key: ``L``. Jacobian:
``dr/dL_k = 1 / Lbar``, ``dr/dL_femur_i = -L_k / (m Lbar^2)`` for ``m`` femurs.
"""

from __future__ import annotations

import gtsam
import numpy as np

__all__ = ["AnthropometricRatioFactor"]


class AnthropometricRatioFactor:
    """Ratio of a bone's length to the mean femur length against the population ratio.

    Args:
        sigma: standard deviation of the ratio (dimensionless).
    """

    def __init__(self, sigma: float) -> None:
        self.sigma = float(sigma)

    @staticmethod
    def evaluate(L: np.ndarray, bone: int, femurs: list[int], ratio: float
                 ) -> tuple[np.ndarray, np.ndarray]:
        """Residual and Jacobian.

        Args:
            L: ``(n,)`` bone lengths.
            bone: entry of the bone in ``L``.
            femurs: entries of the femurs (1 or 2).
            ratio: expected ``L_bone / femur`` (Winter 2009).

        Returns:
            ``r`` (1,) and ``dr/dL`` (1, n).
        """
        L = np.asarray(L, dtype=float)
        mean = float(L[femurs].mean())
        J = np.zeros((1, len(L)))
        J[0, femurs] = -L[bone] / (len(femurs) * mean * mean)
        J[0, bone] += 1.0 / mean
        return np.array([L[bone] / mean - float(ratio)]), J

    def make(self, length_key: int, bone: int, femurs: list[int], ratio: float
             ) -> gtsam.CustomFactor:
        """The factor on the length vector."""
        femurs = [int(f) for f in femurs]
        evaluate = self.evaluate

        def error(this: gtsam.CustomFactor, values: gtsam.Values, H) -> np.ndarray:
            r, J = evaluate(values.atVector(length_key), bone, femurs, ratio)
            if H is not None:
                H[0] = J
            return r

        return gtsam.CustomFactor(gtsam.noiseModel.Isotropic.Sigma(1, self.sigma),
                                  [int(length_key)], error)
