"""A Rerun recording of a calibration: cameras, mirrors, the 3D motion and its reflection.

``mirrorgraph view CALIBRATION [--joints3d FILE] [--video FILE] [--save OUT.rrd]`` and
``--view`` on ``calibrate`` / ``calibrate-rig`` build a recording with the Rerun SDK
(``rerun-sdk``, the ``view`` extra; imported only here, only when called) and open it
in Rerun's viewer, or save it as an ``.rrd`` file that the viewer (``rerun OUT.rrd``,
or its web viewer) opens later. Everything is offline.

What the recording holds (entity paths; world frame: the real camera's, or the rig's
first camera's: x right, y down, z forward, lengths in the calibration's unit)
------------------------------------------------------------------------------------

``world/cameras/<name>``
    each real camera: its pose (``Transform3D``, camera to world) and, under
    ``image``, its pinhole (``K``, image size): the frustum and image plane.
``world/virtual_cameras/<name>``
    each mirror's virtual camera (one per camera that sees the mirror): the camera
    reflected across the mirror, drawn as the camera of the horizontally *flipped*
    image (``u -> W - u``, the convention of :mod:`mirrorgraph.export`: a
    reflected camera is left-handed, its flipped image is an ordinary one).
``world/mirrors/<name>``
    the mirror plane: ``surface`` (a translucent quad) and ``outline``. Its extent is
    the part of the mirror the reflections were seen in (where the rays from the
    camera to the reflected joints cross the plane, 10 % added on each side); a
    2 x 2 length-unit square around the foot of the camera's perpendicular without
    3D joints.
``world/person/joints``, ``world/person/bones``
    the 3D joints and bones over time (timeline ``frame``, the input's frame numbers;
    ``time`` in seconds where the frame rate is known).
``world/reflections/<mirror>/joints``, ``.../bones``
    the same skeleton reflected across each mirror: where the virtual person stands.
``world/person/uncertainty``
    one-sigma ellipsoids of every joint (single mirror only): the covariance of
    triangulating the joint from its two views with iid pixel noise of the
    refinement's RMS residual in each view (``refinement.rms_direct_px``,
    ``rms_mirror_px``), ``sigma^2 (J^T J)^-1`` with ``J`` the projections' Jacobians.
    It leaves out the mirror's own uncertainty and correlated detector error, so it
    is a lower bound: it shows which joints the geometry determines poorly (depth
    along the rays), not a guarantee.
``world/cameras/<real>/image`` (with ``--video``, single mirror)
    the video frames (JPEG, at most ``max_video_frames`` of them, evenly spaced),
    with ``keypoints`` (the person), ``reflection`` (its reflection),
    ``epipolar_lines`` (each joint's: through the joint and the epipole, ``F u``; its
    reflection lies on it up to the detector's error) and ``epipole``. The
    keypoints are the undistorted ones the calibration used: on a lens with strong
    distortion they sit off the raw frame near its corners.
``summary``
    the calibration's summary (a text document).

:func:`record` builds it from a :class:`ViewScene`; :func:`scene_from_calibration` and
:func:`scene_from_rig` make the scene of a single-mirror or a rig calibration;
:func:`view_file` does what the command does.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import geometry as geo
from .errors import InputError, extra_hint, require_extra

__all__ = ["INSTALL_HINT", "ViewCamera", "ViewMirror", "ViewScene", "joint_covariances",
           "record", "require_rerun", "scene_from_calibration", "scene_from_rig", "view_file"]

#: How to get the viewer's dependency.
INSTALL_HINT = extra_hint("view")

PERSON = (60, 200, 90)
REFLECTION = (240, 140, 40)
REAL_CAMERA = (90, 160, 255)
VIRTUAL_CAMERA = (240, 140, 40)
MIRROR = (150, 200, 255, 70)
MIRROR_EDGE = (150, 200, 255)


def require_rerun():
    """The ``rerun`` module, or :class:`MissingExtraError` saying how to install it."""
    return require_extra("rerun", "view", "the viewer", what="the Rerun SDK")


# --------------------------------------------------------------------------- the scene
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
    from .export import flip_camera_matrix
    from .result.rig import virtual_extrinsics

    R, t = virtual_extrinsics(pose, normal, distance)
    W = size[0] if size is not None else 2.0 * K[0, 2]
    return ViewCamera(name, flip_camera_matrix(K, W), size, _pose(R.T, -R.T @ t), virtual=True)


def _bones(joint_names) -> np.ndarray:
    """``(B, 2)`` joint indices of the layout's bones plus the face's and feet's links."""
    from .skeletons import skeletons_for_count
    names = list(joint_names)
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
    drawn.
    """
    from .skeletons import skeleton_by_name

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
        if joints3d is None:
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
    from .io._common import load_json
    return load_json(path)


# --------------------------------------------------------------------------- drawing helpers
def reflect(X: np.ndarray, normal: np.ndarray, distance: float) -> np.ndarray:
    """``(..., 3)`` points reflected across ``n . X = d``: ``X - 2 (n . X - d) n``."""
    n = np.asarray(normal, float)
    return X - 2.0 * ((X @ n) - distance)[..., None] * n


def mirror_quad(mirror: ViewMirror, points: np.ndarray | None) -> np.ndarray:
    """``(4, 3)`` corners of the drawn part of a mirror (see the module docstring).

    ``points`` ``(N, 3)`` joints: the reflections of them seen from each camera of
    :attr:`ViewMirror.seen_from` cross the plane where the mirror must be.
    """
    n, d = np.asarray(mirror.normal, float), float(mirror.distance)
    a = np.cross(n, [0.0, 1.0, 0.0] if abs(n[1]) < 0.9 else [1.0, 0.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    centre_default = d * n
    hits = []
    if points is not None and len(points):
        R = reflect(points, n, d)
        for c in mirror.seen_from or [np.zeros(3)]:
            ray = R - c
            denom = ray @ n
            s = (d - c @ n) / np.where(np.abs(denom) > 1e-12, denom, np.nan)
            p = c + s[:, None] * ray
            hits.append(p[np.isfinite(p).all(-1) & (s > 0) & (s < 1)])
    hits = np.concatenate(hits) if hits else np.zeros((0, 3))
    if len(hits) >= 3:
        u, v = (hits - d * n) @ a, (hits - d * n) @ b
        lo_u, hi_u, lo_v, hi_v = u.min(), u.max(), v.min(), v.max()
        pad_u, pad_v = 0.1 * (hi_u - lo_u) + 1e-6, 0.1 * (hi_v - lo_v) + 1e-6
        lo_u, hi_u, lo_v, hi_v = lo_u - pad_u, hi_u + pad_u, lo_v - pad_v, hi_v + pad_v
        origin = d * n
    else:
        lo_u, hi_u, lo_v, hi_v = -1.0, 1.0, -1.0, 1.0
        origin = centre_default
    return np.array([origin + u * a + v * b for u, v in ((lo_u, lo_v), (hi_u, lo_v),
                                                          (hi_u, hi_v), (lo_u, hi_v))])


def clip_lines(lines: np.ndarray, width: float, height: float) -> tuple[np.ndarray, np.ndarray]:
    """Segments of homogeneous image lines ``(N, 3)`` inside ``[0, W] x [0, H]``.

    Returns ``(N, 2, 2)`` end points and ``(N,)`` bool: the line crosses the image.
    """
    L = np.asarray(lines, float)
    a, b, c = L[:, 0], L[:, 1], L[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        cand = np.stack([
            np.stack([np.zeros_like(a), -c / b], -1),                  # x = 0
            np.stack([np.full_like(a, width), -(c + a * width) / b], -1),   # x = W
            np.stack([-c / a, np.zeros_like(a)], -1),                  # y = 0
            np.stack([-(c + b * height) / a, np.full_like(a, height)], -1),  # y = H
        ], axis=1)                                                     # (N, 4, 2)
    eps = 1e-6 * max(width, height)
    inside = (np.isfinite(cand).all(-1) & (cand[..., 0] >= -eps) & (cand[..., 0] <= width + eps)
              & (cand[..., 1] >= -eps) & (cand[..., 1] <= height + eps))
    # the two inside candidates farthest apart
    big = np.where(inside[..., None], cand, np.nan)
    first = np.nanargmin(np.where(inside, cand[..., 0] + 1e-3 * cand[..., 1], np.inf), axis=1)
    last = np.nanargmax(np.where(inside, cand[..., 0] + 1e-3 * cand[..., 1], -np.inf), axis=1)
    rows = np.arange(len(L))
    seg = np.stack([big[rows, first], big[rows, last]], axis=1)
    ok = inside.sum(1) >= 2
    return seg, ok & np.isfinite(seg).all((-1, -2))


# --------------------------------------------------------------------------- the recording
def record(scene: ViewScene, *, save: str | os.PathLike | None = None,
           video: str | os.PathLike | None = None, max_video_frames: int = 300,
           application_id: str = "mirrorgraph") -> Path:
    """Log ``scene`` into a Rerun recording saved to ``save`` (an ``.rrd``, written
    atomically, no window), or else to a temporary ``.rrd`` opened in Rerun's viewer
    (the one of the installed ``rerun-sdk``, ``python -m rerun``).

    Args:
        scene: what to draw.
        save: the ``.rrd`` file to write, or ``None`` to open the viewer.
        video: the video of the first camera (frames drawn under its image plane with
            the 2D keypoints and epipolar lines), or ``None``.
        max_video_frames: at most this many video frames, evenly spaced over the
            frames with keypoints (the 2D keypoints are drawn in every frame).

    Returns:
        The recording written (``save``, or the temporary file the viewer opened).

    Raises:
        InputError: the Rerun SDK missing, a video that cannot be read, a viewer that
            exits at once (no display: the message names the recording to open elsewhere).
    """
    rr = require_rerun()
    from .io.atomic import atomic_path

    out = Path(save) if save is not None else \
        Path(tempfile.mkdtemp(prefix="mirrorgraph-view-")) / "recording.rrd"
    rec = rr.RecordingStream(application_id)
    layout = blueprint(scene, with_image=scene.keypoints is not None or video is not None)
    with atomic_path(out) as tmp:
        rec.save(str(tmp), default_blueprint=layout)
        _log(rr, rec, scene, video, max_video_frames)
        rec.flush()
        rec.disconnect()
    if save is None:
        open_viewer(out)
    return out


def open_viewer(path: str | os.PathLike, wait: float = 5.0) -> None:
    """Open ``path`` in the Rerun viewer of this Python's ``rerun-sdk``, detached. No
    display (Linux without ``DISPLAY`` or ``WAYLAND_DISPLAY``), or a viewer that exits with
    an error within ``wait`` seconds, raises :class:`InputError` naming the recording."""
    def no_display(why: str) -> InputError:
        return InputError(f"Rerun's viewer did not open ({why}): the recording is {path}; open "
                          f"it where there is a display with 'rerun {path}', or write it to a "
                          "file instead", fix=("save",))

    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                 or os.environ.get("WAYLAND_DISPLAY")):
        raise no_display("no display: neither DISPLAY nor WAYLAND_DISPLAY is set")
    proc = subprocess.Popen([sys.executable, "-m", "rerun", str(path)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        code = proc.wait(timeout=wait)
    except subprocess.TimeoutExpired:
        return                                  # running: the window is open
    if code:
        raise no_display(f"exit status {code}")


def blueprint(scene: ViewScene, *, with_image: bool):
    """The recording's default layout: the 3D scene (seen from above and behind the first
    camera, looking at the middle of the cameras, mirrors and person), beside it the
    first camera's image with its keypoints (where there are some) over the summary."""
    import rerun.blueprint as rrb

    marks = [c.pose[:3, 3] for c in scene.cameras if not c.virtual]
    marks += [m.distance * np.asarray(m.normal, float) for m in scene.mirrors]
    if scene.joints3d is not None and scene.valid.any():
        marks.append(np.median(scene.joints3d[scene.valid], axis=0))
    marks = np.array(marks)
    target = marks.mean(axis=0)
    reach = max(float(np.linalg.norm(marks - target, axis=1).max()), 1.0)
    first = next(c for c in scene.cameras if not c.virtual).pose[:3, :3]
    # to the right of the first camera, above it (-y: the world is y down), a little behind
    offset = first @ np.array([1.0, -1.2, -0.8])
    eye = target + 2.4 * reach * offset / np.linalg.norm(offset)   # all of it in view
    view3d = rrb.Spatial3DView(origin="world", name="cameras, mirrors and person",
                               eye_controls=rrb.EyeControls3D(position=eye, look_target=target,
                                                              eye_up=first @ [0.0, -1.0, 0.0]))
    side = [rrb.TextDocumentView(origin="summary", name="summary")]
    if with_image:
        side.insert(0, rrb.Spatial2DView(origin=_image_path(scene), name="camera image"))
    return rrb.Blueprint(rrb.Horizontal(view3d, rrb.Vertical(*side), column_shares=[3, 2]),
                         collapse_panels=True)


