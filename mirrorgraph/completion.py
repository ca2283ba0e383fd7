"""The keypoints the graph left out, triangulated with the solved mirror.

The single-mirror graph estimates the joints of its joint set (by default the limbs,
:mod:`mirrorgraph.joint_sets`): face and feet, seen by the camera and in the mirror,
have no 3D point from it. Once the mirror ``n . X = d`` is known every such keypoint
seen in both views is a two-view triangulation away
(:func:`mirrorgraph.geometry.triangulate_mirror`: the real camera ``K [I | 0]`` and the
virtual camera ``K [H | 2 d n]``, ``H = I - 2 n n^T``), in the refinement's unit
(metres with a subject height, else mirror distances), real camera frame.

Two views give a point for any pair of rays that nearly meet, so each point passes
two gates before it is kept:

* **reprojection**: its image in the direct view ``pi(K X)`` and in the mirror
  ``pi(K S(X))``, ``S(X) = X - 2 (n . X - d) n``, lie within ``threshold_px`` of the
  detections, and ``X`` is in front of the camera (``z > 0``), on the camera's side of
  the mirror (``n . X < d``) and its reflection in front of the camera. This catches an
  error across the epipolar line;
* **body**: an error *along* the epipolar line moves the point in depth at no
  reprojection cost. Each completed joint is anchored to the two graph joints nearest
  to it (median distance over frames, e.g. the nose to the neck and a shoulder, a toe
  to its ankle and knee); the distance to the anchors of a rigid body part changes
  little from frame to frame, so a frame whose distance to either departs from that
  anchor's median by more than ``max(k MAD, floor * median)`` (robust z-score,
  :data:`BODY_GATE_MADS`, :data:`BODY_GATE_FLOOR`) is dropped (:func:`anchor_gate`).

Measured (BODY_25, 300 frames, 4 px noise, 7 % outliers a view, 5 % left/right
swaps, seeds 0-3, subject height given): about 2,800 face and feet points completed
per scene (86 % of those seen in both views), median error 1.5-2.9 cm against the
truth (the graph's own joints: 1.0-2.6 cm), 0.4-1.7 % of them over 10 cm, most of
those detector outliers that moved along the epipolar line; 14 % of the joints in
``--joints3d`` stay NaN (the limbs' outliers the graph rejected; 49 % without it).

:func:`complete_mirror_joints` is written for one mirror. A rig
(:func:`complete_rig_joints`, any number of views, real or through a mirror) completes
every joint its graph did not estimate by a linear triangulation from every view that
observes it (:func:`mirrorgraph.geometry.triangulate`), one round of rejecting
observations farther than the outlier threshold from the first solution, then the
final triangulation; the completed joints give the stature estimate its eyes
(:mod:`mirrorgraph.stature`) and take no part in the calibration.
"""

from __future__ import annotations

import math
import warnings as _warnings
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from . import geometry as geo
from .keypoints import PairedKeypoints

if TYPE_CHECKING:
    from .rigs.observations import RigObservations
    from .pipelines.solve import RigSolution

__all__ = ["Completion", "complete_mirror_joints", "complete_rig_joints", "anchor_gate",
           "smooth_tracks", "head_prior", "head_level", "HEAD_LANDMARKS", "HEAD_PRIOR_SIGMA", "BODY_GATE_MADS",
           "BODY_GATE_FLOOR", "BODY_GATE_ANCHORS", "BODY_GATE_MIN_FRAMES"]

#: Body gate: robust z-score (in scaled MADs) beyond which a completed joint's
#: distance to its anchor counts as an error along the epipolar line.
BODY_GATE_MADS = 4.0
#: ... but never tighter than this fraction of the median anchor distance (a
#: joint measured very consistently would otherwise lose frames to the noise).
BODY_GATE_FLOOR = 0.10
#: Known joints each completed joint is anchored to (its nearest ones).
BODY_GATE_ANCHORS = 2
#: Fewest frames a joint needs for its anchor distance's median to be trusted; with
#: fewer, its completed points are kept on the reprojection gate alone.
BODY_GATE_MIN_FRAMES = 10


