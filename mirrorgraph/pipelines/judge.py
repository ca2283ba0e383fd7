"""Every warning about a result, computed in one place for both front ends.

A calibration is judged after it is made: too few pairs agreeing on one mirror, a
large residual, a person who hardly moves, a camera or mirror whose std exceeds
:data:`~mirrorgraph.graph.uncertainty.POORLY_DETERMINED_DEG` (with its cause in words:
the unknown intrinsic that dominates its variance, the joint pairs' disagreement, or
the geometry), a rig view whose keypoints the graph mostly rejected, cameras that
disagree about a mirror. :func:`judge_mirror` judges one mirror (the one-camera rig),
:func:`judge_rig` a rig; they share :func:`poorly_determined` and
:func:`dominant_intrinsic`.
"""

from __future__ import annotations

import warnings as _warnings
from typing import Mapping

import numpy as np

from .. import geometry as geo
from ..result.mirror import Calibration
from ..graph.uncertainty import POORLY_DETERMINED_DEG
from ..keypoints import PairedKeypoints
from ..initial.reflection_check import ReflectionCheck

__all__ = ["judge_mirror", "judge_rig", "poor_mirror_cause", "poorly_determined",
           "dominant_intrinsic", "median_ray_angle_deg", "low_parallax_warning", "motion_px"]

#: Warn when the inliers' median epipolar distance exceeds this many pixels.
SUSPICIOUS_RESIDUAL_PX = 6.0
#: Warn when fewer of the pairs agree on one mirror: a true reflection, even
#: with 30% detector outliers, keeps about 70%; a second person mistaken for
#: the reflection keeps about half (chance alignments with a far epipole).
MIN_INLIER_RATIO = 0.6
#: Warn when the person's joints move less than this (median over joints of
#: the standard deviation of their image position over time, pixels).
MIN_MOTION_PX = 3.0
#: Above this angle (deg) between two cameras' initial views of one mirror, warn.
MIRROR_SPREAD_WARN_DEG = 5.0
#: Warn when a view keeps less than this fraction of its keypoints after the graph's
#: outlier rejection (clean synthetic views keep over 99 %, with 30 % detector
#: outliers about 70 %): its keypoints do not fit the rest of the rig.
MIN_KEPT_FRACTION = 0.5


def motion_px(paired: PairedKeypoints, joints: np.ndarray, min_confidence: float) -> float:
    """Median over joints of the std of the person's image position over time, pixels."""
    xy = paired.real[:, joints, :2].copy()
    xy[~(paired.real[:, joints, 2] > min_confidence)] = np.nan
    with np.errstate(invalid="ignore"), _warnings.catch_warnings():
        _warnings.simplefilter("ignore", RuntimeWarning)      # all-NaN joints
        spread = np.nanstd(xy, axis=0)                   # (k, 2)
        return float(np.nanmedian(np.hypot(spread[:, 0], spread[:, 1])))


#: A mirror whose normal is within this angle of the optical axis is "seen square-on"
#: (the epipole near the image centre, the person in front of their reflection) ...
SQUARE_ON_DEG = 15.0
#: ... and beyond this one "edge-on" (the epipole far outside the image), in the words
#: of the warnings (:func:`poor_mirror_cause`).
EDGE_ON_DEG = 65.0
#: A joint's two rays (direct and through the mirror) meeting at a median angle under
#: this is "low parallax" in the warnings (each ray's depth error is ~1/sin of it).
LOW_PARALLAX_DEG = 20.0
#: The share of a rotation's variance (:func:`~mirrorgraph.graph.uncertainty.
#: intrinsics_contributions`) above which an unknown intrinsic is named as the cause.
DOMINANT_SHARE = 0.5


