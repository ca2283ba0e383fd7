"""The metric scale of a run from the subject's measured stature: one mirror's refinement
(:func:`scale_by_stature`) and a rig's solution (:func:`scale_rig_by_stature`) alike.

The graph's gauge holds the limb bones' sum at Winter's fractions of the subject's
height (:mod:`mirrorgraph.factors.gauge`), so the subject's own limb proportions
(a few percent off the population's) go straight into ``d`` and every length.
Afterwards the solution is rescaled so that the stature measured on its joints
(:func:`mirrorgraph.stature.estimate_stature`: ankle to eyes or head top, only the
feet and the top of the head from population figures) equals the given height. A
pure change of scale: reprojections, the mirror's normal and the body priors'
ratios are unchanged, so it is the solution the graph would reach under that gauge.

The chain needs the eyes (or the head top), which the calibration joints (the
limbs) do not include: they are triangulated here from the person and the
reflection with the refined mirror (:func:`mirrorgraph.geometry.triangulate_mirror`).

The metric distance is then ``D = H d / S(n, d)`` with ``S`` the stature measured on joints
triangulated with the mirror ``(n, d)``; triangulation scales with ``d``, so
``D = H / S(n, 1)``: whatever gauge held the graph's scale, only the mirror's normal and
the stature's measurement move it. Its relative std (:func:`distance_rel_parts`) holds the
normal's covariance carried through ``d ln S / d n`` (:func:`normal_scale_rel_std`: a
subject far beyond the mirror's foot point turns a small tilt into a scale, 2.7 % per
0.01 rad with the subject at 2.2 times the mirror's distance), the stature's sampling std,
the given height's prior and the measurement's own spread
(:func:`mirrorgraph.stature.measurement_rel_std`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..anthropometry import KEYPOINT_OFFSET
from ..errors import InputError
from ..geometry import triangulate_mirror
from ..keypoints import PairedKeypoints
from ..stature import (LIMB_CHOSEN, StatureEstimate, estimate_stature, measurement_rel_std,
                       stature_joints, stature_rescale, with_height_sigma)
from ..graph.options import GaugeOptions
from ..graph.result import RefinementResult
from ..rigs.identities import groups_by_size

__all__ = ["scale_by_stature", "scale_rig_by_stature", "limbs_stature", "subject_frames",
           "normal_scale_rel_std", "distance_rel_parts", "NORMAL_STEP", "NORMAL_FRAMES"]

#: The normal's step (radians) of the central differences of ``ln S`` in
#: :func:`normal_scale_rel_std`: the stature is a sum of medians, piecewise constant
#: under a step of 1e-4 rad on a 1000-frame scene (the gradient 2x off), stable within
#: 10 % from 1e-3 to 2e-2 rad; a tenth of a degree is within a typical normal's std.
NORMAL_STEP = 3e-3

#: Most frames :func:`normal_scale_rel_std` triangulates (spread evenly over the video):
#: the medians' gradient is settled by then, and a long video costs no more.
NORMAL_FRAMES = 2000


def limbs_stature(points: np.ndarray, valid: np.ndarray, skeleton,
                  keypoint_offset: float = KEYPOINT_OFFSET) -> StatureEstimate | None:
    """The stature measured on a result whose scale the limbs made (``scale_from =
    "limbs"``), left at that scale: the measurement's spreads (the legs apart, the
    segments' disagreement) for the scale's std (:func:`mirrorgraph.stature.
    measurement_rel_std`, which the estimate's ``scale_from = "limbs"`` points at the
    limbs' own prior, at ``keypoint_offset``, the keypoints' placement as a fraction of
    the height); ``None`` where the joints do not span ankle to eyes."""
    est = estimate_stature(points, valid, skeleton, keypoint_offset=keypoint_offset)
    return None if est is None else replace(est, scale_from="limbs")

def _with_head(res: RefinementResult, paired: PairedKeypoints, K: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """``(T, J, 3)`` joints and ``(T, J)`` mask: the refinement's, plus the stature's joints
    it did not estimate (the eyes or head top) triangulated from both views (in front of
    the camera and the mirror). Only those joints: a long video's every joint would be
    hundreds of MB of triangulation."""
    points = np.array(res.joints3d, dtype=float, copy=True)
    valid = np.array(res.valid, dtype=bool, copy=True)
    chain = stature_joints(paired.skeleton)
    if chain is None:
        return points, valid
    missing = paired.valid()[:, chain] & ~valid[:, chain]                    # (T, k)
    if missing.any():
        t, k = np.nonzero(missing)
        j = chain[k]
        X = triangulate_mirror(K, res.normal, res.distance, paired.real[t, j, :2],
                               paired.mirror[t, j, :2])
        with np.errstate(invalid="ignore"):
            ok = (np.isfinite(X).all(-1) & (X[:, 2] > 0)
                  & (X @ np.asarray(res.normal, float) < res.distance))
        points[t[ok], j[ok]] = X[ok]
        valid[t[ok], j[ok]] = True
    return points, valid


def _tangent_basis(normal: np.ndarray) -> np.ndarray:
    """``(3, 2)`` orthonormal basis of the plane perpendicular to ``normal``."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    a = np.eye(3)[int(np.argmin(np.abs(n)))]
    b1 = np.cross(n, a)
    b1 /= np.linalg.norm(b1)
    return np.stack([b1, np.cross(n, b1)], axis=1)


