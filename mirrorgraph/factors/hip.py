"""Hip colinearity (the paper's ``L_hip``), for skeletons with a mid-hip joint.

MirrorCalib (Liao, Zheng and Mitchell, eq. ``L_hip``) expects the left hip, the
mid-hip and the right hip to be colinear and penalises
``|v_ml x v_mr|``, the cross product of the vectors from the mid-hip to either
hip. The paper skips it for detectors without a mid-hip (HRNet / COCO), and so
does :mod:`mirrorgraph.graph.builder`. One factor per frame:

    r = (X_l - X_m) x (X_r - X_m) / s^2        (3,), dimensionless,

``s`` a fixed length scale (the expected half hip width, so that ``|r|`` is about
the sine of the angle between the two half-pelvis vectors), standard
deviation ``sigma``. Jacobians with ``a = X_l - X_m``, ``b = X_r - X_m``:
``dr/dX_l = -[b]x / s^2``, ``dr/dX_r = [a]x / s^2``, ``dr/dX_m = ([b]x - [a]x) / s^2``.
Keys: mid-hip, left hip, right hip (:class:`gtsam.Point3`, world frame).
"""

from __future__ import annotations

import gtsam
import numpy as np

from ..geometry import skew

__all__ = ["HipColinearityFactor"]


class HipColinearityFactor:
    """Colinearity of left hip, mid-hip and right hip in one frame.

    Args:
        scale: length ``s`` normalising the cross product (length unit of the scene).
        sigma: standard deviation of the normalised cross product (about the
            sine of the hip angle's deviation from a straight line).
    """

    def __init__(self, scale: float, sigma: float) -> None:
        self.scale = float(scale)
        self.sigma = float(sigma)

    def evaluate(self, Xm: np.ndarray, Xl: np.ndarray, Xr: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Residual ``(3,)`` and Jacobians ``(3, 3)`` w.r.t. mid, left and right hip."""
        s2 = self.scale * self.scale
        a = np.asarray(Xl, dtype=float) - np.asarray(Xm, dtype=float)
        b = np.asarray(Xr, dtype=float) - np.asarray(Xm, dtype=float)
        A, Bm = skew(a) / s2, skew(b) / s2
        return np.cross(a, b) / s2, Bm - A, -Bm, A

    def make(self, mid_key: int, left_key: int, right_key: int) -> gtsam.CustomFactor:
        """The factor of one frame."""
        keys = [int(mid_key), int(left_key), int(right_key)]
        evaluate = self.evaluate

        def error(this: gtsam.CustomFactor, values: gtsam.Values, H) -> np.ndarray:
            r, Jm, Jl, Jr = evaluate(values.atPoint3(keys[0]), values.atPoint3(keys[1]),
                                     values.atPoint3(keys[2]))
            if H is not None:
                H[0] = Jm
                H[1] = Jl
                H[2] = Jr
            return r

        return gtsam.CustomFactor(gtsam.noiseModel.Isotropic.Sigma(3, self.sigma), keys, error)
