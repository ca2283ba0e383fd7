"""The data classes of the synthetic rigs of :mod:`.rig` (re-exported there).

:class:`SyntheticRig` (a rig's ground truth and detections), :class:`RigView`
(the ground truth of one view of a person in one camera), :class:`RigBystander`
and :func:`bystander_name`. World frame = camera 0's frame (``x`` right, ``y``
down, ``z`` forward), metres; image coordinates in pixels; the conventions are
in :mod:`.rig`'s docstring.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..intrinsics import Intrinsics
from ..keypoints import RawDetections
from ..skeletons import Skeleton
from .body import BodyModel
from ..geometry import reflect_points
from .rig_placement import PERSON
from .camera import project

__all__ = ["PERSON", "RigView", "RigBystander", "SyntheticRig", "bystander_name"]


@dataclass
class RigView:
    """Ground truth of one view of the person in one camera.

    Attributes:
        name: ``"person"`` (direct), a mirror name, or a double reflection
            (``"a>b"``, ``"a+b"``; see :mod:`.rig`); a bystander's views
            are named after them: ``"bystander1"`` (direct), ``"bystander1/wall"``,
            ``"bystander1/a+b"`` (:func:`bystander_name`).
        paths: the mirror sequences (as the ray from the camera meets them)
            that give this image: ``()`` direct, ``(("wall",),)`` a single
            reflection, ``(("a", "b"), ("b", "a"))`` a merged double one.
        flipped: the detector labels this view with left/right swapped (an
            odd number of reflections).
        clean: ``(T, J, 2)`` noise-free pixels, indexed by the *real* joint
            imaged; NaN where not visible.
        visible: ``(T, J)`` the joint is visible (see :mod:`.rig_placement`).
        detected: ``(T,)`` the view is among the camera's detections.
        observed: ``(T, J, 3)`` what the detector output for it (x, y,
            confidence; NaN/0 where missing), in real-joint labels.
        outliers: ``(T, J)`` observations replaced by a gross error.
        lr_swapped: ``(T,)`` frames where the detector kept the real labels on
            a single reflection (always False for other views).
    """

    name: str
    paths: tuple[tuple[str, ...], ...]
    flipped: bool
    clean: np.ndarray
    visible: np.ndarray
    detected: np.ndarray
    observed: np.ndarray
    outliers: np.ndarray
    lr_swapped: np.ndarray


@dataclass
class RigBystander:
    """Ground truth of one bystander of a rig (``make_rig(..., bystanders=N)``).

    Attributes:
        name: ``"bystander1"``, ``"bystander2"``, ...
        joints3d: ``(T, J, 3)`` their joints, world frame, metres (every frame,
            also where they are not in the room).
        height: their standing height, metres.
        present: ``(T,)`` frames in which they are in the room (detected only there).
        body: their individual body model (units of height).
    """

    name: str
    joints3d: np.ndarray
    height: float
    present: np.ndarray
    body: BodyModel | None = None


def bystander_name(bystander: str, view: str) -> str:
    """Name of a bystander's view: ``"bystander1"`` for :data:`PERSON` (direct), else
    ``"bystander1/<view>"`` (``view`` a mirror or a double reflection)."""
    return bystander if view == PERSON else f"{bystander}/{view}"


@dataclass
class SyntheticRig:
    """A synthetic multi-camera, multi-mirror recording: ground truth and detections.

    Frames and units: see :mod:`.rig` (world = camera 0's frame,
    metres, pixels; ``T`` frames, ``J`` joints of ``skeleton``).

    Attributes:
        kind: ``"1cam2mirrors"``, ``"2cams1mirror"`` or ``"4cams"``.
        skeleton: the keypoint layout.
        frame_ids: ``(T,)`` int frame numbers ``0 .. T-1`` (every camera).
        camera_names: ``["cam01", "cam02", ...]``; camera 0 defines the world.
        K: per camera, ``(3, 3)`` camera matrix (pixels, no distortion).
        image_size: ``(width, height)`` px, every camera.
        poses: per camera, ``(4, 4)`` camera-to-world ``[[R, C], [0, 1]]``;
            ``poses[0]`` is the identity.
        mirror_names: mirror names (empty for ``"4cams"``).
        mirrors: per mirror, ``(n (3,), d)``: the plane ``n . X = d`` in the
            world frame, ``n`` unit, pointing away from camera 0, ``d > 0`` m.
        sees: camera name -> names of the mirrors it sees, ordered by the ``x``
            component of their normals in that camera (the mirror on its left
            first, as ``rig.toml`` wants them); ``[]`` for none.
        joints3d: ``(T, J, 3)`` true joint positions, world frame, metres.
        subject_height: standing height of the person, metres.
        detections: camera name -> :class:`~mirrorgraph.keypoints.RawDetections`
            (``image_size`` and ``fps`` set): every view the camera detected,
            in random order per frame (see :mod:`.rig` for labels).
        options: every argument given to :func:`make_rig` (``bystanders`` only
            when there are some: rigs without them write no such key).
        fps: frame rate.
        seed: the seed.
        mirror_limits: mirror name -> list of ``(a (3,), b)``: the mirror's
            surface is the part of its plane where ``a . X <= b`` for each
            (world frame; empty for a whole wall).
        views: camera name -> view name -> :class:`RigView` (ground truth of
            each view, detected or not).
        detection_views: camera name -> per frame the view name of each row of
            ``detections[camera].people[t]`` (a bystander's rows: their view names,
            see :class:`RigView`).
        body: the individual body model (units of height).
        placement: how the rig was built: ``room_to_world`` ``(4, 4)`` (the
            construction frame, ``Y`` up, floor at ``Y = 0``), ``person_yaw_deg``,
            ``facing``, ``attempts`` and the per-kind numbers (distances,
            azimuths, heights); with bystanders also ``bystanders``: per
            bystander their distance from the subject, azimuth, yaw, first and
            last frame in the room and the attempts.
        bystanders: :class:`RigBystander` per bystander (empty by default).
    """

    kind: str
    skeleton: Skeleton
    frame_ids: np.ndarray
    camera_names: list[str]
    K: list[np.ndarray]
    image_size: tuple[int, int]
    poses: list[np.ndarray]
    mirror_names: list[str]
    mirrors: list[tuple[np.ndarray, float]]
    sees: dict[str, list[str]]
    joints3d: np.ndarray
    subject_height: float
    detections: dict[str, RawDetections]
    options: dict[str, Any] = field(default_factory=dict)
    fps: float = 30.0
    seed: Any = None
    mirror_limits: dict[str, list[tuple[np.ndarray, float]]] = field(default_factory=dict)
    views: dict[str, dict[str, RigView]] = field(default_factory=dict)
    detection_views: dict[str, list[tuple[str, ...]]] = field(default_factory=dict)
    body: BodyModel | None = None
    placement: dict[str, Any] = field(default_factory=dict)
    bystanders: list[RigBystander] = field(default_factory=list)

    def __len__(self) -> int:
        return int(self.joints3d.shape[0])

    def __repr__(self) -> str:
        return (f"SyntheticRig({self.kind}, {self.skeleton.name}, {len(self)} frames, "
                f"cameras {', '.join(self.camera_names)}, "
                f"mirrors {', '.join(self.mirror_names) or 'none'}, "
                f"subject {self.subject_height:.3f} m"
                + (f", {len(self.bystanders)} bystanders" if self.bystanders else "")
                + f", seed={self.seed})")

    def camera_index(self, camera: str | int) -> int:
        """Index of a camera given by name or index."""
        if isinstance(camera, str):
            return self.camera_names.index(camera)
        return int(camera)

    def mirror(self, name: str) -> tuple[np.ndarray, float]:
        """``(n, d)`` of a mirror, world frame."""
        return self.mirrors[self.mirror_names.index(name)]

    def world_to_camera(self, camera: str | int) -> tuple[np.ndarray, np.ndarray]:
        """``(R, t)`` with ``X_cam = R X + t`` (Pose2Sim's convention)."""
        P = self.poses[self.camera_index(camera)]
        R = P[:3, :3].T
        return R, -R @ P[:3, 3]

    def to_camera(self, camera: str | int, X: np.ndarray) -> np.ndarray:
        """World points ``(..., 3)`` in a camera's frame."""
        R, t = self.world_to_camera(camera)
        return X @ R.T + t

    def project(self, camera: str | int, X: np.ndarray) -> np.ndarray:
        """Pixels ``(..., 2)`` of world points ``(..., 3)`` in a camera."""
        return project(self.K[self.camera_index(camera)], self.to_camera(camera, X))

    def reflect(self, X: np.ndarray, mirror: str) -> np.ndarray:
        """``S(X)`` of world points ``(..., 3)`` in a mirror."""
        n, d = self.mirror(mirror)
        return reflect_points(X, n, d)

    def mirror_in_camera(self, camera: str | int, mirror: str) -> tuple[np.ndarray, float]:
        """The mirror plane in a camera's frame, ``n`` pointing away from that camera."""
        n, d = self.mirror(mirror)
        P = self.poses[self.camera_index(camera)]
        n_c = P[:3, :3].T @ n
        d_c = float(d - n @ P[:3, 3])
        return (n_c, d_c) if d_c > 0 else (-n_c, -d_c)

    def intrinsics(self, camera: str | int):
        """A camera's :class:`mirrorgraph.intrinsics.Intrinsics` (exact)."""
        return Intrinsics(K=self.K[self.camera_index(camera)].copy(), dist=None,
                          image_size=tuple(self.image_size), source="synthetic rig",
                          approximate=False)