def _times(rr, scene: ViewScene, frames: np.ndarray) -> list:
    cols = [rr.TimeColumn("frame", sequence=frames)]
    if scene.fps:
        cols.append(rr.TimeColumn("time", duration=frames / scene.fps))
    return cols


def _set_time(rec, scene: ViewScene, frame: int) -> None:
    rec.set_time("frame", sequence=int(frame))
    if scene.fps:
        rec.set_time("time", duration=float(frame) / scene.fps)


def _log(rr, rec, scene: ViewScene, video, max_video_frames: int) -> None:
    rec.log("world", rr.ViewCoordinates.RDF, static=True)
    if scene.summary:
        rec.log("summary", rr.TextDocument(scene.summary), static=True)
    # a sense of scale for the image planes: a tenth of the farthest mirror or camera
    reach = [m.distance for m in scene.mirrors] + [float(np.linalg.norm(c.pose[:3, 3]))
                                                   for c in scene.cameras if not c.virtual]
    plane = max(0.1 * max(reach), 0.05)
    for cam in scene.cameras:
        path = f"world/{'virtual_cameras' if cam.virtual else 'cameras'}/{cam.name}"
        rec.log(path, rr.Transform3D(translation=cam.pose[:3, 3], mat3x3=cam.pose[:3, :3]),
                static=True)
        rec.log(f"{path}/image", rr.Pinhole(image_from_camera=cam.K, resolution=cam.resolution,
                                            camera_xyz=rr.ViewCoordinates.RDF,
                                            image_plane_distance=plane,
                                            color=VIRTUAL_CAMERA if cam.virtual else REAL_CAMERA),
                static=True)
    pts = None
    if scene.joints3d is not None:
        pts = scene.joints3d[scene.valid]
    for m in scene.mirrors:
        quad = mirror_quad(m, pts)
        rec.log(f"world/mirrors/{m.name}/surface",
                rr.Mesh3D(vertex_positions=quad, triangle_indices=[[0, 1, 2], [0, 2, 3]],
                          vertex_colors=[MIRROR] * 4), static=True)
        rec.log(f"world/mirrors/{m.name}/outline",
                rr.LineStrips3D([np.vstack([quad, quad[:1]])], colors=[MIRROR_EDGE]),
                static=True)
    if scene.joints3d is not None and len(scene.frame_ids):
        _log_skeleton(rr, rec, scene, "world/person", scene.joints3d, PERSON)
        for m in scene.mirrors:
            _log_skeleton(rr, rec, scene, f"world/reflections/{m.name}",
                          reflect(scene.joints3d, m.normal, m.distance), REFLECTION)
        if scene.joint_cov is not None:
            _log_uncertainty(rr, rec, scene)
    if scene.keypoints is not None:
        _log_keypoints(rr, rec, scene)
    if video is not None:
        _log_video(rr, rec, scene, video, max_video_frames)


