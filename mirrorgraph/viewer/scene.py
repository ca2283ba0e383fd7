"""What the viewer draws: a :class:`ViewScene` of cameras, mirrors and joints.

:func:`scene_from_calibration` and :func:`scene_from_rig` make the scene of a
single-mirror or a rig calibration (world frame: the real camera's, or the rig's first
camera's; every camera that sees a mirror gets the mirror's virtual camera);
:func:`joint_covariances` is the per-joint uncertainty drawn for a single mirror
(see :mod:`mirrorgraph.viewer.recording` for what the recording holds).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from .. import geometry as geo
from ..errors import InputError

__all__ = ["ViewCamera", "ViewMirror", "ViewScene", "joint_covariances",
           "scene_from_calibration", "scene_from_rig"]


@dataclass
class ViewCamera:
    """A camera to draw.

    Attributes:
        name: entity name.
        K: ``(3, 3)`` camera matrix, pixels.
        size: ``(W, H)`` image size in pixels, or ``None`` (then ``2 cx, 2 cy``).
        pose: ``(4, 4)`` camera to world.
        virtual: a mirror's virtual camera (of the flipped image).
    """

    name: str
    K: np.ndarray
    size: tuple[int, int] | None
    pose: np.ndarray
    virtual: bool = False

    @property
    def resolution(self) -> tuple[float, float]:
        if self.size is not None:
            return float(self.size[0]), float(self.size[1])
        return 2.0 * float(self.K[0, 2]), 2.0 * float(self.K[1, 2])


@dataclass
class ViewMirror:
    """A mirror ``n . X = d`` (world frame) and the centres of the cameras that see it."""

    name: str
    normal: np.ndarray
    distance: float
    seen_from: list[np.ndarray] = field(default_factory=list)


@dataclass
class ViewScene:
    """Everything :func:`record` draws.

    Attributes:
        cameras: real and virtual cameras.
        mirrors: the mirror planes.
        unit: length unit (``"m"``, ``"mirror distance"``, ``"subject height"``).
        joints3d: ``(T, J, 3)`` world-frame joints or ``None``; ``valid`` ``(T, J)``.
        frame_ids: ``(T,)`` frame numbers; ``fps`` Hz or ``None``.
        joint_names: ``(J,)`` canonical names; ``bones`` ``(B, 2)`` joint indices.
        joint_cov: ``(T, J, 3, 3)`` covariances of the joints, or ``None``.
        keypoints: ``(real, mirror)`` ``(T, J, 3)`` pixel keypoints (x, y, confidence)
            of the first camera, or ``None``.
        epipole: ``(3,)`` homogeneous epipole of the first camera's mirror, or ``None``.
        epipole_px: ``(2,)`` the epipole in pixels, ``None`` at infinity.
        summary: text shown beside the scene.
    """

    cameras: list[ViewCamera]
    mirrors: list[ViewMirror]
    unit: str = "m"
    joints3d: np.ndarray | None = None
    valid: np.ndarray | None = None
    frame_ids: np.ndarray | None = None
    fps: float | None = None
    joint_names: tuple[str, ...] = ()
    bones: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), int))
    joint_cov: np.ndarray | None = None
    keypoints: tuple[np.ndarray, np.ndarray] | None = None
    epipole: np.ndarray | None = None
    epipole_px: np.ndarray | None = None
    summary: str = ""


def _pose(R_wc: np.ndarray, centre: np.ndarray) -> np.ndarray:
    P = np.eye(4)
    P[:3, :3], P[:3, 3] = R_wc, centre
    return P


def _virtual_camera(name: str, K: np.ndarray, size, pose: np.ndarray, normal: np.ndarray,
                    distance: float) -> ViewCamera:
    """The flipped-image camera of ``pose`` through the mirror (``R = D R_c^T H``)."""
    from ..export import flip_camera_matrix
    from ..result.rig import virtual_extrinsics

    R, t = virtual_extrinsics(pose, normal, distance)
    W = size[0] if size is not None else 2.0 * K[0, 2]
    return ViewCamera(name, flip_camera_matrix(K, W), size, _pose(R.T, -R.T @ t), virtual=True)


def _bones(joint_names) -> np.ndarray:
    """``(B, 2)`` joint indices of the layout's bones plus the face's and feet's links,
    person by person in the layout of several people
    (:func:`~mirrorgraph.skeletons.people_skeleton`: names tagged ``@p``)."""
    from ..skeletons import person_of
    names = [str(n) for n in joint_names]
    tags = [person_of(n) for n in names]
    out = []
    for tag in dict.fromkeys(tags):
        rows = np.array([i for i, t in enumerate(tags) if t == tag])
        base = [names[i][:len(names[i]) - len(tag)] for i in rows]
        out.append(rows[_body_bones(base)])
    return np.concatenate(out).reshape(-1, 2) if out else np.zeros((0, 2), int)


def _body_bones(names: list[str]) -> np.ndarray:
    """``(B, 2)`` bones of one person's joint names (:func:`_bones`)."""
    from ..skeletons import skeletons_for_count
    idx = {n: i for i, n in enumerate(names)}
    pairs = []
    for sk in skeletons_for_count(len(names)):
        if list(sk.joints) == names:
            pairs += [(idx[a], idx[b]) for a, b in sk.bones.values()]
            break
    extra = [("neck", "nose"), ("nose", "left_eye"), ("nose", "right_eye"),
             ("left_eye", "left_ear"), ("right_eye", "right_ear"), ("neck", "head_top"),
             ("mid_hip", "neck"), ("left_ankle", "left_heel"), ("left_ankle", "left_big_toe"),
             ("left_big_toe", "left_small_toe"), ("right_ankle", "right_heel"),
             ("right_ankle", "right_big_toe"), ("right_big_toe", "right_small_toe"),
             ("left_shoulder", "left_hip"), ("right_shoulder", "right_hip")]
    if "neck" not in idx:
        extra += [("left_shoulder", "right_shoulder")]
    if "mid_hip" not in idx:
        extra += [("left_hip", "right_hip")]
    pairs += [(idx[a], idx[b]) for a, b in extra if a in idx and b in idx]
    return np.array(sorted(set(pairs)), dtype=int).reshape(-1, 2)