#: The face keypoints' landmark heights (:data:`~mirrorgraph.anthropometry.LANDMARK_HEIGHT`
#: names) that place them on the trunk's axis for :func:`head_prior`: the eyes at the eyes,
#: the ears (the tragion, level with them) too, the nose halfway between the eyes and the
#: chin, the head top at the vertex. ``(landmark, weight)`` pairs averaged.
HEAD_LANDMARKS: dict[str, tuple[tuple[str, float], ...]] = {
    "nose": (("eye", 0.5), ("chin", 0.5)),
    "left_eye": (("eye", 1.0),), "right_eye": (("eye", 1.0),),
    "left_ear": (("eye", 1.0),), "right_ear": (("eye", 1.0),),
    "head_top": (("vertex", 1.0),),
}


def _head_prior_sigma() -> float:
    """The per-axis std of a face keypoint about its place on the trunk's axis, a fraction
    of the height: the head turned on the neck (the cervical spine's flexion, extension
    and lateral bending, about 45 deg each in adults: AAOS, *Joint Motion: Method of
    Measuring and Recording*, 1965) at the lever from the shoulders to the eyes
    (:data:`~mirrorgraph.anthropometry.LANDMARK_HEIGHT`, 0.118 H) moves it
    ``0.118 sin 45 = 0.083 H``; the face keypoints lie up to about 0.065 H off the
    neck's axis (half an adult's head length of ~0.11 H, the nose in front of it). The
    two as one isotropic Gaussian of the same RMS length: ``sqrt(0.083^2 + 0.065^2) /
    sqrt(3)`` per axis, 0.061 H (10.7 cm for a 1.75 m adult)."""
    from .anthropometry import LANDMARK_HEIGHT

    lever = LANDMARK_HEIGHT["eye"] - LANDMARK_HEIGHT["shoulder"]
    turn = lever * math.sin(math.radians(45.0))
    return math.hypot(turn, 0.065) / math.sqrt(3.0)


#: :func:`_head_prior_sigma`: 0.061 (a fraction of the height, per axis).
HEAD_PRIOR_SIGMA = _head_prior_sigma()


def head_level(name: str) -> float:
    """A face keypoint's height over the shoulders, a fraction of the stature (Winter's
    landmarks, :data:`HEAD_LANDMARKS`); ``name`` without a person's tag."""
    from .anthropometry import LANDMARK_HEIGHT

    return (sum(w * LANDMARK_HEIGHT[lm] for lm, w in HEAD_LANDMARKS[name])
            - LANDMARK_HEIGHT["shoulder"])


def head_prior(points: np.ndarray, known: np.ndarray, names: list[str] | tuple[str, ...],
               height: float, cov: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray] | None:
    """A prior of each face keypoint from the trunk it sits on: where the body puts it.

    The nose, eyes, ears and head top lie above the shoulders along the trunk's axis
    ``u = (mid-shoulder - mid-hip) / |...|`` at their landmark's height over the
    shoulders' (Winter's, :data:`HEAD_LANDMARKS`): ``mean = mid-shoulder + (h_k -
    h_shoulder) H u``, with an isotropic spread of :data:`HEAD_PRIOR_SIGMA` ``H`` per axis
    (the head turned on the neck, the face off its axis) plus the mid-shoulder's own
    covariance (``cov``, the graph's joints, its two shoulders taken independent). Where
    two rays meet at a small angle and the detector's bias differs between the views,
    the face's triangulated depth can be tenths of a metre off; this prior holds it to
    the body. Frames without both shoulders and both hips known give none.

    Args:
        points: ``(T, J, 3)`` joints (the graph's where ``known``).
        known: ``(T, J)`` bool, the graph's joints.
        names: ``(J,)`` joint names (a person's tag, ``"@1"``, kept with its own trunk).
        height: the subject's height ``H`` in the unit of ``points``.
        cov: ``(T, J, 3, 3)`` the graph's joints' covariances, or ``None``.

    Returns:
        ``(mean, info)``, ``(T, J, 3)`` and ``(T, J, 3, 3)``, NaN where no prior; ``None``
        where the layout has no face keypoint, or no shoulders and hips.
    """
    from .skeletons import person_of

    if not (math.isfinite(height) and height > 0):
        return None
    T, J = np.asarray(known).shape
    index = {n: i for i, n in enumerate(names)}
    mean = np.full((T, J, 3), np.nan)
    info = np.full((T, J, 3, 3), np.nan)
    found = False
    for j, name in enumerate(names):
        tag = person_of(name)
        base = name[:len(name) - len(tag)]
        if base not in HEAD_LANDMARKS:
            continue
        trunk = [index.get(f"{s}_{p}{tag}") for p in ("shoulder", "hip") for s in ("left", "right")]
        if any(k is None for k in trunk):
            continue
        ls, rs, lh, rh = trunk
        ok = np.asarray(known)[:, trunk].all(1)
        if not ok.any():
            continue
        found = True
        ms = 0.5 * (points[ok, ls] + points[ok, rs])
        axis = ms - 0.5 * (points[ok, lh] + points[ok, rh])
        with np.errstate(invalid="ignore", divide="ignore"):
            u = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
        m = ms + head_level(base) * height * u
        C = np.broadcast_to((HEAD_PRIOR_SIGMA * height) ** 2 * np.eye(3), (len(m), 3, 3)).copy()
        if cov is not None:
            Cs = 0.25 * (np.asarray(cov)[ok, ls] + np.asarray(cov)[ok, rs])
            good = np.isfinite(Cs).all((-2, -1))
            C[good] += Cs[good]
        fine = np.isfinite(m).all(-1)
        rows = np.flatnonzero(ok)[fine]
        mean[rows, j] = m[fine]
        info[rows, j] = np.linalg.inv(C[fine])
    return (mean, info) if found else None


