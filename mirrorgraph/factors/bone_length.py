"""Constant bone lengths over time (the paper's ``L_var``): one range factor per frame and bone.

MirrorCalib (Liao, Zheng and Mitchell, sec. "Refining 2D joint locations",
eq. ``L_var``) penalises the variation of every bone's length over the
recording relative to its mean. In a factor graph the natural form is a length
``L_k`` per bone, shared by all frames, and per frame ``t`` the residuals

    r_k^t = |X_a^t - X_b^t| - L_k,      k over the bones seen in frame t,

with standard deviation ``sigma`` (length unit of the scene).

Each residual is GTSAM's built-in :class:`gtsam.RangeFactor3` between the two
joints with the measured range ``L_k``: the lengths are *held* during a
linearisation and set between linearisations to their optimum given the joints
(:func:`mirrorgraph.graph.lengths.update_lengths`: the mean length over the
frames, with the length-only priors and the gauge). That block-coordinate step
reaches the joint optimum of points, mirror and lengths (at a fixed point both
blocks' gradients vanish), and it keeps every bone in C++: a Python factor per
frame carrying ``L`` as a variable cost ~30 us per linearisation and made each
frame's joints one dense clique (measured on 1000 frames x 12 joints: linearise
10 ms against that form's 37, eliminate 32 ms against 57, a solve).

Jacobians (GTSAM's): ``dr / dX_a = u^T``, ``dr / dX_b = -u^T``,
``u = (X_a - X_b) / |X_a - X_b|``.

Where the lengths are strongly coupled to another global, the alternation converges
too slowly: an estimated focal length changes every reconstructed bone's length
(the focal length is determined by the bones' constancy alone), so that with the
lengths held each step moves it by a fraction of its way. There the lengths are a
variable ``L`` (the :data:`~mirrorgraph.graph.problem.LENGTH_KEY` vector) of the
linear systems, one :class:`gtsam.CustomFactor` per frame on that frame's joints and
``L`` (:meth:`BoneLengthFactor.add_frames`): residuals ``|X_a - X_b| - L_k`` of every
bone of the frame, ``dr / dL_k = -1``. It costs ~30 us a frame per linearisation and
makes each frame's joints one clique with ``L`` (measured on 1000 frames x 12
joints: linearise 37 ms against the held lengths' 10, eliminate 57 ms against 32, a
solve).
"""

from __future__ import annotations

import gtsam
import numpy as np

__all__ = ["BoneLengthFactor"]


class BoneLengthFactor:
    """The bones of many frames against their held lengths.

    Args:
        sigma: standard deviation of a bone's length about its constant value,
            length unit of the scene (metres when the scale is metric).
    """

    def __init__(self, sigma: float) -> None:
        self.sigma = float(sigma)
        self._noise = gtsam.noiseModel.Isotropic.Sigma(1, self.sigma)

    @staticmethod
    def evaluate(Xa: np.ndarray, Xb: np.ndarray, L: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Residuals and Jacobians, vectorised over bones.

        Args:
            Xa, Xb: ``(N, 3)`` end points of each bone (world frame).
            L: ``(N,)`` bone lengths.

        Returns:
            ``r`` (N,), ``dr/dXa`` (N, 3), ``dr/dXb`` (N, 3).
        """
        diff = np.asarray(Xa, dtype=float) - np.asarray(Xb, dtype=float)
        length = np.sqrt(np.einsum("bi,bi->b", diff, diff))
        unit = diff / np.maximum(length, 1e-12)[:, None]
        return length - np.asarray(L, dtype=float), unit, -unit

    def add_frames(self, graph: gtsam.NonlinearFactorGraph, keys_a: np.ndarray,
                   keys_b: np.ndarray, bones: np.ndarray, frames: np.ndarray,
                   length_key: int, num_bones: int) -> None:
        """Add one :class:`gtsam.CustomFactor` per frame on its joints and the lengths.

        Args:
            graph: the graph to add to.
            keys_a, keys_b: ``(N,)`` keys of each bone row's two joints.
            bones: ``(N,)`` index of each row's bone in the length vector.
            frames: ``(N,)`` frame of each row (rows of a frame become one factor).
            length_key: key of the length vector ``L`` (``(num_bones,)``).
            num_bones: ``B``, the length of ``L``.
        """
        keys_a = np.asarray(keys_a, dtype=np.uint64)
        keys_b = np.asarray(keys_b, dtype=np.uint64)
        bones = np.asarray(bones, dtype=np.int64)
        frames = np.asarray(frames, dtype=np.int64)
        order = np.argsort(frames, kind="stable")
        starts = np.flatnonzero(np.r_[True, np.diff(frames[order]) != 0])
        for a, b in zip(starts, np.r_[starts[1:], len(order)]):
            rows = order[a:b]
            graph.push_back(self._frame(keys_a[rows], keys_b[rows], bones[rows],
                                        int(length_key), int(num_bones)))

    def _frame(self, ka: np.ndarray, kb: np.ndarray, bones: np.ndarray, length_key: int,
               num_bones: int) -> gtsam.CustomFactor:
        """The bones of one frame: ``R`` residuals on its joints and ``L``."""
        points = sorted(set(ka.tolist()) | set(kb.tolist()))
        slot = {k: i for i, k in enumerate(points)}
        ia = np.array([slot[k] for k in ka.tolist()])
        ib = np.array([slot[k] for k in kb.tolist()])
        R, P = len(bones), len(points)
        rows = np.arange(R)
        JL = np.zeros((R, num_bones))
        JL[rows, bones] = -1.0

        def error(this: gtsam.CustomFactor, values: gtsam.Values, H) -> np.ndarray:
            X = np.array([values.atPoint3(k) for k in points])
            diff = X[ia] - X[ib]                  # (what :meth:`evaluate` does, without
            length = np.sqrt((diff * diff).sum(1))    # its per-call einsum overhead)
            r = length - values.atVector(length_key)[bones]
            if H is not None:
                da = diff / np.maximum(length, 1e-12)[:, None]
                J = np.zeros((P, R, 3))
                J[ia, rows] += da
                J[ib, rows] -= da
                for i in range(P):
                    H[i] = J[i]
                H[P] = JL
            return r

        return gtsam.CustomFactor(gtsam.noiseModel.Isotropic.Sigma(R, self.sigma),
                                  points + [length_key], error)

    def add(self, graph: gtsam.NonlinearFactorGraph, keys_a: np.ndarray, keys_b: np.ndarray,
            lengths: np.ndarray) -> None:
        """Add one :class:`gtsam.RangeFactor3` per row.

        Args:
            graph: the graph to add to.
            keys_a, keys_b: ``(N,)`` keys of each bone's two joints
                (:class:`gtsam.Point3` variables).
            lengths: ``(N,)`` each row's held length.
        """
        make, noise, push = gtsam.RangeFactor3, self._noise, graph.push_back
        for a, b, length in zip(np.asarray(keys_a, dtype=np.uint64).tolist(),
                                np.asarray(keys_b, dtype=np.uint64).tolist(),
                                np.asarray(lengths, dtype=float).tolist()):
            push(make(a, b, length, noise))