def joint_covariances(joints3d: np.ndarray, K: np.ndarray, normal: np.ndarray,
                      distance: float, sigma_real_px: float, sigma_mirror_px: float
                      ) -> np.ndarray:
    """``(T, J, 3, 3)`` covariance of each joint triangulated from the camera and the mirror.

    The joint ``X`` (real camera frame) is seen at ``pi(K X)`` and its reflection at
    ``pi(K S(X))``, ``S(X) = H X + 2 d n``; with iid pixel noise of std
    ``sigma_real_px`` and ``sigma_mirror_px`` the Gauss-Newton covariance is
    ``(J_r^T J_r / s_r^2 + J_m^T J_m / s_m^2)^-1``, ``J = dpi/dX`` (the mirror's
    through ``H``). NaN where a joint is NaN.
    """
    X = np.asarray(joints3d, float)
    n = np.asarray(normal, float)
    H = geo.householder(n)
    S = X @ H.T + 2.0 * float(distance) * n

    def jac(P):                                     # (..., 2, 3) of pi(K P) at P
        x, y, z = P[..., 0], P[..., 1], P[..., 2]
        fx, s, fy = K[0, 0], K[0, 1], K[1, 1]
        J = np.zeros(P.shape[:-1] + (2, 3))
        J[..., 0, 0] = fx / z
        J[..., 0, 1] = s / z
        J[..., 0, 2] = -(fx * x + s * y) / z**2
        J[..., 1, 1] = fy / z
        J[..., 1, 2] = -fy * y / z**2
        return J

    Jr = jac(X)
    Jm = jac(S) @ H
    info = (np.swapaxes(Jr, -1, -2) @ Jr / sigma_real_px**2
            + np.swapaxes(Jm, -1, -2) @ Jm / sigma_mirror_px**2)
    ok = np.isfinite(info).all((-1, -2))
    info[~ok] = np.eye(3)
    cov = np.linalg.inv(info)
    cov[~ok] = np.nan
    return cov


def scene_from_calibration(calib, *, joints3d: np.ndarray | None = None,
                           valid: np.ndarray | None = None,
                           frame_ids: np.ndarray | None = None,
                           joint_names=(), fps: float | None = None,
                           keypoints: tuple[np.ndarray, np.ndarray] | None = None,
                           unit: str | None = None) -> ViewScene:
    """The scene of a single-mirror :class:`~mirrorgraph.result.mirror.Calibration`.

    The world frame is the real camera's. Without a metric scale the mirror is at
    distance 1 and lengths are in mirror distances (as the 3D joints then are).
    ``joints3d`` ``(T, J, 3)`` in that frame and unit; the per-joint uncertainty is
    drawn where the calibration holds the refinement's RMS residuals.
    """
    intr = calib.intrinsics
    d = calib.distance if calib.distance is not None else 1.0
    unit = unit or ("m" if calib.distance is not None else "mirror distance")
    real = ViewCamera("camera", intr.K, intr.image_size, np.eye(4))
    virtual = _virtual_camera("mirror_camera", intr.K, intr.image_size, np.eye(4),
                              calib.normal, d)
    scene = ViewScene([real, virtual], [ViewMirror("mirror", np.asarray(calib.normal, float),
                                                   float(d), [np.zeros(3)])], unit=unit,
                      summary=calib.summary())
    if joints3d is not None:
        _add_joints(scene, joints3d, valid, frame_ids, joint_names, fps)
        rms_r = calib.refinement.get("rms_direct_px")
        rms_m = calib.refinement.get("rms_mirror_px")
        if rms_r and rms_m and np.isfinite([rms_r, rms_m]).all():
            scene.joint_cov = joint_covariances(scene.joints3d, intr.K, calib.normal, d,
                                                float(rms_r), float(rms_m))
    if keypoints is not None:
        scene.keypoints = keypoints
        scene.epipole = np.asarray(calib.epipole, float)
        scene.epipole_px = geo.epipole_pixels(calib.epipole)
    return scene