def _log_skeleton(rr, rec, scene: ViewScene, path: str, X: np.ndarray, colour) -> None:
    ok = scene.valid
    times = _times(rr, scene, scene.frame_ids)
    rec.send_columns(f"{path}/joints", indexes=times,
                     columns=rr.Points3D.columns(positions=X[ok]).partition(ok.sum(1)))
    rec.log(f"{path}/joints", rr.Points3D.from_fields(colors=[colour], radii=[0.02]),
            static=True)
    if len(scene.bones):
        a, b = scene.bones[:, 0], scene.bones[:, 1]
        both = ok[:, a] & ok[:, b]                                    # (T, B)
        strips = np.stack([X[:, a], X[:, b]], axis=2)[both]          # (N, 2, 3)
        rec.send_columns(f"{path}/bones", indexes=times,
                         columns=rr.LineStrips3D.columns(strips=list(strips))
                         .partition(both.sum(1)))
        rec.log(f"{path}/bones", rr.LineStrips3D.from_fields(colors=[colour], radii=[0.008]),
                static=True)


def _log_uncertainty(rr, rec, scene: ViewScene) -> None:
    from scipy.spatial.transform import Rotation

    ok = scene.valid & np.isfinite(scene.joint_cov).all((-1, -2))
    cov = scene.joint_cov[ok]
    w, V = np.linalg.eigh(cov)                                      # ascending eigenvalues
    V[np.linalg.det(V) < 0, :, 0] *= -1                              # proper rotations
    q = Rotation.from_matrix(V).as_quat()                            # x, y, z, w
    rec.send_columns("world/person/uncertainty", indexes=_times(rr, scene, scene.frame_ids),
                     columns=rr.Ellipsoids3D.columns(
                         centers=scene.joints3d[ok], half_sizes=np.sqrt(np.maximum(w, 0)),
                         quaternions=q).partition(ok.sum(1)))
    rec.log("world/person/uncertainty",
            rr.Ellipsoids3D.from_fields(colors=[(*PERSON, 110)], fill_mode="solid"), static=True)


