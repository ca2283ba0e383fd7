"""What a single-mirror calibration rests on: the sensitivity report (``calibration.json``'s
``sensitivity``).

From the joints' scores and Schur complements at the solution
(:func:`~.scores.joint_scores`), without solving again:

* **leave one out**: how the mirror moves when one left/right pair of joints, or one
  segment of the video, is left out (:func:`~.sandwich.leave_one_out`, the
  linearised jackknife), as the virtual camera's rotation (degrees);
* **information per segment**: the share of the normal's information each segment
  carries (trace of its ``2 x 2`` block) and the std that segment alone would give:
  which parts of the video carry the calibration;
* **frames needed**: the rotation std predicted for other numbers of frames with the
  same kind of motion: for iid noise it falls as ``1 / sqrt(N)``; of the reported
  (cluster-robust) variance, the part a joint pair's clusters see beyond what the
  time series sees (a detector's bias) does not fall with more frames, so
  ``std(N)^2 = v_time T / N + v_floor``, ``v_time`` the larger of the time-series
  figures, ``v_floor`` what the headline has beyond it; with the frames needed for a
  few target stds (``None``: not reachable by more frames of this kind).

The weight of each body prior halved and doubled needs the graph solved again: that
part is :func:`prior_weights`, run only when asked (``--sensitivity`` on the command
line), as it costs several calibrations.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..metrics import mirror_rotation_error_deg
from .result import normal_cov_from_tangent, rotation_std_from_normal_cov
from .sandwich import gauge_inverse, leave_one_out, sandwich
from .scores import JointScores

__all__ = ["sensitivity_report", "rig_sensitivity_report", "predicted_std", "TARGET_STDS_DEG", "FRAME_GRID",
           "REPORT_SEGMENTS", "prior_weights", "PRIORS"]

#: Segments of the leave-one-out and information tables.
REPORT_SEGMENTS = 10
#: Frame counts of the predicted std.
FRAME_GRID = (100, 200, 500, 1000, 2000, 5000, 10000, 30000)
#: Target rotation stds (deg) whose frame counts are reported.
TARGET_STDS_DEG = (0.5, 0.2, 0.1, 0.05, 0.02)


def _rot_deg(basis: np.ndarray, dz: np.ndarray) -> float:
    """The virtual camera's rotation (deg) of a normal step ``dz[:2]`` (tangent coordinates)."""
    return float(np.degrees(2.0 * np.linalg.norm(basis @ np.asarray(dz, float)[:2])))


def predicted_std(frames: np.ndarray, T: int, v_time: float, v_floor: float) -> np.ndarray:
    """``sqrt(v_time T / N + v_floor)``: the rotation std (deg) predicted for ``N`` frames
    from variances (deg^2) measured on ``T`` frames (see the module docstring)."""
    N = np.asarray(frames, dtype=float)
    return np.sqrt(v_time * T / N + v_floor)