def _add_joints(scene: ViewScene, joints3d, valid, frame_ids, joint_names, fps) -> None:
    X = np.asarray(joints3d, float)
    if X.ndim != 3 or X.shape[2] != 3:
        raise InputError(f"expected joints of shape (T, J, 3), got {X.shape}", field="joints3d")
    ok = np.isfinite(X).all(-1)
    if valid is not None:
        ok &= np.asarray(valid, bool)
    scene.joints3d, scene.valid = X, ok
    scene.frame_ids = (np.arange(len(X)) if frame_ids is None
                       else np.asarray(frame_ids, np.int64))
    scene.joint_names = tuple(str(n) for n in joint_names)
    scene.bones = _bones(scene.joint_names) if scene.joint_names else np.zeros((0, 2), int)
    scene.fps = None if fps is None or not np.isfinite(fps) else float(fps)


def scene_from_rig(rig, *, joints3d=None, valid=None, frame_ids=None, joint_names=(),
                   fps: float | None = None) -> ViewScene:
    """The scene of a rig: a :class:`~mirrorgraph.result.rig.RigCalibration` or its JSON
    (path or parsed document, :meth:`~mirrorgraph.result.rig.RigCalibration.to_dict`).

    The world frame is the first camera's; every camera that sees a mirror gets its
    virtual camera. Without ``joints3d`` a :class:`RigCalibration`'s own joints are
    drawn, every person's where it holds several (``people_joints3d``).
    """
    from ..skeletons import skeleton_by_name

    if isinstance(rig, (str, os.PathLike)):
        rig = _load_json(rig)
    if isinstance(rig, dict):
        cams = [(c["name"], np.asarray(c["intrinsics"]["K"], float),
                 c["intrinsics"].get("image_size"), np.asarray(c["pose_camera_to_world"], float))
                for c in rig["cameras"]]
        mirrors = [(m["name"], np.asarray(m["normal"], float), float(m["distance"]),
                    list(m.get("seen_by", []))) for m in rig["mirrors"]]
        unit = rig.get("length_unit", "m")
        lines = []
        for name, _, _, pose in cams:
            lines.append(f"camera {name}: centre {np.round(pose[:3, 3], 3).tolist()} {unit}")
        for name, n, d, seen_by in mirrors:
            lines.append(f"mirror {name}: normal {np.round(n, 4).tolist()}, distance {d:.3f} "
                         f"{unit}, seen by {', '.join(seen_by)}")
        summary = "\n".join(lines + [f"warning: {w}" for w in rig.get("warnings", [])])
        skeleton = rig.get("skeleton")
    else:
        cams = [(c.name, c.intrinsics.K, c.intrinsics.image_size, c.pose) for c in rig.cameras]
        mirrors = [(m.name, m.normal, m.distance, list(m.seen_by)) for m in rig.mirrors]
        unit = "m" if rig.scale == "subject_height" else "subject height"
        summary = rig.summary()
        skeleton = rig.skeleton
        if joints3d is None and getattr(rig, "people_joints3d", None) is not None:
            # every person (``--people all``) side by side: the layout of people_skeleton
            from ..skeletons import people_skeleton
            P, T, J = rig.people_valid.shape
            joints3d = np.moveaxis(rig.people_joints3d, 0, 1).reshape(T, P * J, 3)
            valid = np.moveaxis(rig.people_valid, 0, 1).reshape(T, P * J)
            frame_ids = rig.frame_ids
            joint_names = people_skeleton(skeleton_by_name(rig.skeleton), P).joints
        elif joints3d is None:
            joints3d, valid, frame_ids = rig.joints3d, rig.valid, rig.frame_ids
            joint_names = skeleton_by_name(rig.skeleton).joints
    cameras = [ViewCamera(name, K, None if size is None else tuple(size), pose)
               for name, K, size, pose in cams]
    by_name = {c.name: c for c in cameras}
    view_mirrors = []
    for name, n, d, seen_by in mirrors:
        view_mirrors.append(ViewMirror(name, n, d, [by_name[c].pose[:3, 3] for c in seen_by
                                                    if c in by_name]))
        for c in seen_by:
            if c in by_name:
                cam = by_name[c]
                cameras.append(_virtual_camera(f"{c}_{name}", cam.K, cam.size, cam.pose, n, d))
    scene = ViewScene(cameras, view_mirrors, unit=unit, summary=summary)
    if joints3d is not None:
        if not len(joint_names) and skeleton:
            joint_names = skeleton_by_name(skeleton).joints
        _add_joints(scene, joints3d, valid, frame_ids, joint_names, fps)
    return scene


def _load_json(path) -> dict:
    from ..io._common import load_json
    return load_json(path)
