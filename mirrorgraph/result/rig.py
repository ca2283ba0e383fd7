"""The calibrated rig: cameras, mirrors, their uncertainties, and the JSON schema.

Frames and units: the world frame is the first camera's (x right, y down,
z forward). Lengths are metres with a subject height, else in units of the
subject's height (``scale = "unit_height"``). Camera poses are given both ways:
``pose`` camera-to-world ``(4, 4)``, and ``R``, ``t`` world-to-camera
(``X_cam = R X_world + t``, OpenCV / Pose2Sim). A mirror is ``n . X = d`` in the
world frame; its virtual camera for camera ``c`` is the camera reflected across
it (:func:`virtual_extrinsics`).
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .._version import __version__
from ..errors import InputError
from ..geometry import D_FLIP, householder
from ..intrinsics import Intrinsics

if TYPE_CHECKING:
    from .mirror import Calibration

__all__ = ["RigCamera", "RigMirror", "RigCalibration", "virtual_extrinsics",
           "read_rig_calibration", "write_rig_json", "is_rig_document"]

#: Names of the camera and the mirror of a single mirror seen as a rig
#: (:meth:`RigCalibration.from_mirror`).
SINGLE_CAMERA, SINGLE_MIRROR = "camera", "mirror"
#: Frames of the subject's path the rig JSON keeps (:meth:`RigCalibration.subject_path`).
SUBJECT_PATH_POINTS = 500


def virtual_extrinsics(pose: np.ndarray, normal: np.ndarray, distance: float
                       ) -> tuple[np.ndarray, np.ndarray]:
    """World-to-camera ``(R, t)`` of the camera of the horizontally *flipped* mirror view.

    The camera ``pose`` (camera-to-world ``(R_c, c_c)``) sees a world point ``X``
    in the mirror where it would see ``S(X) = H X + 2 d n``, i.e. at
    ``pi(K R_c^T (H X + 2 d n - c_c))``. Flipping the image (``u -> W - u``,
    :func:`mirrorgraph.export.flip_camera_matrix`) turns this left-handed camera
    into an ordinary one with ``R = D R_c^T H`` (a rotation: two reflections) and
    ``t = D R_c^T (2 d n - c_c)``. For ``pose = I`` this is
    :func:`mirrorgraph.geometry.virtual_camera_from_mirror`.
    """
    pose = np.asarray(pose, float)
    Rc, cc = pose[:3, :3], pose[:3, 3]
    n = np.asarray(normal, float)
    return D_FLIP @ Rc.T @ householder(n), D_FLIP @ Rc.T @ (2.0 * float(distance) * n - cc)


@dataclass
class RigCamera:
    """One calibrated camera.

    Attributes:
        name: camera name.
        intrinsics: its intrinsics (as given; keypoints were undistorted with them).
        pose: ``(4, 4)`` camera-to-world.
        rotation_std_deg: RMS rotation error (0 for the first camera): the figure that
            follows the data's error structure (time-correlated and per-joint detector
            error, :mod:`mirrorgraph.graph.uncertainty`), never below the marginal one.
        position_std: RMS error of the camera centre (length unit); with a subject
            height it includes the scale's uncertainty (``height_sigma``, the given
            height's relative std, of the distance to the first camera).
        reprojection_rms_px: RMS residual of its direct view.
        observations: keypoints of its direct view used in the final solve.
        lr_fixes: reflection frames whose labels were corrected.
        matched_frames: frames where another detection than the most confident one
            was taken as the person (cross-camera matching, several people in view).
        fit_share: the share of the keypoints its views (direct and through mirrors)
            offered the graph that the final solve kept within the outlier threshold.
        status: ``"ok"``, or ``"failed"``: under half of its keypoints fit the rig
            (:data:`mirrorgraph.rigs.failure.MIN_FIT_SHARE`), its pose is not to be used.
        reason: why it failed, in words (the likeliest cause), else ``""``.
        time_offset_frames: its time offset, the first camera's frames: at one frame
            rate its frame ``f`` is the first camera's frame ``f - time_offset_frames``
            (the rig file's ``frame_offset`` convention; fractional where found from
            the people, :mod:`mirrorgraph.rigs.clocks`); at another, its frame ``g`` is
            at ``g / fps - time_offset_s`` seconds of the first camera's clock.
        time_offset_std: its std, frames (0 for the first camera; NaN where taken as
            given).
        time_offset_source: ``"reference"``, ``"search"`` (the search's: the rig file's
            offset where the people do not significantly prefer another) or ``"given"``
            (not searched).
        time_offset_s, time_offset_s_std: the offset and its std in seconds (NaN where
            the frame rate is unknown).
        fps: its frame rate (its input's or the rig file's), NaN where unknown.
        clock_rate: its clock's rate against the first camera's (1 + drift; 1 where not
            estimated: the rig file's ``clock_drift``); its frame ``g`` at ``g /
            (fps clock_rate) - time_offset_s`` seconds.
        clock_rate_std: its std (NaN where not estimated).
    """

    name: str
    intrinsics: Intrinsics
    pose: np.ndarray
    rotation_std_deg: float
    position_std: float
    reprojection_rms_px: float
    observations: int
    lr_fixes: int = 0
    matched_frames: int = 0
    marginal_rotation_std_deg: float = float("nan")
    fit_share: float = float("nan")
    status: str = "ok"
    reason: str = ""
    time_offset_frames: float = 0.0
    time_offset_std: float = float("nan")
    time_offset_source: str = "given"
    time_offset_s: float = float("nan")
    time_offset_s_std: float = float("nan")
    fps: float = float("nan")
    clock_rate: float = 1.0
    clock_rate_std: float = float("nan")

    @property
    def failed(self) -> bool:
        """Whether the camera failed (``status == "failed"``)."""
        return self.status == "failed"

    @property
    def R(self) -> np.ndarray:
        """``(3, 3)`` world-to-camera rotation."""
        return self.pose[:3, :3].T

    @property
    def t(self) -> np.ndarray:
        """``(3,)`` world-to-camera translation."""
        return -self.pose[:3, :3].T @ self.pose[:3, 3]


@dataclass
class RigMirror:
    """One calibrated mirror.

    Attributes:
        name: mirror name.
        normal: ``(3,)`` unit normal, world frame (away from the world origin).
        distance: ``d`` of ``n . X = d`` (length unit).
        normal_cov: ``(3, 3)`` covariance of the normal (rad^2, rank 2).
        rotation_std_deg: RMS rotation error of its virtual cameras (2x the normal's),
            the robust figure as :attr:`RigCamera.rotation_std_deg`.
        distance_std: standard deviation of ``d`` (with the scale's uncertainty, as
            ``position_std``).
        seen_by: cameras that see it.
        views_rms_px: camera name -> RMS residual of that camera's view through it.
    """

    name: str
    normal: np.ndarray
    distance: float
    normal_cov: np.ndarray
    rotation_std_deg: float
    distance_std: float
    seen_by: list[str]
    views_rms_px: dict[str, float] = field(default_factory=dict)
    marginal_rotation_std_deg: float = float("nan")


@dataclass
class RigCalibration:
    """Everything :func:`mirrorgraph.pipelines.rig.calibrate_rig` found.

    Attributes:
        cameras, mirrors: the calibrated cameras and mirrors.
        scale: ``"subject_height"`` (metres) or ``"unit_height"`` (the subject is 1 tall).
        subject_height: metres, or ``None``.
        scale_source: how the height became a length of the rig (the stature
            measured on the joints, or limb proportions).
        skeleton: keypoint layout name.
        frame_ids: ``(T,)`` rig frames.
        joints3d: ``(T, J, 3)`` joints, world frame, length unit; NaN where unknown.
        valid: ``(T, J)`` bool.
        joints_std: ``(T, J)`` each joint's own uncertainty, the RMS length of its 3D
            error (the length unit; :mod:`mirrorgraph.graph.joints_uncertainty`, the
            metric scale's share included), NaN where unknown; ``None``: not computed
            (not kept in the JSON).
        people_joints3d: ``(P, T, J, 3)`` every person's joints (``--people all``; person 0
            is the one of ``joints3d``), NaN where unknown; ``None``: one person (not kept
            in the JSON; ``refinement["people"]`` says how many were used).
        people_valid: ``(P, T, J)`` bool; people_std: ``(P, T, J)`` as ``joints_std``.
        bone_lengths: bone -> length.
        initialisation: the pairwise edges, spanning tree and mirror sightings.
        refinement: iterations, rejected observations, priors, timings.
        sensitivity: per estimated camera and mirror, how it moves with each joint pair
            or video segment left out, each segment's information, the frames a target
            accuracy needs (:func:`mirrorgraph.graph.sensitivity.rig_sensitivity_report`).
        warnings: what the user should know.
        source: the rig file.
    """

    cameras: list[RigCamera]
    mirrors: list[RigMirror]
    scale: str
    subject_height: float | None
    skeleton: str
    frame_ids: np.ndarray
    joints3d: np.ndarray
    valid: np.ndarray
    bone_lengths: dict[str, float]
    initialisation: dict[str, Any]
    refinement: dict[str, Any]
    warnings: list[str] = field(default_factory=list)
    source: str = ""
    scale_source: str = ""
    sensitivity: dict[str, Any] = field(default_factory=dict)
    joints_std: np.ndarray | None = None
    people_joints3d: np.ndarray | None = None
    people_valid: np.ndarray | None = None
    people_std: np.ndarray | None = None

    @property
    def num_people(self) -> int:
        """People in the graph (1 without ``people_joints3d``)."""
        return 1 if self.people_joints3d is None else int(self.people_joints3d.shape[0])

    @property
    def failed_cameras(self) -> list[RigCamera]:
        """The cameras marked failed (:attr:`RigCamera.status`)."""
        return [c for c in self.cameras if c.failed]

    def camera(self, name: str) -> RigCamera:
        """The camera called ``name``."""
        return next(c for c in self.cameras if c.name == name)

    def mirror(self, name: str) -> RigMirror:
        """The mirror called ``name``."""
        return next(m for m in self.mirrors if m.name == name)

    # ------------------------------------------------------------ one mirror, one rig
    @classmethod
    def from_mirror(cls, calib: "Calibration") -> "RigCalibration":
        """A single mirror's calibration as the rig it is: one camera (the world frame,
        named ``"camera"``) and one mirror (``"mirror"``).

        Its numbers are the calibration's own: the camera at the identity with zero
        std (the world frame), the mirror's normal, distance, normal covariance and
        rotation std, the distance std (0 where the scale is unknown: the unit is the
        mirror distance), the reprojection RMS of both views. ``scale``: ``"subject_height"`` where the
        calibration has a distance (metres), else the single mirror's ``"unknown"``
        (lengths in mirror distances, ``distance = 1``). The 3D joints are not part of a calibration; they stay empty.
        """
        u = calib.uncertainty or {}
        ref = calib.refinement or {}
        unknown = calib.distance is None
        ncov = np.asarray(u.get("normal_cov", np.full((3, 3), np.nan)), float)
        nan = float("nan")
        camera = RigCamera(name=SINGLE_CAMERA, intrinsics=calib.intrinsics, pose=np.eye(4),
                           rotation_std_deg=0.0, position_std=0.0,
                           reprojection_rms_px=float(ref.get("rms_direct_px", nan)),
                           observations=int(calib.pairs_used), lr_fixes=int(calib.lr_fixes),
                           marginal_rotation_std_deg=0.0)
        dstd = u.get("distance_std")
        mirror = RigMirror(name=SINGLE_MIRROR, normal=np.asarray(calib.normal, float),
                           distance=1.0 if unknown else float(calib.distance), normal_cov=ncov,
                           rotation_std_deg=float(u.get("rotation_std_deg", nan)),
                           distance_std=0.0 if unknown else float(nan if dstd is None else dstd),
                           seen_by=[SINGLE_CAMERA],
                           views_rms_px={SINGLE_CAMERA: float(ref.get("rms_mirror_px", nan))},
                           marginal_rotation_std_deg=float(u.get("marginal_rotation_std_deg",
                                                                 nan)))
        height = (calib.input or {}).get("subject_height")
        return cls(cameras=[camera], mirrors=[mirror],
                   scale="unknown" if unknown else "subject_height",
                   subject_height=None if height is None else float(height),
                   skeleton=str((calib.input or {}).get("skeleton", "")),
                   frame_ids=np.arange(int(calib.frames_read)),
                   joints3d=np.zeros((0, 0, 3)), valid=np.zeros((0, 0), bool),
                   bone_lengths=dict(ref.get("bone_lengths") or {}), initialisation={},
                   refinement=dict(ref), warnings=list(calib.warnings),
                   source=str((calib.input or {}).get("source", "")),
                   scale_source=str(ref.get("scale_source", "")),
                   sensitivity=dict(calib.sensitivity or {}))

    def mirror_view(self, camera: str | None = None, mirror: str | None = None
                    ) -> "Calibration":
        """One camera and one mirror of the rig as a single mirror's calibration, in that
        camera's frame (the one-camera rig's view of itself).

        The plane ``n . X = d`` (world) is ``(R^T n) . X_c = d - n . c`` in the frame of
        the camera at ``pose = (R, c)``. Its covariance is rotated the same way; for a
        camera other than the first (the world frame) the camera's own rotation std is
        added in quadrature to the mirror's (independent errors assumed: the rig's joint
        covariance is not stored), so the figure does not understate it.

        Args:
            camera (str | None): the camera's name; default the first camera.
            mirror (str | None): the mirror's name; default the first mirror it sees.

        Raises:
            InputError: no such camera or mirror, or the camera does not see the mirror.
        """
        from .mirror import Calibration

        cam = self.cameras[0] if camera is None else next(
            (c for c in self.cameras if c.name == camera), None)
        if cam is None:
            raise InputError(f"no camera {camera!r} (cameras: "
                             f"{', '.join(c.name for c in self.cameras)})", field="camera")
        seen = [m for m in self.mirrors if cam.name in m.seen_by]
        mir = (seen[0] if seen else None) if mirror is None else next(
            (m for m in seen if m.name == mirror), None)
        if mir is None:
            raise InputError(f"camera {cam.name} sees no mirror "
                             f"{'' if mirror is None else repr(mirror)}".rstrip(), field="mirror")
        R, c = np.asarray(cam.pose, float)[:3, :3], np.asarray(cam.pose, float)[:3, 3]
        n_w = np.asarray(mir.normal, float)
        n, d = R.T @ n_w, float(mir.distance - n_w @ c)
        ncov = R.T @ np.asarray(mir.normal_cov, float) @ R
        rot = float(np.hypot(mir.rotation_std_deg, cam.rotation_std_deg))
        unknown = self.scale != "subject_height"
        uncertainty = {"normal_cov": ncov.tolist(), "rotation_std_deg": rot,
                       "distance_std": None if unknown else float(np.hypot(mir.distance_std,
                                                                           cam.position_std)),
                       "marginal_rotation_std_deg": float(np.hypot(
                           mir.marginal_rotation_std_deg, cam.marginal_rotation_std_deg)),
                       "source": f"the rig's mirror {mir.name} seen from camera {cam.name}"}
        return Calibration(normal=n, distance=None if unknown else d,
                           scale="subject_height" if not unknown else "unknown",
                           estimator="rig", intrinsics=cam.intrinsics, initial_normal=n.copy(),
                           refined=True, frames_read=int(len(self.frame_ids)),
                           pairs_used=int(cam.observations), lr_fixes=int(cam.lr_fixes),
                           input={"source": self.source, "skeleton": self.skeleton,
                                  "subject_height": self.subject_height,
                                  "rig": {"camera": cam.name, "mirror": mir.name}},
                           refinement={"rms_direct_px": cam.reprojection_rms_px,
                                       "rms_mirror_px": mir.views_rms_px.get(cam.name),
                                       "scale_source": self.scale_source},
                           uncertainty=uncertainty, warnings=list(self.warnings))

    def subject_path(self, max_points: int = SUBJECT_PATH_POINTS) -> dict[str, list]:
        """The subject's path for the JSON (and the report drawn from it): the mean of
        the estimated joints of at most ``max_points`` frames spread over the video,
        ``{"frames": [...], "xyz": [[x, y, z], ...]}`` (world frame, length unit; frames
        without a joint left out)."""
        return _mean_path(self.joints3d, self.valid, self.frame_ids, max_points)

    def people_paths(self, max_points: int = SUBJECT_PATH_POINTS) -> list[dict[str, list]]:
        """Every person's path as :meth:`subject_path` (person 0's is the subject's); an
        empty list for one person (no ``people_joints3d``)."""
        if self.people_joints3d is None:
            return []
        return [_mean_path(X, ok, self.frame_ids, max_points)
                for X, ok in zip(self.people_joints3d, self.people_valid)]

    def to_dict(self) -> dict[str, Any]:
        """The rig JSON schema (plain Python types)."""

        unit = "m" if self.scale == "subject_height" else "subject heights"
        return {
            "mirrorgraph_version": __version__,
            "world_frame": f"camera {self.cameras[0].name} (x right, y down, z forward)",
            "scale": self.scale, "length_unit": unit, "subject_height": self.subject_height,
            "scale_source": self.scale_source,
            "skeleton": self.skeleton,
            "cameras": [{
                "name": c.name, "pose_camera_to_world": c.pose.tolist(),
                "R": c.R.tolist(), "t": c.t.tolist(),
                "convention": "X_camera = R X_world + t",
                "intrinsics": c.intrinsics.to_dict(),
                "uncertainty": {"rotation_std_deg": c.rotation_std_deg,
                                "position_std": c.position_std,
                                "marginal_rotation_std_deg": c.marginal_rotation_std_deg},
                "reprojection_rms_px": c.reprojection_rms_px,
                "observations": c.observations, "lr_fixes": c.lr_fixes,
                "matched_frames": c.matched_frames,
                "fit_share": c.fit_share, "status": c.status,
                "reason": c.reason or None,
                "time_offset_frames": c.time_offset_frames,
                "time_offset_std": c.time_offset_std,
                "time_offset_source": c.time_offset_source,
                "time_offset_s": c.time_offset_s,
                "time_offset_s_std": c.time_offset_s_std,
                "fps": c.fps,
                "clock_rate": c.clock_rate,
                "clock_rate_std": c.clock_rate_std,
            } for c in self.cameras],
            "mirrors": [{
                "name": m.name, "normal": np.asarray(m.normal).tolist(), "distance": m.distance,
                "plane": "n.X = distance, world frame",
                "uncertainty": {"normal_cov": np.asarray(m.normal_cov).tolist(),
                                "rotation_std_deg": m.rotation_std_deg,
                                "distance_std": m.distance_std,
                                "marginal_rotation_std_deg": m.marginal_rotation_std_deg},
                "seen_by": list(m.seen_by), "reprojection_rms_px": dict(m.views_rms_px),
            } for m in self.mirrors],
            "bone_lengths": dict(self.bone_lengths),
            "frames": int(len(self.frame_ids)),
            "subject_path": self.subject_path(),
            **({"people_paths": self.people_paths()} if self.people_joints3d is not None
               else {}),
            "initialisation": self.initialisation,
            "refinement": self.refinement,
            "sensitivity": self.sensitivity,
            "warnings": list(self.warnings),
            "source": self.source,
        }

    def summary(self) -> str:
        """A few lines for people."""
        unit = "m" if self.scale == "subject_height" else "heights"
        lines = []
        for c in self.cameras:
            pos = c.pose[:3, 3]
            if c.failed:
                lines.append(f"camera {c.name:<10} FAILED: {c.reason}")
                continue
            lines.append(f"camera {c.name:<10} centre [{pos[0]:+.3f}, {pos[1]:+.3f}, "
                         f"{pos[2]:+.3f}] {unit}  rot std {c.rotation_std_deg:.3f} deg  "
                         f"pos std {c.position_std:.4f} {unit}  rms {c.reprojection_rms_px:.2f} px"
                         + _time_offset(c))
        for m in self.mirrors:
            n = m.normal
            lines.append(f"mirror {m.name:<10} normal [{n[0]:+.4f}, {n[1]:+.4f}, {n[2]:+.4f}] "
                         f"d {m.distance:.4f} {unit}  rot std {m.rotation_std_deg:.3f} deg")
        people = (self.refinement or {}).get("people") or {}
        if people.get("mode") == "all" and "found" in people:
            lines.append(f"people: {people.get('count')} in the one graph (every person in "
                         f"view; {people.get('found')} associated across the cameras)")
        lines.append("scale: " + (f"subject height {self.subject_height:g} m"
                                  + (f" ({self.scale_source})" if self.scale_source else "")
                                  if self.scale == "subject_height"
                                  else "unknown (lengths in subject heights; pass "
                                       "subject_height or --subject-height for metres)"))
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)


def _mean_path(joints3d, valid, frame_ids, max_points: int) -> dict[str, list]:
    """``{"frames", "xyz"}``: the mean of the valid joints ``(T, J, 3)`` of at most
    ``max_points`` frames spread over ``T``, frames without a joint left out."""
    J = np.asarray(joints3d, float)
    if J.ndim != 3 or not J.size:
        return {"frames": [], "xyz": []}
    rows = np.unique(np.linspace(0, len(J) - 1, min(max_points, len(J))).round().astype(int))
    X = np.where(np.asarray(valid, bool)[rows, :, None], J[rows], np.nan)
    seen = np.isfinite(X).all(-1).any(1)
    mean = np.nansum(np.nan_to_num(X[seen]), axis=1) / np.isfinite(X[seen]).all(-1).sum(1)[:, None]
    frames = np.asarray(frame_ids)[rows[seen]]
    return {"frames": [int(f) for f in frames], "xyz": mean.round(5).tolist()}


def _time_offset(c: RigCamera) -> str:
    """The summary's words on a camera's time offset: ``""`` for the reference."""
    if c.time_offset_source == "reference":
        return ""
    secs = f" ({1000 * c.time_offset_s:+.1f} ms)" if np.isfinite(c.time_offset_s) else ""
    rate = (f", clock rate 1 {c.clock_rate - 1:+.1e} +- {c.clock_rate_std:.1e}"
            if np.isfinite(c.clock_rate_std) else "")
    if c.time_offset_source == "search":
        return (f"  time offset {c.time_offset_frames:+.2f} +- {c.time_offset_std:.2f} "
                f"frames{secs}{rate}")
    return f"  time offset {c.time_offset_frames:+g} frames{secs} (given)"


def is_rig_document(obj: Any) -> bool:
    """Whether a parsed JSON document is a rig's (:meth:`RigCalibration.to_dict`: a list of
    ``cameras`` and of ``mirrors``) rather than a single mirror's ``calibration.json``."""
    return (isinstance(obj, Mapping) and isinstance(obj.get("cameras"), list)
            and isinstance(obj.get("mirrors"), list))