def sensitivity_report(scores: JointScores, basis: np.ndarray, parts: dict,
                       marginal_std: float, skeleton, frame_ids: np.ndarray) -> dict:
    """The ``sensitivity`` record of a single mirror (see the module docstring).

    Args:
        scores: :func:`~.scores.joint_scores` at the solution (one plane).
        basis: ``(3, 2)`` the plane normal's tangent basis of the scores.
        parts: :func:`~.uncertainty.robust_normal_cov`'s record (each figure's std).
        marginal_std: the marginal rotation std (deg), scaled by the noise.
        skeleton: the keypoint layout (joint names).
        frame_ids: ``(T,)`` frame numbers of the rows.

    Returns:
        A JSON-ready dict: ``leave_out`` (``joint_pairs``, ``segments``),
        ``information`` (``segments``), ``frames_needed``.
    """
    T = scores.frame_info.shape[0]
    H = scores.information
    whitened_var = rotation_std_from_normal_cov(
        normal_cov_from_tangent(basis, gauge_inverse(H, scores.gauge)[:2, :2])) ** 2
    # the scores are whitened with the assumed pixel sigma; the marginal figure is scaled
    # by the noise the data show: the same factor turns "alone" figures into degrees
    scale = marginal_std ** 2 / whitened_var if whitened_var > 0 else float("nan")
    pairs, dpair, _ = leave_one_out(scores, "joint")
    segs, dseg, Hseg = leave_one_out(scores, "time", min(REPORT_SEGMENTS, max(T, 1)))
    fid = np.asarray(frame_ids)
    total_trace = float(np.trace(H[:2, :2]))

    def alone(Hc: np.ndarray) -> float | None:
        if np.trace(Hc[:2, :2]) <= 0:
            return None
        try:
            cov = np.linalg.inv(Hc[:2, :2])
        except np.linalg.LinAlgError:
            return None
        return float(np.sqrt(scale) * rotation_std_from_normal_cov(
            normal_cov_from_tangent(basis, cov)))

    segments = [{"frames": [int(fid[a]), int(fid[b - 1])] if b > a else [None, None],
                 "rotation_change_deg": _rot_deg(basis, d),
                 "information_share": float(np.trace(Hc[:2, :2]) / total_trace)
                 if total_trace > 0 else None,
                 "rotation_std_deg_alone": alone(Hc)}
                for (a, b), d, Hc in zip(segs, dseg, Hseg)]
    joint_pairs = [{"joints": [skeleton.joints[j] for j in members],
                    "rotation_change_deg": _rot_deg(basis, d)}
                   for members, d in zip(pairs, dpair)]
    time_std = max(parts.get("time_rotation_std_deg", 0.0) or 0.0,
                   parts.get("jack_time_rotation_std_deg", 0.0) or 0.0, marginal_std)
    head_std = max(marginal_std, *(parts.get(f"{k}_rotation_std_deg", 0.0) or 0.0
                                   for k in ("time", "joint", "two_way", "jack_time",
                                             "jack_joint")))
    v_time, v_floor = time_std ** 2, max(head_std ** 2 - time_std ** 2, 0.0)
    grid = np.array(FRAME_GRID, dtype=float)
    needed = {}
    for target in TARGET_STDS_DEG:
        if target ** 2 <= v_floor:
            needed[f"{target:g}"] = None
        else:
            needed[f"{target:g}"] = int(np.ceil(v_time * T / (target ** 2 - v_floor)))
    return {
        "leave_out": {"joint_pairs": joint_pairs, "segments": segments},
        "frames_needed": {
            "frames": [int(x) for x in grid],
            "iid_rotation_std_deg": predicted_std(grid, T, marginal_std ** 2, 0.0).tolist(),
            "rotation_std_deg": predicted_std(grid, T, v_time, v_floor).tolist(),
            "floor_rotation_std_deg": float(np.sqrt(v_floor)),
            "frames_for_rotation_std_deg": needed,
            "model": "std(N)^2 = v_time * T / N + v_floor: the time series' variance falls "
                     "with more frames, a bias the joint pairs show beyond it does not",
        },
    }


# --------------------------------------------------------------------------- rigs
def _block_move_deg(kind: str, basis, d: np.ndarray) -> float:
    """A camera's rotation (deg) of its pose step ``d[:3]``, or a mirror's virtual-camera
    rotation of its plane step (``d[:2]``, normal tangent coordinates)."""
    if kind == "camera":
        return float(np.degrees(np.linalg.norm(np.asarray(d, float)[:3])))
    return _rot_deg(basis, d)


def _block_std_deg(kind: str, basis, C: np.ndarray) -> float:
    """The rotation std (deg) of a camera's ``(3, 3)`` or a mirror's ``(2, 2)`` tangent
    covariance (as :func:`mirrorgraph.pipelines.solve.camera_std` and ``plane_std``)."""
    if kind == "camera":
        return float(np.degrees(np.sqrt(max(np.trace(C), 0.0))))
    return rotation_std_from_normal_cov(normal_cov_from_tangent(basis, C))