def normal_scale_rel_std(paired: PairedKeypoints, K: np.ndarray, normal: np.ndarray,
                         distance: float, valid: np.ndarray, normal_cov: np.ndarray,
                         keypoint_offset: float = KEYPOINT_OFFSET) -> float:
    """The metric distance's relative std from the mirror normal's uncertainty, through
    the stature.

    With the scale from the stature, the metric distance is ``D = H / S(n, 1)``, ``S``
    the stature measured (:func:`mirrorgraph.stature.estimate_stature`) on the chain's
    joints triangulated from both views with the mirror ``(n, 1)``
    (:func:`mirrorgraph.geometry.triangulate_mirror`); a tilt ``dn`` of the normal moves
    the subject's reconstructed depth, and so ``S``, by the subject's lever arm about the
    mirror's foot point (the body far beyond it: several percent per degree). First-order
    propagation (Bishop, *Pattern Recognition and Machine Learning*, 2006, sec. 2.3.3):
    ``var ln D = g^T B^T C B g``, ``g`` the gradient of ``ln S`` over the two tangent
    coordinates ``B`` of the normal (central differences of step :data:`NORMAL_STEP`), ``C``
    the normal's covariance. The joints' error at a given mirror is the stature's sampling
    std (:attr:`~mirrorgraph.stature.StatureEstimate.sampling_rel_std`), not this.

    Args:
        paired: person and reflection keypoints (undistorted pixels).
        K: ``(3, 3)`` intrinsics.
        normal: ``(3,)`` the mirror's unit normal (camera frame).
        distance: the mirror's distance (any unit: ``S`` scales with it, ``ln S``'s
            gradient does not).
        valid: ``(T, J)`` bool, the observations to triangulate (the chain's joints the
            run used; at most :data:`NORMAL_FRAMES` frames are taken, evenly spread).
        normal_cov: ``(3, 3)`` the normal's covariance (rad^2, camera frame).
        keypoint_offset: the keypoints' placement, a fraction of the height (unused by
            the height itself; passed to the estimate).

    Returns:
        The relative std (dimensionless); 0 where the stature cannot be measured at the
        perturbed normals or the covariance is not finite.
    """
    C = np.asarray(normal_cov, float)
    chain = stature_joints(paired.skeleton)
    if chain is None or C.shape != (3, 3) or not np.all(np.isfinite(C)):
        return 0.0
    ok = np.asarray(valid, bool)[:, chain] & paired.valid()[:, chain]           # (T, k)
    rows = np.flatnonzero(ok.any(1))
    if len(rows) > NORMAL_FRAMES:
        rows = rows[np.linspace(0, len(rows) - 1, NORMAL_FRAMES).round().astype(int)]
    t, k = np.nonzero(ok[rows])
    j = chain[k]
    u, um = paired.real[rows[t], j, :2], paired.mirror[rows[t], j, :2]
    J = paired.real.shape[1]
    n0 = np.asarray(normal, float) / np.linalg.norm(normal)
    B = _tangent_basis(n0)

    def log_stature(n: np.ndarray) -> float:
        n = n / np.linalg.norm(n)
        X = triangulate_mirror(K, n, float(distance), u, um)
        with np.errstate(invalid="ignore"):
            good = (np.isfinite(X).all(-1) & (X[:, 2] > 0) & (X @ n < float(distance)))
        P = np.full((len(rows), J, 3), np.nan)
        P[t[good], j[good]] = X[good]
        mask = np.zeros((len(rows), J), bool)
        mask[t[good], j[good]] = True
        est = estimate_stature(P, mask, paired.skeleton, keypoint_offset=keypoint_offset)
        return math.log(est.height) if est is not None and est.height > 0 else float("nan")

    g = np.array([(log_stature(n0 + NORMAL_STEP * B[:, i])
                   - log_stature(n0 - NORMAL_STEP * B[:, i])) / (2.0 * NORMAL_STEP)
                  for i in range(2)])
    if not np.all(np.isfinite(g)):
        return 0.0
    var = float(g @ (B.T @ C @ B) @ g)
    return math.sqrt(max(var, 0.0))