@dataclass
class Completion:
    """The refined joints, completed.

    Attributes:
        joints3d: ``(T, J, 3)`` real camera frame, unit of the mirror distance given;
            the graph's joints unchanged, NaN where neither estimated nor completed.
        valid: ``(T, J)`` bool mask of ``joints3d``.
        completed: ``(T, J)`` bool, the entries filled here.
        candidates: entries seen in both views that the graph did not estimate.
        rejected_reprojection, rejected_body: candidates dropped by each gate.
        cov: ``(T, J, 3, 3)`` the completed entries' covariance (their two rays at the
            pixel noise and the plane's uncertainty through the triangulation,
            :func:`mirrorgraph.graph.joints_uncertainty.triangulated_covariance`), NaN
            elsewhere; ``None`` where no pixel noise was given.
    """

    joints3d: np.ndarray
    valid: np.ndarray
    completed: np.ndarray
    candidates: int = 0
    rejected_reprojection: int = 0
    rejected_body: int = 0
    cov: np.ndarray | None = None

    @property
    def count(self) -> int:
        """Entries completed."""
        return int(np.count_nonzero(self.completed))

    def to_dict(self) -> dict:
        """The record in ``calibration.json`` (``refinement.completion``)."""
        return {"joints_completed": self.count, "candidates": int(self.candidates),
                "rejected_reprojection": int(self.rejected_reprojection),
                "rejected_body": int(self.rejected_body),
                "method": "triangulated with the solved mirror (geometry.triangulate_mirror), "
                          "reprojection and body-distance gates"}


def _seen(kp: np.ndarray, min_confidence: float) -> np.ndarray:
    """``(T, J)`` bool: finite coordinates with confidence at least ``min_confidence``."""
    return (kp[..., 2] >= min_confidence) & (kp[..., 2] > 0) & np.isfinite(kp[..., :2]).all(-1)


def anchor_gate(points: np.ndarray, known: np.ndarray, new: np.ndarray, *,
                mads: float = BODY_GATE_MADS, floor: float = BODY_GATE_FLOOR,
                anchors: int = BODY_GATE_ANCHORS,
                min_frames: int = BODY_GATE_MIN_FRAMES) -> np.ndarray:
    """Drop completed points whose distances to the body are unlike the joint's usual ones.

    For every joint ``j`` with new points, its anchors are the ``anchors`` known joints
    ``a`` with the smallest median distance ``m_a`` of ``|X_j - X_a|`` over the frames
    holding both (e.g. a toe's ankle and knee). A new point is kept where, for every
    anchor known in its frame, ``| |X_j - X_a| - m_a | <= max(mads * 1.4826 MAD_a,
    floor * m_a)``. Two anchors catch an error that keeps the distance to one of them.
    Anchors seen with ``j`` in fewer than ``min_frames`` frames are not used; a joint
    without any keeps its points.

    Args:
        points: ``(T, J, 3)`` joints, any unit (NaN where unknown).
        known: ``(T, J)`` bool, the trusted joints (the graph's).
        new: ``(T, J)`` bool, the points to test (disjoint from ``known``).
        mads, floor, anchors, min_frames: see above.

    Returns:
        ``(T, J)`` bool: the entries of ``new`` that pass.
    """
    keep = np.array(new, dtype=bool, copy=True)
    known = np.asarray(known, dtype=bool)
    cols = np.flatnonzero(known.any(0))
    if cols.size == 0:
        return keep
    for j in np.flatnonzero(keep.any(0)):
        both = keep[:, j, None] & known[:, cols]                        # (T, A)
        enough = both.sum(0) >= min_frames
        if not enough.any():
            continue
        dist = np.linalg.norm(points[:, j, None] - points[:, cols], axis=-1)    # (T, A)
        dist = np.where(both, dist, np.nan)
        with _warnings.catch_warnings():
            _warnings.simplefilter("ignore", RuntimeWarning)             # all-NaN columns
            med = np.nanmedian(dist, axis=0)                              # (A,)
            med[~enough] = np.inf
            near = np.argsort(med, kind="stable")[:anchors]
            near = near[np.isfinite(med[near])]
            m = med[near]                                                 # (a,)
            dev = np.abs(dist[:, near] - m)                               # (T, a)
            mad = 1.4826 * np.nanmedian(dev, axis=0)
        tol = np.maximum(mads * mad, floor * m)
        bad = (both[:, near] & ~(dev <= tol)).any(1)
        keep[bad, j] = False
    return keep


