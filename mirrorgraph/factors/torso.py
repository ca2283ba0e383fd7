"""The torso nearly rigid: the distances between its four corner joints held over the video.

The shoulders and the hips are the corners of the trunk, which bends and twists only a
little about its own length: the distance between any two of the four joints (the two
sides, shoulder to hip of one side, and the two diagonals, shoulder to the other hip)
stays within a few centimetres of its value over a video. On the CMU take that
:mod:`mirrorgraph.synth.mocap` ships (01_01: marker-based motion capture) these four
distances have a standard deviation of 0.5-0.7 cm, their 1st-99th percentile range 2-3 cm
(the shoulder girdle's elevation and the spine's flexion; Winter, *Biomechanics and Motor
Control of Human Movement*, 4th ed., 2009, ch. 4 treats the trunk as one segment).

A skeleton's bones (:mod:`mirrorgraph.skeletons`) link a shoulder to its elbow and to the
other shoulder (or the neck), never to a hip: a shoulder whose two rays meet at a small
angle then slides in depth on the sphere its shoulder width allows, carrying its arm,
and meets that sphere twice. The torso's distances tie it to the hips, whose depth the
legs hold.

Each distance is a range between two joints of one frame at a held length, GTSAM's
built-in :class:`gtsam.RangeFactor3` as a bone's (:class:`~.bone_length.BoneLengthFactor`,
whose residual and Jacobians it shares):

    r = |X_a - X_b| - L,      standard deviation ``sigma`` (length unit of the scene).

:func:`torso_pairs` names the distances a skeleton's bones do not already hold.
"""

from __future__ import annotations

import gtsam
import numpy as np

from .bone_length import BoneLengthFactor

__all__ = ["TORSO_CORNERS", "TorsoFactors", "torso_pairs"]


#: The torso's four corners: joint names (without a person's tag).
TORSO_CORNERS = ("left_shoulder", "right_shoulder", "left_hip", "right_hip")


def torso_pairs(joint_names: list[str] | tuple[str, ...],
                bones: list[tuple[int, int]] | np.ndarray) -> np.ndarray:
    """``(P, 2)`` joint indices of the torso's distances the bones do not hold.

    Every pair of the four corners (:data:`TORSO_CORNERS`) of each person (a joint name's
    tag after ``@``, :func:`mirrorgraph.skeletons.people_skeleton`) that has all four,
    less the pairs that are a bone already (COCO's shoulder and hip widths).

    Args:
        joint_names: the skeleton's joint names, index order.
        bones: ``(B, 2)`` the joint indices of the bones held elsewhere.
    """
    held = {frozenset((int(a), int(b))) for a, b in np.asarray(bones, int).reshape(-1, 2)}
    people: dict[str, dict[str, int]] = {}
    for i, name in enumerate(joint_names):
        base, _, tag = str(name).partition("@")
        if base in TORSO_CORNERS:
            people.setdefault(tag, {})[base] = i
    out = []
    for corners in people.values():
        if len(corners) < len(TORSO_CORNERS):
            continue
        idx = [corners[c] for c in TORSO_CORNERS]
        for k, a in enumerate(idx):
            for b in idx[k + 1:]:
                if frozenset((a, b)) not in held:
                    out.append((a, b))
    return np.array(out, dtype=int).reshape(-1, 2)


class TorsoFactors:
    """The torso's distances in every frame, each at its held length.

    Args:
        sigma: standard deviation of a distance about its held length, length unit of
            the scene.
    """

    def __init__(self, sigma: float) -> None:
        self.sigma = float(sigma)
        self._bone = BoneLengthFactor(self.sigma)

    @staticmethod
    def evaluate(Xa: np.ndarray, Xb: np.ndarray, L: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Residuals ``(N,)`` and Jacobians ``(N, 3)`` w.r.t. ``Xa`` and ``Xb`` ``(N, 3)``
        at lengths ``L`` ``(N,)`` (:meth:`.BoneLengthFactor.evaluate`)."""
        return BoneLengthFactor.evaluate(Xa, Xb, L)

    def add(self, graph: gtsam.NonlinearFactorGraph, keys_a: np.ndarray, keys_b: np.ndarray,
            lengths: np.ndarray) -> None:
        """One range factor per row: ``keys_a``, ``keys_b`` ``(N,)`` the two joints'
        :class:`gtsam.Point3` keys, ``lengths`` ``(N,)`` each row's held length."""
        self._bone.add(graph, keys_a, keys_b, lengths)