def distance_rel_parts(normal_rel: float, stature: StatureEstimate, height_sigma: float,
                       focal_rel: float = 0.0) -> dict[str, float]:
    """The metric distance's relative std with the scale from the stature, by part.

    ``D = H / S(n, 1)`` (module docstring): the data's share is the normal's
    (``normal_rel``, :func:`normal_scale_rel_std`) and the stature's sampling std over
    its frames (:attr:`~mirrorgraph.stature.StatureEstimate.sampling_rel_std`, 0 where
    not measured) in quadrature, or an estimated focal length's relative std where larger
    (a person of known size imaged at a fixed size lies at a depth proportional to the
    focal length); the scale's share is the given height's prior (``height_sigma``,
    ``RefineOptions.height_sigma``) and the measurement's own spread
    (:func:`mirrorgraph.stature.measurement_rel_std`).

    Returns:
        ``normal``, ``sampling``, ``focal``, ``data``, ``height``, ``measurement`` and
        ``total`` (the quadrature of ``data``, ``height`` and ``measurement``), each a
        relative std (dimensionless).
    """
    sampling = float(stature.sampling_rel_std)
    sampling = sampling if math.isfinite(sampling) else 0.0
    data = max(math.hypot(float(normal_rel), sampling), float(focal_rel))
    meas = measurement_rel_std(stature)
    total = math.sqrt(data ** 2 + float(height_sigma) ** 2 + meas ** 2)
    return {"normal": float(normal_rel), "sampling": sampling, "focal": float(focal_rel),
            "data": data, "height": float(height_sigma), "measurement": meas, "total": total}