def complete_mirror_joints(paired: PairedKeypoints, K: np.ndarray, normal: np.ndarray,
                           distance: float, joints3d: np.ndarray, valid: np.ndarray, *,
                           joints: np.ndarray, min_confidence: float, threshold_px: float,
                           pixel_sigma: float | None = None,
                           plane_cov: np.ndarray | None = None,
                           body_gauge: bool = False,
                           smoothness: tuple[float, int] | None = None,
                           head: tuple[list[str], float, np.ndarray | None] | None = None
                           ) -> Completion:
    """Triangulate, with the solved mirror, the keypoints outside the graph's joint set.

    Args:
        paired: person and reflection ``(T, J, 3)`` (undistorted pixels, the reflection
            in the real joints' labels).
        K: ``(3, 3)`` intrinsics.
        normal: ``(3,)`` unit mirror normal, real camera frame, away from the camera.
        distance: mirror distance ``d`` (the unit of ``joints3d``: metres with a subject
            height, else 1).
        joints3d: ``(T, J, 3)`` the graph's joints (NaN where not estimated).
        valid: ``(T, J)`` bool, where the graph estimated a joint.
        joints: ``(k,)`` the graph's joint set: these are not completed (the graph's
            rejections stand).
        min_confidence: both detections need at least this confidence.
        threshold_px: reprojection gate, pixels in each view.
        pixel_sigma: the keypoints' noise, px: with it, each completed point's
            covariance (:attr:`Completion.cov`).
        plane_cov: ``(3, 3)`` the plane's covariance in GTSAM's tangent of
            :class:`gtsam.OrientedPlane3` (normal directions, then the distance, the
            distance in the unit of ``joints3d``); ``None``: the rays' share alone.
        body_gauge: the scale is the subject's (its stature on the joints takes back a
            change of the body's size, which the plane's share then leaves out).
        smoothness: ``(sigma, max_gap)``, with ``pixel_sigma``: each joint's completed
            points smoothed over time with their rays' information
            (:func:`smooth_tracks`; ``sigma`` in the unit of ``joints3d`` per frame^2),
            as the joints pass smooths the graph's joints; ``None``: each frame its
            own triangulation.
        head: ``(names, height, cov)``, with ``pixel_sigma``: the face keypoints held to
            the trunk they sit on (:func:`head_prior`: the joint names, the subject's
            height in the unit of ``joints3d``, the graph's joints' covariances or
            ``None``), fused with their rays (and smoothed with ``smoothness``).

    Returns:
        :class:`Completion`.
    """
    T, J = paired.real.shape[:2]
    points = np.array(joints3d, dtype=float, copy=True)
    known = np.array(valid, dtype=bool, copy=True)
    want = _seen(paired.real, min_confidence) & _seen(paired.mirror, min_confidence) & ~known
    want[:, np.asarray(joints, dtype=int)] = False
    t, j = np.nonzero(want)
    out = Completion(points, known, np.zeros((T, J), dtype=bool), candidates=int(t.size))
    if t.size == 0:
        return out
    n = np.asarray(normal, dtype=float).reshape(3)
    u, um = paired.real[t, j, :2], paired.mirror[t, j, :2]
    X = geo.triangulate_mirror(K, n, float(distance), u, um)
    S = geo.reflect_points(X, n, float(distance))
    with np.errstate(invalid="ignore", divide="ignore"):
        ok = (np.isfinite(X).all(-1) & (X[:, 2] > 0) & (X @ n < distance) & (S[:, 2] > 0))
        ok &= np.linalg.norm(geo.project(K, X) - u, axis=-1) <= threshold_px
        ok &= np.linalg.norm(geo.project(K, S) - um, axis=-1) <= threshold_px
    out.rejected_reprojection = int(np.count_nonzero(~ok))
    points[t[ok], j[ok]] = X[ok]
    new = np.zeros((T, J), dtype=bool)
    new[t[ok], j[ok]] = True
    keep = anchor_gate(points, known, new)
    out.rejected_body = int(np.count_nonzero(new & ~keep))
    points[new & ~keep] = np.nan
    out.joints3d, out.valid, out.completed = points, known | keep, keep
    if pixel_sigma is not None:
        from .graph.joints_uncertainty import (mirror_plane_projections,
                                               rays_time_correlation_factor,
                                               triangulated_covariance)

        tk, jk = np.nonzero(keep)
        projections = mirror_plane_projections(K, n, float(distance))
        pixels = [paired.real[tk, jk, :2], paired.mirror[tk, jk, :2]]
        masks = [np.ones(len(tk), bool)] * 2
        rays = triangulated_covariance(projections, None, points[tk, jk], pixels, masks,
                                       float(pixel_sigma))
        # the plane's share: common to a track's frames, the smoothing averages the rays'
        # noise, not it
        shared = (np.zeros_like(rays) if plane_cov is None else triangulated_covariance(
            projections, np.asarray(plane_cov, float), points[tk, jk], pixels, masks,
            float(pixel_sigma), frames=tk if body_gauge else None, rays=False))
        cov = np.full((T, J, 3, 3), np.nan)
        cov[tk, jk] = rays + shared
        prior = None if head is None else head_prior(points, known, head[0], float(head[1]),
                                                      head[2])
        good = np.isfinite(rays).all((1, 2))
        # the detector's bias, which the frames share (smoothing averages noise, not it):
        # each joint's mean residual in each view across its frames
        bias = _bias_covariance(rays, jk, good, K, n, float(distance), points[tk, jk],
                                pixels, float(pixel_sigma))
        if smoothness is not None and len(tk):
            info = np.zeros((T, J, 3, 3))
            info[tk[good], jk[good]] = np.linalg.inv(rays[good])
            track = np.zeros((T, J), dtype=bool)
            track[tk[good], jk[good]] = True
            measured = points[tk, jk]
            points, smoothed = smooth_tracks(points, info, track, paired.frame_ids,
                                             float(smoothness[0]), int(smoothness[1]))
            # the detector's noise that persists from frame to frame, which the smoothing
            # does not average out (the rays' own residuals' autocorrelation)
            frame = np.full((T, J, 3, 3), np.nan)
            frame[tk[good], jk[good]] = rays[good]
            widen = rays_time_correlation_factor(projections(np.zeros(0)), measured,
                                                 pixels, tk, jk, frame, smoothed)
            own = smoothed[tk, jk] * widen[tk, jk][:, None, None] + bias
        else:
            own = rays + bias
        own[~good] = np.nan
        if prior is not None:
            own = _fuse_prior(points, own, tk, jk, good, prior)
        cov[tk[good], jk[good]] = own[good] + shared[good]
        out.joints3d = points
        out.cov = cov
    return out