def rig_sensitivity_report(scores: JointScores, blocks: list[tuple[str, str, object]],
                           marginal_blocks: list[np.ndarray], skeleton,
                           frame_ids: np.ndarray) -> dict:
    """The ``sensitivity`` record of a rig: per estimated camera and mirror, as
    :func:`sensitivity_report` for a single mirror.

    Args:
        scores: :func:`~.scores.joint_scores` of the rig at its solution.
        blocks: per reduced variable of ``scores.z_keys``, in order: ``(name, kind,
            basis)``, kind ``"camera"`` (a pose: rotation first) or ``"mirror"`` (a plane:
            the normal's tangent first, ``basis`` its ``(3, 2)`` tangent basis).
        marginal_blocks: each variable's marginal covariance (scaled by the noise).
        skeleton, frame_ids: as :func:`sensitivity_report`.

    Returns:
        camera or mirror name -> ``{"leave_out": {"joint_pairs", "segments"},
        "frames_needed"}`` (rotations in degrees: a camera's own, a mirror's virtual
        camera's).
    """
    T = scores.frame_info.shape[0]
    H = scores.information
    Hinv = gauge_inverse(H, scores.gauge)
    sw = sandwich(scores)
    cands = {k: sw[f"cov_{k}"] for k in ("time", "joint", "jack_time", "jack_joint")}
    cands["two_way"] = sw["cov"]
    pairs, dpair, _ = leave_one_out(scores, "joint")
    segs, dseg, Hseg = leave_one_out(scores, "time", min(REPORT_SEGMENTS, max(T, 1)))
    fid = np.asarray(frame_ids)
    grid = np.array(FRAME_GRID, dtype=float)
    out, off = {}, 0
    for (key, dim), (name, kind, basis), M in zip(scores.z_keys, blocks, marginal_blocks):
        rot = slice(off, off + (3 if kind == "camera" else 2))
        block = slice(off, off + dim)
        off += dim
        M = np.asarray(M, dtype=float)
        r = slice(0, 3 if kind == "camera" else 2)
        marginal_std = _block_std_deg(kind, basis, M[r, r])
        whitened = _block_std_deg(kind, basis, Hinv[rot, rot])
        scale = (marginal_std / whitened) ** 2 if whitened > 0 else float("nan")
        total = float(np.trace(H[rot, rot]))

        def alone(Hc: np.ndarray, rot=rot, kind=kind, basis=basis, scale=scale):
            # the segment's own marginal (its information on every global, the gauge
            # fixed): a camera's rotation is tied to its position
            if np.trace(Hc[rot, rot]) <= 0:
                return None
            try:
                C = gauge_inverse(Hc, scores.gauge)[rot, rot]
            except np.linalg.LinAlgError:
                return None
            if not np.all(np.isfinite(C)):
                return None
            return float(np.sqrt(scale) * _block_std_deg(kind, basis, C))

        segments = [{"frames": [int(fid[a]), int(fid[b - 1])] if b > a else [None, None],
                     "rotation_change_deg": _block_move_deg(kind, basis, d[block]),
                     "information_share": float(np.trace(Hc[rot, rot]) / total)
                     if total > 0 else None,
                     "rotation_std_deg_alone": alone(Hc)}
                    for (a, b), d, Hc in zip(segs, dseg, Hseg)]
        joint_pairs = [{"joints": [skeleton.joints[j] for j in members],
                        "rotation_change_deg": _block_move_deg(kind, basis, d[block])}
                       for members, d in zip(pairs, dpair)]
        stds = {k: _block_std_deg(kind, basis, C[rot, rot]) for k, C in cands.items()
                if np.all(np.isfinite(C[rot, rot]))}
        time_std = max([marginal_std] + [stds[k] for k in ("time", "jack_time") if k in stds])
        head_std = max([marginal_std] + list(stds.values()))
        v_time, v_floor = time_std ** 2, max(head_std ** 2 - time_std ** 2, 0.0)
        needed = {f"{t:g}": (None if t ** 2 <= v_floor
                             else int(np.ceil(v_time * T / (t ** 2 - v_floor))))
                  for t in TARGET_STDS_DEG}
        out[name] = {
            "kind": kind,
            "leave_out": {"joint_pairs": joint_pairs, "segments": segments},
            "frames_needed": {
                "frames": [int(x) for x in grid],
                "rotation_std_deg": predicted_std(grid, T, v_time, v_floor).tolist(),
                "floor_rotation_std_deg": float(np.sqrt(v_floor)),
                "frames_for_rotation_std_deg": needed},
        }
    return out


# --------------------------------------------------------------------------- priors
#: The body priors of the calibration graph whose weight :func:`prior_weights` varies:
#: name -> the :class:`~.options.RefineOptions` sigma.
PRIORS = {"bone_length": "bone_sigma", "symmetry": "symmetry_sigma",
          "anthropometry": "anthropometry_sigma", "hip": "hip_sigma"}


def prior_weights(refine, normal: np.ndarray, options, used: dict, factors=(0.5, 2.0)) -> dict:
    """How the mirror moves when each body prior's weight is halved or doubled.

    A prior's weight is ``1 / sigma^2``: its sigma is multiplied by ``1 / sqrt(f)`` and
    the calibration solved again (``refine(options) -> RefinementResult``, from the
    same pairs and initial mirror); the change of the virtual camera's rotation from
    ``normal``, in degrees.

    Args:
        refine: ``refine(options)`` -> a result with ``normal``.
        normal: ``(3,)`` the calibration's normal (solved with ``options``).
        options: its :class:`~.options.RefineOptions`.
        used: its ``priors`` record: priors the graph did not use are left out.
        factors: the weight factors.

    Returns:
        prior name -> ``{"x0.5": deg, "x2": deg}``.
    """
    out = {}
    for name, field_name in PRIORS.items():
        if name not in used:
            continue
        row = {}
        for f in factors:
            sigma = getattr(options, field_name) / np.sqrt(f)
            res = refine(replace(options, **{field_name: sigma}))
            row[f"x{f:g}"] = mirror_rotation_error_deg(res.normal, normal)
        out[name] = row
    return out