def _image_path(scene: ViewScene) -> str:
    real = next(c for c in scene.cameras if not c.virtual)
    return f"world/cameras/{real.name}/image"


def _log_keypoints(rr, rec, scene: ViewScene) -> None:
    real, mirror = scene.keypoints
    ids = scene.frame_ids
    if real.shape[0] != len(ids):
        raise InputError(f"{real.shape[0]} frames of keypoints for {len(ids)} frames of joints",
                         field="keypoints")
    base = _image_path(scene)
    times = _times(rr, scene, ids)
    ok_r = np.isfinite(real[..., :2]).all(-1)
    ok_m = np.isfinite(mirror[..., :2]).all(-1)
    for name, kp, ok, colour in (("keypoints", real, ok_r, PERSON),
                                 ("reflection", mirror, ok_m, REFLECTION)):
        rec.send_columns(f"{base}/{name}", indexes=times,
                         columns=rr.Points2D.columns(positions=kp[..., :2][ok])
                         .partition(ok.sum(1)))
        rec.log(f"{base}/{name}", rr.Points2D.from_fields(colors=[colour], radii=[4.0]),
                static=True)
    W, H = next(c for c in scene.cameras if not c.virtual).resolution
    both = ok_r & ok_m
    if scene.epipole is None:
        both[:] = False
    u = np.concatenate([real[..., :2], np.ones(real.shape[:2] + (1,))], -1)[both]
    # the epipolar line of each joint: through the joint and the epipole, F u = e x u
    seg, inside = clip_lines(np.cross(np.broadcast_to(scene.epipole, u.shape), u), W, H)
    per_frame = np.zeros(both.shape, bool)
    per_frame[both] = inside
    rec.send_columns(f"{base}/epipolar_lines", indexes=times,
                     columns=rr.LineStrips2D.columns(strips=list(seg[inside]))
                     .partition(per_frame.sum(1)))
    rec.log(f"{base}/epipolar_lines",
            rr.LineStrips2D.from_fields(colors=[(255, 255, 255, 90)], radii=[1.0]), static=True)
    if scene.epipole_px is not None:
        rec.log(f"{base}/epipole", rr.Points2D([scene.epipole_px], colors=[(255, 60, 60)],
                                               radii=[8.0], labels=["epipole"]), static=True)