def _bias_covariance(rays: np.ndarray, jk: np.ndarray, good: np.ndarray, K: np.ndarray,
                     normal: np.ndarray, distance: float, X: np.ndarray, pixels: list,
                     pixel_sigma: float) -> np.ndarray:
    """``(n, 3, 3)`` the detector's per-joint bias through each completed point's two rays.

    A bias that the frames share shows in the mean of a joint's reprojection residuals
    ``m_v`` in each view ``v`` across the epipolar line (the triangulation takes the rest
    as depth); along it, it is invisible and taken as large as across, as for the graph's
    joints (:func:`mirrorgraph.graph.joints_uncertainty.graph_joints_covariance`): a
    per-coordinate variance ``b^2 = mean_v 2 |m_v|^2`` (px^2) through the rays' response,
    ``(b / pixel_sigma)^2`` times their covariance ``rays``. Under iid noise ``|m_v|^2`` is
    ``~2 sigma^2 / frames``.

    Args:
        rays: ``(n, 3, 3)`` the points' two-ray covariances at ``pixel_sigma``.
        jk: ``(n,)`` each point's joint; good: ``(n,)`` bool, the points with a covariance.
        K, normal, distance: the camera and the mirror; X: ``(n, 3)`` the points.
        pixels: the ``(n, 2)`` observations in the real view and in the mirror.
        pixel_sigma: the keypoints' noise, px.
    """
    S = geo.reflect_points(X, normal, distance)
    res = [geo.project(K, X) - pixels[0], geo.project(K, S) - pixels[1]]
    out = np.zeros_like(rays)
    var = np.zeros(len(jk))
    for j in np.unique(jk[good]):
        sel = good & (jk == j)
        b2 = np.mean([2.0 * np.sum(np.nanmean(r[sel], axis=0) ** 2) for r in res])
        var[sel] = b2 if np.isfinite(b2) else 0.0
    out[good] = (var[good] / float(pixel_sigma) ** 2)[:, None, None] * rays[good]
    return out


