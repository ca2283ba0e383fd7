"""The gauge: what fixes the scale of the scene.

Reflections carry no absolute scale: the mirror distance ``d``, the joints and
the bone lengths can all be multiplied by the same factor without changing a
single pixel. One of two priors fixes it:

* :class:`HeightPriorFactor`: the sum of the bone-length variables is held at
  ``S``. When the subject's standing height ``H`` (metres) is known,
  ``S = sum_k f_k H`` with ``f_k`` Winter's segment-length fractions
  (:func:`mirrorgraph.anthropometry.expected_bone_lengths`; D. A. Winter,
  *Biomechanics and Motor Control of Human Movement*, 4th ed., 2009, Fig. 4.1),
  and ``d``, the joints and the lengths come out in metres. Without a height
  the same factor holds the initial estimate of ``S`` and the solution is
  rescaled to ``d = 1`` afterwards (:mod:`mirrorgraph.pipelines.solve`): fixing
  ``d`` directly lets the length-valued body priors shrink the body against
  the weak data coupling of the ratio body / mirror distance, which tilts the
  mirror (measured: 1.4 deg on a 1000-frame scene whose bound is 0.12 deg).
  Residual ``r = sum_k L_k - S`` (1,); ``dr/dL = (1, ..., 1)``. Key: the length vector ``L``.

  The factor is a *gauge*: its sigma is tiny. An honest sigma (an individual's
  proportions differ from the population's by a few percent) cannot be put
  in the graph, because every other length-valued prior (bone constancy,
  smoothness) has its residuals shrink with the scene and would pull the
  scale towards zero against a soft prior. Being a pure scale, that
  uncertainty is exact to add afterwards: ``distance_std^2 += (rel_sigma d)^2``
  (:mod:`mirrorgraph.pipelines.solve`). For the same reason the final scale need not be
  this gauge's: by default the solution is rescaled afterwards so that the stature
  measured on its joints is ``H`` (:mod:`mirrorgraph.pipelines.scale`), which
  leaves the subject's limb proportions out of it; the gauge then only fixes the
  scale during the solve.
* :class:`DistancePriorFactor` when there are no bone lengths (body priors
  off) and in the reprojection-only warm start: ``d = d0`` (1 by default), i.e.
  lengths in units of the mirror distance. Residual ``r = d - d0`` (1,); the plane
  variable (:class:`gtsam.OrientedPlane3`, ``d_gtsam = -d``, see
  :mod:`mirrorgraph.factors.mirror_link`) retracts ``d_gtsam`` additively, so
  ``dr/d(v1, v2, v3) = (0, 0, -1)``.
"""

from __future__ import annotations

import gtsam
import numpy as np

from .mirror_link import plane_from_gtsam

__all__ = ["HeightPriorFactor", "DistancePriorFactor"]

_DIST_JAC = np.array([[0.0, 0.0, -1.0]])


class HeightPriorFactor:
    """Prior on the sum of the bone lengths implied by the subject's height.

    Args:
        expected_sum: ``sum_k w_k f_k H`` in metres (``w_k = 1`` without weights).
        rel_sigma: standard deviation relative to ``expected_sum`` (a gauge: tiny).
        weights: ``(n,)`` weight of each length in the sum (default: all 1); see
            :func:`mirrorgraph.graph.priors.gauge_weights` for why and where.
    """

    def __init__(self, expected_sum: float, rel_sigma: float = 1e-6,
                 weights: np.ndarray | None = None) -> None:
        self.expected_sum = float(expected_sum)
        self.sigma = float(rel_sigma) * self.expected_sum
        self.weights = None if weights is None else np.asarray(weights, dtype=float).reshape(-1)

    def evaluate(self, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Residual ``(1,)`` metres and its Jacobian ``(1, n)`` (the weights, else all ones)."""
        L = np.asarray(lengths, dtype=float).reshape(-1)
        if self.weights is None:
            return np.array([L.sum() - self.expected_sum]), np.ones((1, len(L)))
        return (np.array([float(self.weights @ L) - self.expected_sum]),
                self.weights.reshape(1, -1).copy())

    def make(self, length_key: int) -> gtsam.CustomFactor:
        """The factor on the length vector."""
        evaluate = self.evaluate

        def error(this: gtsam.CustomFactor, values: gtsam.Values, H) -> np.ndarray:
            r, J = evaluate(values.atVector(length_key))
            if H is not None:
                H[0] = J
            return r

        return gtsam.CustomFactor(gtsam.noiseModel.Isotropic.Sigma(1, self.sigma),
                                  [int(length_key)], error)


class DistancePriorFactor:
    """Prior ``d = d0`` on the mirror distance (the unit-distance gauge).

    Args:
        distance: ``d0`` (1.0: lengths in units of the mirror distance).
        sigma: standard deviation; tiny, it is a gauge, not information.
    """

    def __init__(self, distance: float = 1.0, sigma: float = 1e-6) -> None:
        self.distance = float(distance)
        self.sigma = float(sigma)

    def evaluate(self, d: float) -> tuple[np.ndarray, np.ndarray]:
        """Residual ``(1,)`` and Jacobian ``(1, 3)`` w.r.t. the plane's tangent space."""
        return np.array([float(d) - self.distance]), _DIST_JAC

    def make(self, plane_key: int) -> gtsam.CustomFactor:
        """The factor on the plane variable."""
        evaluate = self.evaluate

        def error(this: gtsam.CustomFactor, values: gtsam.Values, H) -> np.ndarray:
            _, d = plane_from_gtsam(values.atOrientedPlane3(plane_key))
            r, J = evaluate(d)
            if H is not None:
                H[0] = J
            return r

        return gtsam.CustomFactor(gtsam.noiseModel.Isotropic.Sigma(1, self.sigma),
                                  [int(plane_key)], error)
