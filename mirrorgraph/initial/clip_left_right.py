"""Which view's left/right labels a detector crossed, decided over the whole clip.

A detector labels a body seen from behind as one facing the camera: in the view that
shows the person's back (the direct view when they face the mirror, the reflection when
they face the camera) their left and right are crossed, frame after frame, for as long as
they turn their back, or the whole clip. The pairing's check (:func:`.left_right.is_swap`)
decides each frame on its own and only where the crossed labels fit the epipole badly;
where the person's left/right pairs lie along the epipolar lines (seen from the side of the
mirror) both labellings fit and the crossed ones stay, and a consistent pair of crossed
views triangulates a body whose left is its right.

:func:`crossed_states` decides it for every frame of the clip jointly, with a hidden
four-state Markov chain decoded by its min-sum (Viterbi) messages (Rabiner 1989,
sec. III-B; :func:`.body_left_right.min_sum_messages`): the state is whether the direct
view's labels are crossed and whether the reflection's are. Each frame weighs how well the
two views' labels fit the mirror's epipole under the state (which tells crossed views from
consistent ones, not which view is crossed) and the handedness of the body they
triangulate (a person's left, up and facing make a right-handed frame: which view is
crossed); each step between frames weighs the motion of every view's keypoints as the
states relabel them (the chain changes a view's state where the detector's labels jump from
one side to the other) and a cost per change. A run between two jumps is decided by the
evidence of all its frames together: frames where neither labelling fits better (the side
views) take their run's state, and a clip the detector labels the same way throughout is
decided as one. :func:`clip_left_right` relabels the frames so found;
:func:`clip_left_right_people` does it for every person's track apart.

Frames: ``paired.real`` and ``paired.mirror`` in undistorted pixels, the reflection's labels
in the person's (:class:`~mirrorgraph.keypoints.PairedKeypoints`); ``K`` the camera's (an
approximate one serves: the handedness is a sign).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .. import geometry as geo
from ..errors import DegenerateGeometryError
from ..keypoints import PairedKeypoints
from .body_left_right import min_sum_messages
from .pair_candidates import PairingOptions, epipole_either_labelling, masked, spread_subset

__all__ = ["ClipLeftRightOptions", "clip_left_right", "clip_left_right_people",
           "crossed_states", "handedness"]


@dataclass(frozen=True)
class ClipLeftRightOptions:
    """The chain's costs (negative log-probabilities) and limits.

    Attributes:
        truncation: a joint's epipolar distance counts up to this many ``sigma`` (half
            the pairing's threshold), its motion up to this many typical motions: a gross
            error weighs no more than this.
        facing_gain: ``k`` of the facing term: a frame whose normalised handedness is
            ``h`` says ``k |h|`` nats for its sign.
        dead_zone: the epipolar distance that says nothing, in units of ``sigma`` (half the
            pairing's threshold): without it the realistic detector's label-following bias
            crosses whole runs of a scene whose left/right pairs lie along the epipolar
            lines; from ``0.5`` on, BlazePose's crossed runs of a drawn clip go unseen
            (``bench/RESULTS_left_right_clip.md``).
        evidence_weight: the weight of each frame's epipolar and facing terms (about one
            over the number of frames a detector's errors stay correlated).
        switch_cost: a change of one view's state between consecutive frames
            (``-log`` of its prior probability per frame; ``9.2``: 1e-4).
        crossed_cost: each frame of the direct view and of the reflection in the crossed
            state (the labels as given are the default; the reflection, seen from behind
            where the person faces the camera, a little less so).
        max_gap: frames further apart are unrelated; the chain restarts.
        min_motion_px: floor of a joint's typical motion between consecutive frames (the
            detector's noise), pixels.
    """

    truncation: float = 3.0
    facing_gain: float = 4.0
    dead_zone: float = 0.25
    evidence_weight: float = 0.1
    switch_cost: float = 9.2
    crossed_cost: tuple[float, float] = (0.006, 0.005)
    max_gap: int = 15
    min_motion_px: float = 2.0


#: The chain's states: whether the direct view's (bit 0) and the reflection's (bit 1)
#: labels are crossed.
_REAL = np.array([0, 1, 0, 1])
_MIRROR = np.array([0, 0, 1, 1])

#: The joints of the handedness: (left, right) pairs of the body's side, the face.
_SIDES = (("left_shoulder", "right_shoulder"), ("left_hip", "right_hip"))
_FACE = ("nose", "left_eye", "right_eye", "left_ear", "right_ear")


#: The face's offset ahead of the ears' midpoint, in units of the torso's length (the
#: shoulders' midpoint to the hips'): about 10 cm of 50 cm.
FACE_AHEAD = 0.2


def _face_joints(sk) -> np.ndarray | None:
    """``(9,)`` indices: left shoulder, right shoulder, left hip, right hip, nose, left eye,
    right eye, left ear, right ear; ``None`` where the layout lacks one."""
    names = [n for pair in _SIDES for n in pair] + list(_FACE)
    if not all(sk.has(n) for n in names):
        return None
    return np.array([sk.index(n) for n in names])


def handedness(X: np.ndarray) -> np.ndarray:
    """``(...)`` the normalised handedness ``h`` of bodies ``(..., 9, 3)`` (the joints of
    :func:`_face_joints`' order, any frame and unit): positive for a body whose joints
    labelled left are on its left (module docstring), in ``[-1, 1]``; NaN where a joint is.
    """
    side = (X[..., 0, :] - X[..., 1, :]) + (X[..., 2, :] - X[..., 3, :])
    up = 0.5 * (X[..., 0, :] + X[..., 1, :]) - 0.5 * (X[..., 2, :] + X[..., 3, :])
    ahead = (0.5 * X[..., 4, :] + 0.25 * (X[..., 5, :] + X[..., 6, :])
             - 0.5 * (X[..., 7, :] + X[..., 8, :]))
    h = np.einsum("...i,...i->...", np.cross(side, up), ahead)
    norm = (np.linalg.norm(side, axis=-1) * np.linalg.norm(up, axis=-1)
            * np.linalg.norm(ahead, axis=-1))
    with np.errstate(invalid="ignore", divide="ignore"):
        return h / norm


def _facing(paired: PairedKeypoints, real: np.ndarray, mirror: np.ndarray, e: np.ndarray,
            K: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """``(T, 2)`` the handedness of each frame's body triangulated from the reflection as
    labelled (``[:, 0]``) and with its left and right exchanged (``[:, 1]``), the direct
    view's labels, and ``(T, 2)`` its weight (the module docstring's); NaN (weight 0)
    where the layout or a frame lacks a joint of it."""
    T = len(real)
    idx = _face_joints(paired.skeleton)
    if idx is None:
        return np.full((T, 2), np.nan), np.zeros((T, 2))
    flip = paired.skeleton.flip
    n = geo.normal_from_epipole(K, e)
    u, um = real[:, idx, :2], mirror[:, idx, :2]
    seen = np.isfinite(u).all(-1) & np.isfinite(um).all(-1)
    if seen[:, 4].sum() >= 3:                      # the nose: the same in either labelling
        n = geo.orient_normal(K, n, u[seen[:, 4], 4], um[seen[:, 4], 4])
    out, weight = [], []
    for m in (mirror, mirror[:, flip]):
        X = geo.triangulate_mirror(K, n, 1.0, u, m[:, idx, :2], iterations=0)
        out.append(handedness(X))
        head = X[:, 4:].mean(1)                                        # (T, 3)
        torso = np.linalg.norm(X[:, :2].mean(1) - X[:, 2:4].mean(1), axis=-1)
        d1 = np.linalg.norm(head, axis=-1)
        d2 = np.linalg.norm(head - 2.0 * n, axis=-1)                  # the virtual camera
        with np.errstate(invalid="ignore", divide="ignore"):
            sin = np.linalg.norm(np.cross(head / d1[:, None], (head - 2.0 * n) / d2[:, None]),
                                 axis=-1)
            q = FACE_AHEAD * torso * K[0, 0] * sin / (sigma * np.hypot(d1, d2))
        weight.append(np.nan_to_num(q ** 2 / (1.0 + q ** 2)))
    return np.stack(out, axis=-1), np.stack(weight, axis=-1)


def _epipolar(e: np.ndarray, real: np.ndarray, mirror: np.ndarray, flip: np.ndarray,
              sigma: float, cap: float, dead_zone: float) -> np.ndarray:
    """``(T, 2)`` the epipolar term of the reflection as labelled and with its left and
    right exchanged (the module docstring's), over the joints with a counterpart."""
    sided = np.flatnonzero(flip != np.arange(len(flip)))
    out = []
    for m in (mirror, mirror[:, flip]):
        d = geo.epipolar_distances(e, real[:, sided, :2], m[:, sided, :2])
        r = np.minimum((np.maximum(d - dead_zone * sigma, 0.0) / sigma) ** 2, cap ** 2)
        out.append(0.5 * np.nansum(np.where(np.isfinite(r), r, np.nan), axis=1))
    return np.stack(out, axis=-1)


def _motion(view: np.ndarray, flip: np.ndarray, gap: np.ndarray, cap: float,
            floor: float) -> np.ndarray:
    """``(T, 2)`` the motion term of one view ``(T, J, 3)`` from its last keypoints seen
    before each frame, with the frame's labels as given (``[:, 0]``) and exchanged
    (``[:, 1]``), in units of each joint's typical motion over ``gap`` frames (the module
    docstring's)."""
    x = view[..., :2]
    T = len(x)
    ok = np.isfinite(x).all(-1)                                         # (T, J)
    seen = np.maximum.accumulate(np.where(ok, np.arange(T)[:, None], -1), axis=0)
    prev = np.concatenate([np.full((1, x.shape[1]), -1), seen[:-1]])    # last seen before t
    last = np.where((prev >= 0)[..., None],
                    np.take_along_axis(x, np.maximum(prev, 0)[..., None], axis=0), np.nan)
    d = np.linalg.norm(x[1:] - x[:-1], axis=-1)[gap[1:] == 1]
    with np.errstate(invalid="ignore"):
        scale = (np.nanmedian(np.where(np.isfinite(d), d, np.nan), axis=0) if len(d)
                 and np.isfinite(d).any() else np.full(x.shape[1], np.nan))
    scale = np.where(np.isfinite(scale), np.maximum(scale, floor), floor)     # (J,)
    s = scale * np.maximum(gap, 1)[:, None]
    out = []
    for cur in (x, x[:, flip]):
        r = np.minimum((np.linalg.norm(cur - last, axis=-1) / s) ** 2, cap ** 2)
        out.append(0.5 * np.nansum(r, axis=1))
    return np.stack(out, axis=-1)


def _epipole(real: np.ndarray, mirror: np.ndarray, joints: np.ndarray, flip: np.ndarray,
             opts: PairingOptions, source: str) -> np.ndarray:
    """The mirror's epipole from a spread subset of the paired frames, either labelling
    (:func:`.pair_candidates.epipole_either_labelling`)."""
    sub = spread_subset(np.arange(len(real)), opts.ransac_frames)
    try:
        e = epipole_either_labelling(real[sub], mirror[sub], joints, flip, opts, opts.seed)
    except DegenerateGeometryError as exc:
        raise DegenerateGeometryError(f"{source}: {exc}") from None
    return e


def crossed_states(paired: PairedKeypoints, K: np.ndarray, joints: np.ndarray | None = None,
                   pairing: PairingOptions | None = None,
                   options: ClipLeftRightOptions | None = None,
                   epipole: np.ndarray | None = None) -> np.ndarray:
    """``(T, 2)`` bool: the frames whose direct view (``[:, 0]``) and reflection
    (``[:, 1]``) carry crossed left/right labels, the most likely path of the module
    docstring's chain (each frame's state the smallest sum of the forward and backward
    min-sum messages).

    The chain's costs of a state, each frame:

    * the *epipolar* term: the two views' left/right joints under the labelling the state
      gives them relative to each other, ``sum_j min(((d_j - z sigma)_+ / sigma)^2, c^2) / 2``
      over the epipolar (Sampson) distances ``d_j`` to the epipole
      (:func:`mirrorgraph.geometry.epipolar_distances`), ``sigma`` half the pairing's
      threshold, ``c`` the truncation, ``z`` the dead zone (a detector's bias that follows
      its labels in both views makes the crossed labelling fit a little better where the
      left/right pairs lie along the epipolar lines, frame after frame);
    * the *facing* term: the body triangulated from the consistent labelling
      (:func:`mirrorgraph.geometry.triangulate_mirror`, the normal ``K^-1 e``, unit
      distance) has the handedness ``h = ((L - R) x (S - H)) . (N - E)`` normalised by the
      three lengths (:func:`handedness`: ``L``, ``R`` the shoulders and hips labelled left
      and right, ``S``, ``H`` the shoulders' and hips' midpoints, ``N`` the mean of the nose
      and the eyes' midpoint, ``E`` the ears' midpoint), ``h > 0`` where the labels are
      right and ``h < 0`` where both views are crossed (the midpoints and the nose do not
      depend on the labels). The term is the logistic loss ``log(1 + exp(-k s h))``, ``s``
      the sign the state expects, weighted by the share of ``h``'s spread that is signal,
      ``q^2 / (1 + q^2)``: ``q`` the face's offset ahead of the ears (:data:`FACE_AHEAD` of
      the torso's length) over the triangulation's std along its worse axis,
      ``sigma sqrt(D1^2 + D2^2) / (f sin theta)`` (``D1``, ``D2`` the head's distances to
      the camera and to the virtual camera, ``theta`` the angle between their rays: a
      person on the line between the camera and the mirror is seen along nearly opposite
      rays, and their facing is the depth neither view measures);
    * both weighted by ``evidence_weight`` (a detector's errors persist over frames, and so
      do the geometry's ambiguities: a run's frames are not independent witnesses);
    * a small cost of each crossed view (the labels as given are the default);

    and each step between consecutive frames costs ``switch_cost`` for each view whose state
    changes plus, in each view, the motion of its keypoints as the two states relabel them,
    ``sum_j min((|x_t - x_prev| / s_j)^2, c^2) / 2`` in units of each joint's typical motion
    ``s_j`` (over frames one apart, at least ``min_motion_px``). Frames further apart than
    ``max_gap`` are unrelated (the chain restarts).

    Args:
        paired: person and reflection, paired (the reflection's labels in the person's).
        K: ``(3, 3)`` the camera's intrinsics (pixels of ``paired``).
        joints: the joints that find the epipole (default: the calibration joints).
        pairing: the pairing's options (confidence, threshold, RANSAC seed and frames).
        options: :class:`ClipLeftRightOptions`.
        epipole: ``(3,)`` the mirror's homogeneous epipole, pixels; ``None``: found here.
    """
    popts = pairing or PairingOptions()
    opts = options or ClipLeftRightOptions()
    sk = paired.skeleton
    T = len(paired)
    if T == 0:
        return np.zeros((0, 2), bool)
    joints = sk.calibration_joints if joints is None else np.asarray(joints, dtype=int)
    flip = np.asarray(sk.flip)
    real = masked(paired.real, popts.min_confidence)
    mirror = masked(paired.mirror, popts.min_confidence)
    e = (_epipole(real, mirror, joints, flip, popts, paired.source) if epipole is None
         else np.asarray(epipole, dtype=float).reshape(3))
    epi = _epipolar(e, real, mirror, flip, 0.5 * popts.threshold_px, opts.truncation,
                    opts.dead_zone)
    face, weight = _facing(paired, real, mirror, e, np.asarray(K, dtype=float),
                           0.5 * popts.threshold_px)                        # (T, 2)
    rel = _REAL ^ _MIRROR                                   # (S,) pairing the state implies
    sign = 1.0 - 2.0 * _REAL                                 # (S,) handedness it expects
    h = np.nan_to_num(face[:, rel], nan=0.0)                 # (T, S)
    emit = (opts.evidence_weight * (epi[:, rel] + weight[:, rel]
                                    * np.logaddexp(0.0, -opts.facing_gain * sign * h))
            + opts.crossed_cost[0] * _REAL + opts.crossed_cost[1] * _MIRROR)
    frames = np.asarray(paired.frame_ids, dtype=np.int64)
    gap = np.diff(frames, prepend=frames[0]) if len(frames) == T else np.ones(T, np.int64)
    trans = np.zeros((T, len(_REAL), len(_REAL)))
    for bits, view in ((_REAL, real), (_MIRROR, mirror)):
        change = (bits[:, None] != bits[None, :]).astype(int)
        motion = _motion(view, flip, gap, opts.truncation, opts.min_motion_px)   # (T, 2)
        trans += opts.switch_cost * change + motion[:, change]
    trans = np.where((gap > opts.max_gap)[:, None, None] | (np.arange(T) == 0)[:, None, None],
                     0.0, trans)                             # (T, prev, cur)
    M = trans + emit[:, None, :]
    forward = min_sum_messages(M)
    backward = np.zeros_like(forward)
    if T > 1:
        backward[:-1] = min_sum_messages(np.swapaxes(M[1:][::-1], -1, -2))[::-1]
    state = np.argmin(forward + backward, axis=-1)
    seen = np.stack([np.isfinite(real[..., :2]).all(-1).any(-1),
                     np.isfinite(mirror[..., :2]).all(-1).any(-1)], -1)
    return np.stack([_REAL[state], _MIRROR[state]], -1).astype(bool) & seen


def clip_left_right(paired: PairedKeypoints, K: np.ndarray, joints: np.ndarray | None = None,
                    pairing: PairingOptions | None = None,
                    options: ClipLeftRightOptions | None = None,
                    epipole: np.ndarray | None = None) -> tuple[PairedKeypoints, int]:
    """Exchange left and right in the frames and views :func:`crossed_states` finds
    crossed.

    Returns:
        The keypoints so relabelled (``lr_fixes`` counts the frames changed on top of the
        pairing's), and how many frames changed.
    """
    crossed = crossed_states(paired, K, joints, pairing, options, epipole)
    changed = crossed.any(1)
    n = int(np.count_nonzero(changed))
    if n == 0:
        return paired, 0
    flip = paired.skeleton.flip
    real = np.where(crossed[:, 0, None, None], paired.real[:, flip], paired.real)
    mirror = np.where(crossed[:, 1, None, None], paired.mirror[:, flip], paired.mirror)
    return replace(paired, real=real, mirror=mirror, lr_fixes=paired.lr_fixes + n), n


def clip_left_right_people(paired: PairedKeypoints, base, K: np.ndarray, epipole: np.ndarray,
                           joints: np.ndarray | None = None,
                           pairing: PairingOptions | None = None,
                           options: ClipLeftRightOptions | None = None
                           ) -> tuple[PairedKeypoints, int]:
    """:func:`clip_left_right` for each person's track apart, with the mirror's epipole.

    Args:
        paired: every person and their reflection side by side, layout
            :func:`~mirrorgraph.skeletons.people_skeleton` of ``base`` (``(T, P J, 3)``).
        base: one person's layout (``J`` joints).
        K: ``(3, 3)`` the camera's intrinsics.
        epipole: ``(3,)`` the mirror's homogeneous epipole, pixels.
        joints: one person's joints (default: ``base``'s calibration joints).

    Returns:
        The keypoints relabelled, and how many (frame, person) tracks' frames changed.
    """
    J = base.num_joints
    P = paired.real.shape[1] // J
    real, mirror = np.array(paired.real, copy=True), np.array(paired.mirror, copy=True)
    total = 0
    for p in range(P):
        block = slice(p * J, (p + 1) * J)
        one = replace(paired, skeleton=base, real=paired.real[:, block],
                      mirror=paired.mirror[:, block], lr_fixes=0)
        fixed, n = clip_left_right(one, K, joints, pairing, options, epipole)
        real[:, block], mirror[:, block] = fixed.real, fixed.mirror
        total += n
    if total == 0:
        return paired, 0
    return replace(paired, real=real, mirror=mirror, lr_fixes=paired.lr_fixes + total), total
