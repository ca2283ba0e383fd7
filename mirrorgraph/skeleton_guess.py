"""Tell keypoint layouts of the same count apart from the detections themselves.

Only one count is ambiguous: 25, OpenPose's ``BODY_25`` and its experimental
``BODY_25B`` (Pose2Sim's default), which differ in the order of the joints. Joints 0, 1,
2 and 5 are

=====  ============================  =========================
index  BODY_25                       BODY_25B
=====  ============================  =========================
0      nose                          nose
1      neck (mid-shoulder)           left eye
2      right shoulder                right eye
5      left shoulder                 left shoulder
=====  ============================  =========================

For one detection let ``a = |p1 - (p2 + p5) / 2|`` and ``b = max(|p1 - p0|, |p2 - p0|)``
(pixels). In BODY_25 the neck is the midpoint of the shoulders, so ``a`` is detector
noise while ``b`` is at least the nose-to-neck distance; in BODY_25B joints 1 and 2 are
the eyes, so ``b`` is an eye-to-nose distance while ``a`` is half an eye-to-shoulder
distance. The ratio ``r = a / (a + b)`` in ``[0, 1]`` does not depend on image scale,
rotation or a reflection's labelling. The median of ``r`` over the file's confident
detections decides (BODY_25 under 0.30, BODY_25B over 0.45); a file with fewer than
:data:`MIN_DETECTIONS` of them, or a median in between, is refused with a message asking
for the ``skeleton`` argument (``--skeleton`` on the command line).

The thresholds come from the medians measured on synthetic scenes (BODY_25 0.05-0.36,
BODY_25B 0.41-0.69, random joints 0.41; ``tests/test_skeletons_extra.py``); the table of
them: ``docs/internals.md``.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from .errors import InputError
from .keypoints import DEFAULT_MIN_CONFIDENCE
from .skeletons import BODY_25, BODY_25B, Skeleton

#: A joint takes part only with at least this confidence (the CLI's default
#: ``--min-confidence``).
MIN_CONFIDENCE = DEFAULT_MIN_CONFIDENCE

#: Fewest usable detections (all of joints 0, 1, 2, 5 confident) for a decision.
MIN_DETECTIONS = 10

#: Median ratio below which the data are BODY_25 ...
BODY_25_BELOW = 0.30

#: ... and above which they are BODY_25B; in between the data do not tell.
BODY_25B_ABOVE = 0.45


def body25_ratios(keypoints: np.ndarray, min_confidence: float = MIN_CONFIDENCE) -> np.ndarray:
    """Per detection ``r = a / (a + b)`` of the module docstring.

    Args:
        keypoints: ``(N, 25, 3)`` detections (x px, y px, confidence), any labelling.
        min_confidence: joints 0, 1, 2 and 5 must all have at least this confidence.

    Returns:
        ``(M,)`` ratios in ``[0, 1]`` (dimensionless) of the ``M <= N`` usable
        detections: joints confident and finite, ``a + b > 0``.
    """
    kp = np.asarray(keypoints, dtype=float).reshape(-1, 25, 3)[:, [0, 1, 2, 5]]   # (N, 4, 3)
    xy = kp[..., :2]
    ok = (kp[..., 2] >= min_confidence).all(-1) & np.isfinite(xy).all((-1, -2))
    xy = xy[ok]
    nose, p1, p2, p5 = (xy[:, i] for i in range(4))
    a = np.linalg.norm(p1 - (p2 + p5) / 2.0, axis=-1)
    b = np.maximum(np.linalg.norm(p1 - nose, axis=-1), np.linalg.norm(p2 - nose, axis=-1))
    s = a + b
    return a[s > 0] / s[s > 0]


class AmbiguousSkeletonError(InputError):
    """25 keypoints that one input's detections do not resolve into BODY_25 or BODY_25B.

    An :class:`InputError` (its ``fix`` names the ``skeleton`` argument), carrying what a caller
    holding several inputs of one layout (a rig's cameras) needs to decide from all of
    them together (:func:`decide_body25`).

    Attributes:
        candidates: the layouts the count fits.
        ratios: ``(M,)`` the input's usable ratios (:func:`body25_ratios`).
    """

    def __init__(self, message: str, *, source: Any, candidates: Sequence[Skeleton],
                 ratios: np.ndarray, fix: tuple[str, ...] = ()) -> None:
        super().__init__(message, source=source, fix=fix)
        self.candidates = tuple(candidates)
        self.ratios = np.asarray(ratios, dtype=float)


def decide_body25(ratios: np.ndarray) -> tuple[Skeleton | None, str]:
    """BODY_25, BODY_25B or neither from detections' ratios (:func:`body25_ratios`).

    Args:
        ratios: ``(M,)`` ratios, one a detection, from one input or several pooled.

    Returns:
        the layout (``None``: undecided) and, when undecided, why, in words.
    """
    r = np.asarray(ratios, dtype=float)
    if len(r) < MIN_DETECTIONS:
        return None, f"only {len(r)} confident detections to tell them apart"
    m = float(np.median(r))
    if m < BODY_25_BELOW:
        return BODY_25, ""
    if m > BODY_25B_ABOVE:
        return BODY_25B, ""
    return None, f"the joints do not tell them apart (median ratio {m:.2f})"


def guess_skeleton(candidates: Sequence[Skeleton], people: np.ndarray | Iterable[Any], *,
                   source: Any) -> Skeleton:
    """The layout among ``candidates`` (same keypoint count) that ``people`` show.

    Args:
        candidates: layouts sharing a count; only ``(BODY_25, BODY_25B)`` (either
            order) can be told apart.
        people: ``(N, J, 3)`` detections (x px, y px, confidence), or an iterable of
            ``(P_t, J, 3)`` arrays per frame (``None`` entries skipped).
        source: the file or folder, for the error message.

    Raises:
        InputError: the candidates cannot be told apart;
            :class:`AmbiguousSkeletonError` where the data do not decide (fewer than
            :data:`MIN_DETECTIONS` usable detections, or a median ratio between
            :data:`BODY_25_BELOW` and :data:`BODY_25B_ABOVE`).
    """
    names = " or ".join(s.name for s in candidates)
    fix = tuple(f"skeleton={s.name}" for s in candidates)
    if {s.name for s in candidates} != {BODY_25.name, BODY_25B.name}:
        raise InputError(f"the keypoint count fits {names}", source=source, fix=fix)
    if isinstance(people, np.ndarray):
        kp = people.reshape(-1, 25, 3)
    else:
        rows = [np.asarray(p, dtype=float).reshape(-1, 25, 3) for p in people if p is not None]
        kp = np.concatenate(rows) if rows else np.empty((0, 25, 3))
    r = body25_ratios(kp)
    found, why = decide_body25(r)
    if found is not None:
        return found
    raise AmbiguousSkeletonError(f"25 keypoints fit BODY_25 and BODY_25B and {why}",
                                 source=source, fix=fix, candidates=candidates, ratios=r)