def _log_video(rr, rec, scene: ViewScene, video, max_video_frames: int) -> None:
    import cv2

    from .video.reader import frames, probe

    probe(video)                                  # one error line if it cannot be read
    ids = scene.frame_ids if scene.frame_ids is not None else np.arange(max_video_frames)
    if len(ids) > max_video_frames:
        ids = ids[np.unique(np.linspace(0, len(ids) - 1, max_video_frames).round().astype(int))]
    wanted = {int(f) for f in ids}
    base = _image_path(scene)
    last = max(wanted) + 1 if wanted else 0
    for f, rgb in frames(video, end=last):
        if f not in wanted:
            continue
        ok, jpeg = cv2.imencode(".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR),
                                [cv2.IMWRITE_JPEG_QUALITY, 80])
        if not ok:
            continue
        _set_time(rec, scene, f)
        rec.log(base, rr.EncodedImage(contents=jpeg.tobytes(), media_type="image/jpeg"))


# --------------------------------------------------------------------------- the command
def view_file(calibration: str | os.PathLike, *, joints3d: str | os.PathLike | None = None,
              video: str | os.PathLike | None = None, save: str | os.PathLike | None = None,
              fps: float | None = None, max_video_frames: int = 300) -> Path:
    """What ``mirrorgraph view`` does: the recording of a calibration file.

    Args:
        calibration: a single mirror's ``calibration.json``, a rig's JSON, or a rig's
            ``calibration.toml`` (the JSON beside it is read).
        joints3d: a ``--joints3d`` ``.npz``; without it a single mirror's joints come
            from the run kept beside the calibration (``c.report.npz``) where there is
            one, with its 2D keypoints.
        video: the video of the (first) camera: single mirror only.
        save: ``.rrd`` to write instead of opening the viewer.
        fps: frame rate of the timeline ``time`` (default: the joints file's).

    Raises:
        InputError: an unreadable or unknown calibration, joints that do not belong to it,
            a video with a rig.
    """
    require_rerun()
    path = Path(calibration)
    if path.suffix.lower() == ".toml":
        json_path = path.with_suffix(".json")
        if not json_path.is_file():
            raise InputError("a rig's calibration.toml is drawn from the JSON calibrate-rig "
                             f"writes beside it: no {json_path.name}", source=path)
        path = json_path
    doc = _load_json(path)
    if not isinstance(doc, dict) or not ("mirror" in doc or "cameras" in doc):
        raise InputError("neither a mirrorgraph calibration.json nor a rig's JSON", source=path)
    motion = _read_motion(joints3d) if joints3d is not None else None
    if motion is not None and fps is None:
        fps = motion["fps"]
    if "cameras" in doc:
        if video is not None:
            raise InputError("draws the video of a single-mirror calibration, not of a rig",
                             field="video")
        kw = {} if motion is None else {k: motion[k] for k in ("joints3d", "valid", "frame_ids",
                                                               "joint_names")}
        scene = scene_from_rig(doc, fps=fps, **kw)
        return record(scene, save=save, max_video_frames=max_video_frames)
    from .result.mirror import read_calibration
    calib = read_calibration(path)
    keypoints = None
    run = _read_kept_run(path, calib)
    if motion is not None and run is not None \
            and np.array_equal(np.asarray(motion["frame_ids"]), run.paired.frame_ids):
        keypoints = (run.paired.real, run.paired.mirror)     # the same frames: their 2D
    if motion is None:
        if run is not None and run.joints3d is not None:
            motion = {"joints3d": run.joints3d, "valid": run.valid3d,
                      "frame_ids": run.paired.frame_ids, "joint_names": run.paired.skeleton.joints,
                      "fps": run.fps if run.fps else run.paired.fps,
                      "unit": "m" if calib.distance is not None else "mirror distance"}
            keypoints = (run.paired.real, run.paired.mirror)
            if fps is None:
                fps = motion["fps"]
    if motion is not None:
        if motion.get("unit") and calib.distance is not None and motion["unit"] != "m":
            raise InputError(f"the joints are in {motion['unit']!r}, the calibration in metres: "
                             "not the joints of this calibration", source=joints3d)
    scene = scene_from_calibration(
        calib, keypoints=keypoints, fps=fps,
        **({} if motion is None else {k: motion[k] for k in ("joints3d", "valid", "frame_ids",
                                                              "joint_names")}))
    if video is not None and not Path(video).is_file():
        raise InputError("no such video file", source=video)
    return record(scene, save=save, video=video, max_video_frames=max_video_frames)