def read_rig_calibration(calibration: "RigCalibration | Mapping | str | os.PathLike"
                         ) -> RigCalibration:
    """A :class:`RigCalibration` from the rig JSON (:meth:`RigCalibration.to_dict`).

    The cameras (intrinsics, pose, stds) and mirrors are checked and read; the reports
    (``initialisation``, ``refinement``, ``sensitivity``, ``warnings``) are taken as
    written. The JSON holds no 3D joints: ``joints3d`` comes back ``(k, 1, 3)``, the
    subject's path (:meth:`RigCalibration.subject_path`) on its ``k`` frames
    (``frame_ids``), and ``people_joints3d`` ``(P, k, 1, 3)`` every person's where the
    JSON has them (:meth:`RigCalibration.people_paths`), NaN on frames a path leaves out.

    Raises:
        InputError: unreadable file or a missing / malformed field, naming both.
    """
    from .mirror import read_intrinsics_section
    from ..io._common import load_json, numeric_array

    if isinstance(calibration, RigCalibration):
        return calibration
    if isinstance(calibration, (str, os.PathLike)):
        src: str | None = str(calibration)
        obj = load_json(calibration)
    else:
        src, obj = None, calibration
    if not is_rig_document(obj):
        raise InputError("not a rig calibration (no lists of cameras and mirrors)",
                         source=src, field="cameras")

    def num(v, ndim, where, shape):
        a = numeric_array(v, ndim, source=src, frame=None, field=where)
        if a.shape != shape or not np.isfinite(a).all():
            raise InputError(f"expected finite numbers of shape {shape}, got {a.shape}",
                             source=src, field=where)
        return a

    def fnum(v, where):
        try:
            return float("nan") if v is None else float(v)
        except (TypeError, ValueError):
            raise InputError(f"expected a number, got {v!r}", source=src, field=where) from None

    cameras = []
    for i, c in enumerate(obj["cameras"]):
        at = f"cameras[{i}]"
        if not isinstance(c, Mapping) or "name" not in c:
            raise InputError("expected an object with a name", source=src, field=at)
        u = c.get("uncertainty") or {}
        cameras.append(RigCamera(
            name=str(c["name"]), intrinsics=read_intrinsics_section(c.get("intrinsics") or {}, src),
            pose=num(c.get("pose_camera_to_world"), 2, f"{at}.pose_camera_to_world", (4, 4)),
            rotation_std_deg=fnum(u.get("rotation_std_deg"), f"{at}.uncertainty"),
            position_std=fnum(u.get("position_std"), f"{at}.uncertainty"),
            marginal_rotation_std_deg=fnum(u.get("marginal_rotation_std_deg"),
                                           f"{at}.uncertainty"),
            reprojection_rms_px=fnum(c.get("reprojection_rms_px"), f"{at}.reprojection_rms_px"),
            observations=int(c.get("observations") or 0), lr_fixes=int(c.get("lr_fixes") or 0),
            matched_frames=int(c.get("matched_frames") or 0),
            fit_share=fnum(c.get("fit_share"), f"{at}.fit_share"),
            status=str(c.get("status") or "ok"), reason=str(c.get("reason") or ""),
            time_offset_frames=fnum(c.get("time_offset_frames", 0.0), f"{at}.time_offset_frames"),
            time_offset_std=fnum(c.get("time_offset_std"), f"{at}.time_offset_std"),
            time_offset_source=str(c.get("time_offset_source") or "given"),
            time_offset_s=fnum(c.get("time_offset_s"), f"{at}.time_offset_s"),
            time_offset_s_std=fnum(c.get("time_offset_s_std"), f"{at}.time_offset_s_std"),
            fps=fnum(c.get("fps"), f"{at}.fps"),
            clock_rate=fnum(c.get("clock_rate", 1.0), f"{at}.clock_rate"),
            clock_rate_std=fnum(c.get("clock_rate_std"), f"{at}.clock_rate_std")))
    mirrors = []
    for i, m in enumerate(obj["mirrors"]):
        at = f"mirrors[{i}]"
        if not isinstance(m, Mapping) or "name" not in m:
            raise InputError("expected an object with a name", source=src, field=at)
        u = m.get("uncertainty") or {}
        normal = num(m.get("normal"), 1, f"{at}.normal", (3,))
        cov = numeric_array(u.get("normal_cov", np.full((3, 3), np.nan).tolist()), 2,
                            source=src, frame=None, field=f"{at}.uncertainty.normal_cov")
        mirrors.append(RigMirror(
            name=str(m["name"]), normal=normal / np.linalg.norm(normal),
            distance=fnum(m.get("distance"), f"{at}.distance"), normal_cov=cov,
            rotation_std_deg=fnum(u.get("rotation_std_deg"), f"{at}.uncertainty"),
            distance_std=fnum(u.get("distance_std"), f"{at}.uncertainty"),
            marginal_rotation_std_deg=fnum(u.get("marginal_rotation_std_deg"),
                                           f"{at}.uncertainty"),
            seen_by=[str(x) for x in m.get("seen_by") or []],
            views_rms_px={str(k): fnum(v, f"{at}.reprojection_rms_px")
                          for k, v in (m.get("reprojection_rms_px") or {}).items()}))
    if not cameras:
        raise InputError("no cameras", source=src, field="cameras")
    height = obj.get("subject_height")
    # the 3D joints are not in the JSON: the paths stand for them (one "joint" a person)
    def read_path(sp, where):
        if not isinstance(sp, Mapping):
            raise InputError("expected an object with frames and xyz", source=src, field=where)
        xyz = numeric_array(sp.get("xyz") or np.zeros((0, 3)).tolist(), 2, source=src,
                            frame=None, field=f"{where}.xyz").reshape(-1, 3)
        frames = np.asarray(sp.get("frames") or [], dtype=np.int64)
        if len(frames) != len(xyz):
            raise InputError(f"{len(frames)} frames for {len(xyz)} points", source=src,
                             field=where)
        return frames, xyz

    paths = [read_path(obj.get("subject_path") or {}, "subject_path")]
    people = obj.get("people_paths")
    if people is not None and not isinstance(people, list):
        raise InputError("expected a list of paths", source=src, field="people_paths")
    paths += [read_path(sp, f"people_paths[{k}]") for k, sp in enumerate(people or [])]
    frame_ids = np.unique(np.concatenate([f for f, _ in paths]))
    on_frames = np.full((len(paths), len(frame_ids), 1, 3), np.nan)
    for k, (frames, xyz) in enumerate(paths):
        on_frames[k, np.searchsorted(frame_ids, frames), 0] = xyz
    path_valid = np.isfinite(on_frames).all(-1)
    return RigCalibration(
        cameras=cameras, mirrors=mirrors, scale=str(obj.get("scale", "unit_height")),
        subject_height=None if height is None else fnum(height, "subject_height"),
        skeleton=str(obj.get("skeleton", "")), frame_ids=frame_ids,
        joints3d=on_frames[0], valid=path_valid[0],
        people_joints3d=on_frames[1:] if people else None,
        people_valid=path_valid[1:] if people else None,
        bone_lengths={str(k): float(v) for k, v in (obj.get("bone_lengths") or {}).items()},
        initialisation=dict(obj.get("initialisation") or {}),
        refinement=dict(obj.get("refinement") or {}),
        warnings=[str(w) for w in obj.get("warnings") or []], source=str(obj.get("source", "")),
        scale_source=str(obj.get("scale_source", "")),
        sensitivity=dict(obj.get("sensitivity") or {}))


def write_rig_json(calib: RigCalibration, path: str | os.PathLike) -> None:
    """Write the rig JSON (:meth:`RigCalibration.to_dict`), atomically."""
    from ..io.calibration import write_json

    write_json(path, calib.to_dict())