def poor_mirror_cause(uncertainty: dict, normal: np.ndarray, ray_angle_deg: float = np.nan,
                      motion_px: float = np.inf, frames: int | None = None) -> str:
    """The cause of a poorly determined mirror, in words, from what dominates its std.

    The unknown focal length or principal point where its share of the rotation's
    variance (``uncertainty["contributions"]``) is the largest and above
    :data:`DOMINANT_SHARE`; else the joint pairs' disagreement where the joint-pair
    clusters gave the figure (a detector's per-joint bias); else what the geometry
    shows: rays meeting at small angles (``ray_angle_deg``, the median angle between a
    joint's two rays), a mirror seen edge-on or square-on (the normal's angle to the
    optical axis), a person who hardly moves (``motion_px``), few frames.
    """
    top = dominant_intrinsic(uncertainty.get("contributions"))
    if top is not None:
        what = {"focal_length": "the unknown focal length", "principal_point":
                "the unknown principal point (the image centre +- the spread of real cameras)"}
        share = {k: v for k, v in uncertainty["contributions"].items() if np.isfinite(v)}
        rest = [f"{what[k].split(' (')[0]} {100 * v:.0f}%" for k, v in share.items()]
        return (f"{what[top]} dominates it ({', '.join(rest)} of its variance); "
                "give the camera's intrinsics (a calibrated camera matrix) to remove it")
    robust = uncertainty.get("robust") or {}
    if robust.get("chosen") in ("joint", "two_way", "jack_joint"):
        return ("the joint pairs disagree about the mirror (a detector placing some joints "
                "consistently off: more frames do not help; see sensitivity.leave_out.joint_pairs)")
    causes = []
    if np.isfinite(ray_angle_deg) and ray_angle_deg < LOW_PARALLAX_DEG:
        causes.append(f"low parallax (a joint's two rays meet at a median {ray_angle_deg:.0f} "
                      "deg: the person near the line from the camera to the mirror)")
    angle = float(np.degrees(np.arccos(min(abs(float(np.asarray(normal)[2])), 1.0))))
    if angle < SQUARE_ON_DEG:
        causes.append(f"a mirror seen square-on ({angle:.0f} deg off the optical axis)")
    elif angle > EDGE_ON_DEG:
        causes.append(f"a mirror seen edge-on ({angle:.0f} deg off the optical axis)")
    if motion_px < 3 * MIN_MOTION_PX:
        causes.append(f"too little motion (joints move {motion_px:.1f} px)")
    if frames is not None and frames < 100:
        causes.append(f"few frames ({frames})")
    if causes:
        return "; ".join(causes)
    return ("a mirror seen almost edge-on or square-on, too few frames or too little motion; "
            "more frames and motion help")


def median_ray_angle_deg(joints3d: np.ndarray | None, valid: np.ndarray | None,
                         normal: np.ndarray, distance: float) -> float:
    """Median of :func:`mirrorgraph.geometry.mirror_ray_angles_deg` (the angle between the
    lines of a joint's two rays, in ``[0, 90]``) over the ``(T, J, 3)`` joints ``valid``;
    NaN without joints."""
    if joints3d is None or valid is None or not np.any(valid):
        return float("nan")
    X = np.asarray(joints3d, float)[np.asarray(valid, bool)]
    return float(np.median(geo.mirror_ray_angles_deg(X, normal, distance)))


def low_parallax_warning(ray_angle_deg: float, scale_rel_std: float | None) -> str | None:
    """The warning about the 3D joints of a person near the line from the camera to the
    mirror (their rays meeting at a median angle under :data:`LOW_PARALLAX_DEG`): each
    joint's depth rests on the body (its bone lengths, the other joints, the motion)
    more than on its two rays, and with it the metric scale; ``None`` otherwise."""
    if not (np.isfinite(ray_angle_deg) and ray_angle_deg < LOW_PARALLAX_DEG):
        return None
    text = (f"low parallax: a joint's two rays meet at a median {ray_angle_deg:.0f} deg (the "
            "person near the line from the camera to the mirror): the joints' depths rest on "
            "the body's bone lengths more than on the views")
    if scale_rel_std is not None and np.isfinite(scale_rel_std) and scale_rel_std > 0:
        text += f", and the metric scale with them (std {100 * scale_rel_std:.0f}%)"
    return text + "; film from further to the side of the mirror for better depth"


def judge_mirror(calib: Calibration, inlier_residuals: np.ndarray,
           motion_px: float = np.inf, check: ReflectionCheck | None = None,
           ray_angle_deg: float = np.nan) -> None:
    """Put doubts about a single mirror's result into its warnings.

    Args:
        calib: the result (its ``warnings`` are appended to).
        inlier_residuals: ``(N,)`` the initial inliers' epipolar distances, pixels.
        motion_px: :func:`motion_px` of the person.
        check: the reflection check (:func:`mirrorgraph.initial.reflection_check.check_reflection`).
        ray_angle_deg: :func:`median_ray_angle_deg` of the refined joints.
    """
    if check is not None and check.verdict == "doubtful":
        calib.warnings.append(check.describe())
    if calib.inlier_ratio < MIN_INLIER_RATIO:
        calib.warnings.append(
            f"only {100 * calib.inlier_ratio:.0f}% of the joint/reflection pairs agree on one "
            "mirror: the 'reflection' may be a second person, or the detector poor")
    med = float(np.median(inlier_residuals)) if inlier_residuals.size else np.inf
    if med > SUSPICIOUS_RESIDUAL_PX:
        calib.warnings.append(
            f"median epipolar distance of the inliers is {med:.1f} px, far above typical "
            "detector noise: the 'reflection' may be another person or the keypoints poor")
    if calib.uncertainty.get("rotation_std_deg", 0.0) > POORLY_DETERMINED_DEG:
        calib.warnings.append(poorly_determined(
            "the mirror", calib.uncertainty["rotation_std_deg"],
            poor_mirror_cause(calib.uncertainty, calib.normal, ray_angle_deg, motion_px,
                              calib.frames_used)))
    if motion_px < MIN_MOTION_PX:
        calib.warnings.append(
            f"the person hardly moves (joints move {motion_px:.1f} px): the calibration rests "
            "on a single pose, and its errors do not average out over frames")
    e_px = geo.epipole_pixels(calib.epipole)
    if e_px is None:
        calib.warnings.append("the epipole is at infinity (mirror parallel to the optical axis)")


