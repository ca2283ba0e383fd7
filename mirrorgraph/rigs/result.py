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

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._version import __version__
from ..geometry import D_FLIP, householder
from ..intrinsics import Intrinsics

__all__ = ["RigCamera", "RigMirror", "RigCalibration", "virtual_extrinsics"]


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
            height it includes the scale's uncertainty (``height_sigma``, 2 %, of the
            distance to the first camera: the subject's proportions vs Winter's).
        reprojection_rms_px: RMS residual of its direct view.
        observations: keypoints of its direct view used in the final solve.
        lr_fixes: reflection frames whose labels were corrected.
        matched_frames: frames where another detection than the most confident one
            was taken as the person (cross-camera matching, several people in view).
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
    """Everything :func:`mirrorgraph.rigs.calibrate_rig` found.

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

    def camera(self, name: str) -> RigCamera:
        """The camera called ``name``."""
        return next(c for c in self.cameras if c.name == name)

    def mirror(self, name: str) -> RigMirror:
        """The mirror called ``name``."""
        return next(m for m in self.mirrors if m.name == name)

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
            lines.append(f"camera {c.name:<10} centre [{pos[0]:+.3f}, {pos[1]:+.3f}, "
                         f"{pos[2]:+.3f}] {unit}  rot std {c.rotation_std_deg:.3f} deg  "
                         f"pos std {c.position_std:.4f} {unit}  rms {c.reprojection_rms_px:.2f} px")
        for m in self.mirrors:
            n = m.normal
            lines.append(f"mirror {m.name:<10} normal [{n[0]:+.4f}, {n[1]:+.4f}, {n[2]:+.4f}] "
                         f"d {m.distance:.4f} {unit}  rot std {m.rotation_std_deg:.3f} deg")
        lines.append("scale: " + (f"subject height {self.subject_height:g} m"
                                  + (f" ({self.scale_source})" if self.scale_source else "")
                                  if self.scale == "subject_height"
                                  else "unknown (lengths in subject heights; pass "
                                       "subject_height or --subject-height for metres)"))
        lines += [f"warning: {w}" for w in self.warnings]
        return "\n".join(lines)