def scale_by_stature(res: RefinementResult, paired: PairedKeypoints, K: np.ndarray,
                     height: float, scale_from: str = "stature",
                     keypoint_offset: float = KEYPOINT_OFFSET,
                     height_sigma: float | None = None) -> RefinementResult:
    """Rescale a metric refinement so that the subject's measured stature is ``height``.

    Args:
        res: the refinement (``scale == "subject_height"``: metres through the gauge).
        paired: its person and reflection keypoints (undistorted pixels).
        K: ``(3, 3)`` intrinsics.
        height: the subject's standing height, metres.
        scale_from: ``"stature"``, or ``"limbs"``: the gauge's scale kept, as asked
            (``RefineOptions.scale_from``), the stature measured on it
            (:func:`limbs_stature`) and ``distance_std`` widened by the limbs' rule of
            :func:`mirrorgraph.stature.measurement_rel_std`.
        keypoint_offset: the keypoints' placement off their landmarks, a fraction of the
            height (:func:`mirrorgraph.stature.keypoint_offset_fraction` of
            ``RefineOptions.keypoint_offset``), which the std holds.
        height_sigma: the given height's relative std (``RefineOptions.height_sigma``;
            ``None``: its default), the one ``res.distance_std`` holds.

    Returns:
        ``res`` with ``distance``, ``joints3d`` and ``bone_lengths`` multiplied by
        ``height / measured stature`` (``joints_cov`` by its square, the distance's part
        of ``plane_cov`` as the distance), ``distance_std`` the metric distance's
        (:func:`distance_rel_parts` of the normal's covariance through the stature,
        :func:`normal_scale_rel_std`, the stature's sampling, the height's prior and the
        measurement's own spread; NaN where ``res.distance_std`` is: no marginals) and
        ``scale_source``/``stature`` set (the record's ``distance_rel_std``: the parts);
        unchanged but for ``scale_source`` when the stature cannot be measured.

    Raises:
        InputError: ``height`` is not a positive finite number.
    """
    h = height
    if isinstance(h, bool) or not isinstance(h, (int, float, np.floating)) or not (
            math.isfinite(h) and h > 0):
        raise InputError(f"must be a positive number of metres, got {height!r}",
                         field="subject_height")
    points, valid = _with_head(res, paired, K)
    if scale_from != "stature":
        stature = limbs_stature(points, valid, paired.skeleton, keypoint_offset)
        dstd = with_height_sigma(res.distance_std, res.distance,
                                 measurement_rel_std(stature, "limbs", keypoint_offset))
        return replace(res, distance_std=dstd, scale_source=LIMB_CHOSEN,
                       stature=None if stature is None else stature.to_dict())
    f, source, stature = stature_rescale(points, valid, paired.skeleton, height, keypoint_offset)
    if f is None:
        return replace(res, scale_source=source)
    hs = GaugeOptions().height_sigma if height_sigma is None else float(height_sigma)
    normal_rel = normal_scale_rel_std(paired, K, res.normal, res.distance, valid,
                                      res.normal_cov, keypoint_offset)
    focal_rel = float(res.focal.get("rel_std", 0.0)) if res.focal.get("estimated") else 0.0
    parts = distance_rel_parts(normal_rel, stature, hs, focal_rel)
    record = stature.to_dict()
    record["distance_rel_std"] = parts
    dstd = (parts["total"] * res.distance * f if math.isfinite(res.distance_std)
            else float("nan"))
    plane = None
    if res.plane_cov is not None:
        plane = np.array(res.plane_cov, float)
        plane[2, :] *= f
        plane[:, 2] *= f
    return replace(res, distance=res.distance * f, joints3d=res.joints3d * f,
                   joints_cov=None if res.joints_cov is None else res.joints_cov * f * f,
                   plane_cov=plane,
                   bone_lengths={b: v * f for b, v in res.bone_lengths.items()},
                   distance_std=dstd, scale_source=source, stature=record)