def _read_kept_run(path: Path, calib):
    from .report.store import report_data_path, read_run
    kept = report_data_path(path)
    if not kept.is_file():
        return None
    try:
        return read_run(kept, calib)
    except InputError:
        return None


def _read_motion(path) -> dict[str, Any]:
    """A ``--joints3d`` ``.npz`` (:func:`mirrorgraph.io.motion.write_joints3d_npz`)."""
    path = Path(path)
    if path.suffix.lower() != ".npz":
        raise InputError("give the .npz of the 3D joints that a calibration writes (it holds "
                         "the joint names, the unit and the frame)", source=path)
    try:
        with np.load(path, allow_pickle=False) as z:
            d = {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise InputError("no such file", source=path) from None
    except (OSError, ValueError, EOFError) as exc:
        raise InputError(f"cannot be read as a .npz ({type(exc).__name__})", source=path) from None
    missing = [k for k in ("joints3d", "joint_names") if k not in d]
    if missing:
        raise InputError(f"missing {', '.join(missing)} (not a .npz of 3D joints?)",
                         source=path)
    X = d["joints3d"]
    fps = float(d["fps"]) if "fps" in d else float("nan")
    return {"joints3d": X, "valid": d.get("valid"), "frame_ids": d.get("frame_ids"),
            "joint_names": [str(n) for n in d["joint_names"]],
            "fps": fps if np.isfinite(fps) else None,
            "unit": str(d["unit"]) if "unit" in d else None}