def dominant_intrinsic(contributions: Mapping[str, float] | None) -> str | None:
    """The unknown intrinsic (``"focal_length"``, ``"principal_point"``) whose share of a
    rotation's variance (:func:`~mirrorgraph.graph.uncertainty.intrinsics_contributions`)
    is the largest and above :data:`DOMINANT_SHARE`, else ``None``."""
    share = {k: v for k, v in (contributions or {}).items() if np.isfinite(v)}
    if not share:
        return None
    top = max(share, key=share.get)
    return top if share[top] > DOMINANT_SHARE else None


def poorly_determined(what: str, rotation_std_deg: float, cause: str,
                      marginal_std_deg: float | None = None) -> str:
    """The warning for a camera or mirror whose rotation std exceeds
    :data:`~mirrorgraph.graph.uncertainty.POORLY_DETERMINED_DEG` (degrees), with its
    cause in words (and the marginals' figure beside it where given)."""
    figures = f"rotation std {rotation_std_deg:.2f} deg"
    if marginal_std_deg is not None:
        figures += f", {marginal_std_deg:.2f} deg from the marginals alone"
    return f"{what} is poorly determined ({figures}): {cause}"


def judge_rig(cameras, mirrors, robust_parts: Mapping[str, dict], view_names, view_counts,
              view_observed, mirror_spread_deg: Mapping[str, float], failed=()) -> list[str]:
    """The warnings about a solved rig.

    Args:
        cameras: :class:`~mirrorgraph.result.rig.RigCamera` list (the first is the world
            frame and is not judged).
        mirrors: :class:`~mirrorgraph.result.rig.RigMirror` list.
        robust_parts: camera or mirror name -> its uncertainty's parts (``contributions``:
            the unknown intrinsics' shares of its variance).
        view_names, view_counts, view_observed: per view, the observations the graph kept
            and those it was offered.
        mirror_spread_deg: mirror name -> the largest angle between two cameras' initial
            estimates of it, degrees.
        failed: the cameras marked failed (their own line says why; not judged again).

    Returns:
        The warnings, in words.
    """
    out = [f"mirror {m}: the cameras' initial estimates differ by {spread:.1f} deg (is it "
           "the same mirror in all of them?)"
           for m, spread in mirror_spread_deg.items() if spread > MIRROR_SPREAD_WARN_DEG]
    for name, kept, offered in zip(view_names, view_counts, view_observed):
        if str(name).split("/")[0] in failed:
            continue
        if offered and kept < MIN_KEPT_FRACTION * offered:
            out.append(f"view {name}: only {100 * kept / offered:.0f} % of its keypoints fit "
                       "the rig (is it the same person as in the other cameras? the right "
                       "intrinsics, frame offset, mirror?)")
    for what, items in (("camera", cameras[1:]), ("mirror", mirrors)):
        for item in items:
            if getattr(item, "failed", False):
                continue
            if item.rotation_std_deg > POORLY_DETERMINED_DEG:
                share = (robust_parts.get(item.name) or {}).get("contributions") or {}
                top = dominant_intrinsic(share)
                cause = ("too few frames, too little motion, or a detector's error the frames "
                         "do not average out")
                if top is not None:
                    cause = (f"the unknown {top.replace('_', ' ')} of a camera listed without "
                             f"intrinsics dominates it ({100 * share[top]:.0f}% of its "
                             "variance): give that camera its intrinsics")
                out.append(poorly_determined(f"{what} {item.name}", item.rotation_std_deg, cause,
                                             item.marginal_rotation_std_deg))
    return out