def _fuse_prior(points: np.ndarray, own: np.ndarray, tk: np.ndarray, jk: np.ndarray,
                good: np.ndarray, prior: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Each completed point (``points[tk, jk]``, covariance ``own``) fused with its prior
    ``(mean, info)`` (:func:`head_prior`) where it has one, in place: ``C = (own^-1 +
    P)^-1``, ``x = C (own^-1 x + P m)``. Returns the covariances."""
    m, P = prior[0][tk, jk], prior[1][tk, jk]
    has = good & np.isfinite(m).all(-1) & np.isfinite(P).all((-2, -1))
    if not has.any():
        return own
    L = np.linalg.inv(own[has])
    post = np.linalg.inv(L + P[has])
    x = np.einsum("nij,nj->ni", post, np.einsum("nij,nj->ni", L, points[tk[has], jk[has]])
                  + np.einsum("nij,nj->ni", P[has], m[has]))
    points[tk[has], jk[has]] = x
    own = own.copy()
    own[has] = post
    return own


def smooth_tracks(points: np.ndarray, info: np.ndarray, mask: np.ndarray,
                  frame_ids: np.ndarray, sigma: float, max_gap: int, *,
                  newest_only: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Each joint's track of measured points smoothed as the joints pass smooths the
    graph's joints.

    The maximum a posteriori points of the measurements ``x_t ~ N(X_t, info_t^-1)``
    under the second-difference prior of
    :class:`~mirrorgraph.factors.smoothness.SmoothnessFactor` (``sigma`` per frame^2, no
    triple across a step over ``max_gap``): linear, one block-banded solve over every
    joint at once (a Rauch-Tung-Striebel smoother's answer; Sarkka, *Bayesian Filtering
    and Smoothing*, 2013, ch. 8), with the exact marginal covariance of each point
    (:func:`~mirrorgraph.graph.joints_uncertainty.chain_marginals`). Where two rays meet
    at a small angle the measurement is weak along them, and the neighbouring frames
    decide the depth.

    Args:
        points: ``(T, J, 3)`` the measured points (read where ``mask``).
        info: ``(T, J, 3, 3)`` their information (inverse covariance, read where ``mask``).
        mask: ``(T, J)`` bool, the entries to smooth.
        frame_ids: ``(T,)`` increasing frame numbers.
        sigma: the acceleration's std, the points' unit per frame^2.
        max_gap: the longest frame step a triple spans.
        newest_only: the covariance of each track's newest point alone (a filter's:
            cheaper), NaN at the others.

    Returns:
        ``(T, J, 3)`` the points, smoothed where ``mask``, and ``(T, J, 3, 3)`` their
        covariance (NaN outside ``mask``).
    """
    from .factors.smoothness import SmoothnessFactor

    points = np.array(points, dtype=float, copy=True)
    cov = np.full(points.shape + (3,), np.nan)
    fid = np.asarray(frame_ids, dtype=np.int64)
    jj, tt = np.nonzero(np.asarray(mask, bool).T)          # each joint's frames, in order
    if not len(jj):
        return points, cov
    joints, chain, size = np.unique(jj, return_inverse=True, return_counts=True)
    B, N = len(joints), int(size.max())
    pos = np.arange(len(jj)) - np.concatenate([[0], np.cumsum(size)[:-1]])[chain]
    # the chains side by side, (B, N): padded past each chain's end with unit blocks and
    # frame numbers no triple spans
    inside = np.arange(N)[None, :] < size[:, None]
    frames = np.zeros((B, N), dtype=np.int64)
    diag = np.broadcast_to(np.eye(3), (B, N, 3, 3)).copy()
    rhs = np.zeros((B, N, 3))
    L = np.nan_to_num(info[tt, jj])
    frames[chain, pos] = fid[tt]
    diag[chain, pos] = L
    rhs[chain, pos] = np.einsum("nij,nj->ni", L, np.nan_to_num(points[tt, jj]))
    off1, off2 = np.zeros((B, N, 3, 3)), np.zeros((B, N, 3, 3))
    if N >= 3:
        step = np.diff(frames, axis=1)
        ok = (inside[:, 2:] & (step[:, :-1] >= 1) & (step[:, :-1] <= max_gap)
              & (step[:, 1:] >= 1) & (step[:, 1:] <= max_gap))
        trip = np.stack([frames[:, :-2], frames[:, 1:-1], frames[:, 2:]], -1)
        with np.errstate(divide="ignore", invalid="ignore"):
            c = SmoothnessFactor.coefficients(trip) / float(sigma)       # (B, N-2, 3)
        c = np.where(ok[..., None], c, 0.0)
        I3 = np.eye(3)
        for k in range(3):
            diag[:, k:N - 2 + k] += (c[..., k] ** 2)[..., None, None] * I3
        off1[:, :N - 2] += (c[..., 0] * c[..., 1])[..., None, None] * I3
        off1[:, 1:N - 1] += (c[..., 1] * c[..., 2])[..., None, None] * I3
        off2[:, :N - 2] += (c[..., 0] * c[..., 2])[..., None, None] * I3
    if newest_only and 3 * N <= DENSE_CHAIN:
        x, marg = _dense_newest(diag, off1, off2, rhs, size - 1)
        last = pos == size[chain] - 1
        points[tt, jj] = x[chain, pos]
        cov[tt[last], jj[last]] = marg[chain[last]]
        return points, cov
    if 3 * N <= DENSE_CHAIN:
        x, marg = _dense_chain(diag, off1, off2, rhs)
    else:
        x, marg = _sparse_chain(diag, off1, off2, rhs)
    points[tt, jj] = x[chain, pos]
    cov[tt, jj] = marg[chain, pos]
    return points, cov


#: Chains of up to this many unknowns are solved and inverted dense (a live window),
#: longer ones by cyclic reduction (a whole video).
DENSE_CHAIN = 240


def _band(diag: np.ndarray, off1: np.ndarray, off2: np.ndarray) -> np.ndarray:
    """``(B, 3N, 3N)`` the dense symmetric matrices of block bands ``(B, N, 3, 3)``."""
    B, N = diag.shape[:2]
    H = np.zeros((B, N, 3, N, 3))
    i = np.arange(N)
    H[:, i, :, i, :] = np.moveaxis(diag, 1, 0)
    H[:, i[:-1], :, i[:-1] + 1, :] = np.moveaxis(off1[:, :-1], 1, 0)
    H[:, i[:-1] + 1, :, i[:-1], :] = np.moveaxis(np.swapaxes(off1[:, :-1], -1, -2), 1, 0)
    if N > 2:
        H[:, i[:-2], :, i[:-2] + 2, :] = np.moveaxis(off2[:, :-2], 1, 0)
        H[:, i[:-2] + 2, :, i[:-2], :] = np.moveaxis(np.swapaxes(off2[:, :-2], -1, -2), 1, 0)
    return H.reshape(B, 3 * N, 3 * N)


def _dense_chain(diag, off1, off2, rhs) -> tuple[np.ndarray, np.ndarray]:
    """Mean ``(B, N, 3)`` and diagonal blocks of the inverse ``(B, N, 3, 3)``, dense."""
    B, N = diag.shape[:2]
    Hinv = np.linalg.inv(_band(diag, off1, off2))
    x = np.einsum("bij,bj->bi", Hinv, rhs.reshape(B, 3 * N)).reshape(B, N, 3)
    blocks = Hinv.reshape(B, N, 3, N, 3)[:, np.arange(N), :, np.arange(N), :]
    return x, np.moveaxis(blocks, 0, 1)


def _dense_newest(diag, off1, off2, rhs, last: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean ``(B, N, 3)`` and the ``(B, 3, 3)`` block of the inverse at each chain's
    position ``last``, by one dense solve with four right-hand sides."""
    B, N = diag.shape[:2]
    E = np.zeros((B, N, 3, 3))
    E[np.arange(B), last] = np.eye(3)
    R = np.concatenate([rhs.reshape(B, 3 * N, 1), E.reshape(B, 3 * N, 3)], axis=-1)
    sol = np.linalg.solve(_band(diag, off1, off2), R)
    cols = sol[..., 1:].reshape(B, N, 3, 3)
    return sol[..., 0].reshape(B, N, 3), cols[np.arange(B), last]


def _sparse_chain(diag, off1, off2, rhs) -> tuple[np.ndarray, np.ndarray]:
    """Mean and diagonal blocks of the inverse, by cyclic reduction along every chain at
    once (:func:`~mirrorgraph.graph.joints_uncertainty.chain_marginals`)."""
    from .graph.joints_uncertainty import chain_marginals

    return chain_marginals(diag, off1, off2, rhs=rhs)


# --------------------------------------------------------------------------- rigs
def _rig_views(obs: "RigObservations", sol: "RigSolution"
               ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Projection matrices ``(3, 4)`` and keypoints ``(T, J, 3)`` of every real and
    mirror view of the solved rig."""
    planes = dict(zip(sol.mirror_names, sol.planes))
    projections, keypoints = [], []
    for cam, pose in zip(obs.cameras, sol.poses):
        K = cam.intrinsics.K
        projections.append(geo.camera_projection(K, pose))
        keypoints.append(cam.real)
        for m, refl in cam.reflections.items():
            if m in planes:
                projections.append(geo.mirror_projection(K, pose, *planes[m]))
                keypoints.append(refl)
    return projections, keypoints


def _view_residuals(P: np.ndarray, X: np.ndarray, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel distance ``(N,)`` of ``uv`` ``(N, 2)`` to the projection of ``X`` ``(N, 3)``,
    and whether ``X`` is in front of the view."""
    h = np.nan_to_num(X) @ P[:, :3].T + P[:, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        dist = np.linalg.norm(h[:, :2] / h[:, 2:3] - uv, axis=-1)
    return dist, h[:, 2] > 0


def complete_rig_joints(obs: "RigObservations", sol: "RigSolution", threshold_px: float
                        ) -> "RigSolution":
    """Fill the joints the solution lacks by triangulating them with its rig.

    Args:
        obs: the rig's sorted observations (frames = ``sol``'s frames).
        sol: the solved rig; ``sol.points`` ``(T, J, 3)`` world frame, ``sol.used``
            ``(T, J)``.
        threshold_px: observations farther than this from the first triangulation
            (pixels) are dropped before the second.

    Returns:
        ``sol`` with ``points`` and ``used`` filled where the graph had no joint and
        two views or more (after rejection) observe it, and their covariance in
        ``joints_cov`` (their rays at the solve's pixel noise,
        :func:`~mirrorgraph.geometry.triangulation_covariance`; the rig's own
        uncertainty not added); the graph's joints unchanged.
    """
    missing = ~np.asarray(sol.used, bool)                                  # (T, J)
    if not missing.any():
        return sol
    from .initial.rig import observed

    projections, keypoints = _rig_views(obs, sol)
    masks = [observed(k) & missing for k in keypoints]
    pixels = [k[..., :2] for k in keypoints]
    X, ok = geo.triangulate(projections, pixels, masks)
    if not ok.any():
        return sol
    kept = []
    for P, uv, m in zip(projections, pixels, masks):
        dist, ahead = _view_residuals(P, X[ok], uv[ok])
        keep = m.copy()
        keep[ok] &= (dist <= threshold_px) & ahead
        kept.append(keep)
    X, ok = geo.triangulate(projections, pixels, kept)
    points = np.array(sol.points, dtype=float, copy=True)
    used = np.array(sol.used, dtype=bool, copy=True)
    points[ok] = X[ok]
    used |= ok
    cov = sol.joints_cov
    if cov is not None:
        # their rays' share at the solve's noise (the rig's own uncertainty not added)
        cov = np.array(cov, dtype=float, copy=True)
        noise = sol.noise_px if np.isfinite(sol.noise_px) else threshold_px / 3.0
        cov[ok] = geo.triangulation_covariance(projections, X[ok], [k[ok] for k in kept],
                                               noise)
    return replace(sol, points=points, used=used, joints_cov=cov)