def subject_frames(points: np.ndarray, used: np.ndarray, skeleton, stretch: np.ndarray,
                   count: int) -> tuple[np.ndarray, int, int]:
    """The frames of the body seen longest where each stretch of frames keeps its own
    subject (snapshots far apart in time: no track crosses them, and a rig's one-person
    run takes each stretch's own, :mod:`mirrorgraph.rigs.observations`), so that one
    person's stature gives the scale, not a mix of people's.

    Each stretch's subject is measured alone (:func:`mirrorgraph.stature.
    estimate_stature` over its frames, one frame enough) and the stretches grouped by that
    stature (:func:`mirrorgraph.rigs.identities.groups_by_size`, at most ``count``
    people); the group holding the most frames is kept.

    Args:
        points: ``(T, J, 3)`` the subject's joints; used: ``(T, J)`` bool.
        skeleton: their layout.
        stretch: ``(T,)`` each frame's stretch (:func:`mirrorgraph.rigs.tracking.
            rig_segments`).
        count: the most people seen at once (the groups' most).

    Returns:
        ``(frames (T,) bool, bodies, stretches)``: the frames kept (every frame with one
        stretch, one group or no stature a stretch), the groups found and the stretches
        measured.
    """
    stretch = np.asarray(stretch)
    keep = np.ones(len(stretch), bool)
    ids = np.unique(stretch)
    if len(ids) < 2 or count < 2:
        return keep, 1, len(ids)
    sizes = np.full(len(ids), np.nan)
    for i, s in enumerate(ids):
        rows = stretch == s
        est = estimate_stature(points[rows], used[rows], skeleton, min_frames=1)
        if est is not None:
            sizes[i] = est.height
    group = groups_by_size(sizes, count)
    bodies = int(group.max()) + 1
    if bodies < 2:
        return keep, max(bodies, 1), int(np.isfinite(sizes).sum())
    frames = np.array([np.isin(stretch, ids[group == g]).sum() for g in range(bodies)])
    return np.isin(stretch, ids[group == int(frames.argmax())]), bodies, int(np.isfinite(sizes).sum())


def scale_rig_by_stature(sol, skeleton, height: float, scale_from: str = "stature",
                         stretch: np.ndarray | None = None, count: int = 1,
                         keypoint_offset: float = KEYPOINT_OFFSET):
    """A rig's solution rescaled so that the stature measured on its joints is ``height``.

    Args:
        sol (mirrorgraph.pipelines.solve.RigSolution): the solved rig, joints completed
            (``points`` ``(T, J, 3)``, ``used`` ``(T, J)``).
        skeleton: the joints' layout.
        height: the subject's height in the output unit.
        scale_from: ``"stature"``, or ``"limbs"`` (the gauge's limb proportions kept, as
            asked: ``RefineOptions.scale_from``).
        stretch: ``(T,)`` each frame's stretch of frames where each keeps its own subject
            (snapshots), with ``count`` the most people seen at once: the stature is then
            the body's seen in the most frames (:func:`subject_frames`; ``height`` is
            theirs), not a mix of the subjects'.
        keypoint_offset: the keypoints' placement off their landmarks, a fraction of the
            height, which the stature's std holds (:func:`scale_by_stature`).

    Returns:
        ``(solution, source, stature)``: the (rescaled) solution, the scale's source in
        words (:data:`mirrorgraph.stature.LIMB_PROPORTIONS` where the joints do not span
        ankle to eyes) and the stature estimate after scaling (with the limbs as asked the
        stature measured on the solution, :func:`limbs_stature`; ``None`` where the joints
        do not span ankle to eyes).
    """
    keep, bodies, measured = (subject_frames(sol.points, sol.used, skeleton, stretch, count)
                              if stretch is not None else (None, 1, 0))
    points, used = ((sol.points, sol.used) if bodies < 2
                    else (sol.points[keep], sol.used[keep]))
    if scale_from != "stature":
        return sol, LIMB_CHOSEN, limbs_stature(points, used, skeleton, keypoint_offset)
    factor, source, stature = stature_rescale(points, used, skeleton, height, keypoint_offset)
    if factor is not None and bodies > 1:
        source += (f"; the subject's {measured} stretches of frames show {bodies} bodies: "
                   f"the one of the most frames ({int(keep.sum())} of {len(keep)})")
    return (sol if factor is None else sol.scaled(factor)), source, stature

