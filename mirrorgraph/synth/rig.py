"""Synthetic rigs of several cameras and mirrors, with ground truth.

The test and benchmark data of ``mirrorgraph calibrate-rig RIG.toml``: the
person of :mod:`mirrorgraph.synth` (an individual body, :mod:`.body`, doing the
procedural exercises of :mod:`.motion`: moving, stepping and turning up to
+-70 deg) is filmed by one or more cameras, directly and in one or two planar
mirrors. :func:`make_rig` builds the rig and simulates the pose detector of
each camera; :func:`write_rig` writes what a user of ``calibrate-rig`` would
have (keypoints, an intrinsics file, ``rig.toml``) next to the ground truth;
:func:`read_rig_ground_truth` reads the ground truth back.

Frames, units and conventions
-----------------------------
* World frame = camera 0's frame: ``x`` right, ``y`` down, ``z`` forward,
  metres. Camera poses are camera-to-world ``(4, 4)`` matrices ``[[R, C], [0, 1]]``
  (``R`` the camera's axes in world coordinates, ``C`` its centre): a world
  point ``X`` is ``R^T (X - C)`` in the camera's frame. Camera 0's pose is the
  identity.
* A mirror is the plane ``n . X = d`` in the world frame, ``n`` a unit vector
  pointing away from camera 0, so ``d > 0`` is camera 0's distance to it. Its
  reflective side is ``n . X < d`` (the side of the room, where the cameras and
  the person are). In the frame of another camera ``i`` the same plane is
  ``n_i = R_i^T n``, ``d_i = d - n . C_i``; since every camera that sees the
  mirror stands on its reflective side, ``d_i > 0`` there too
  (:meth:`SyntheticRig.mirror_in_camera` gives the plane oriented away from any
  camera, flipping the sign where a camera is on the far side). The reflection
  is ``S(X) = X - 2 (n . X - d) n``.
* Images: pinhole cameras without distortion, ``fx = fy = (w / 2) / tan(fov / 2)``
  (``fov`` horizontal), principal point within +-4 px of the centre (drawn
  per camera, as in :mod:`.scene`); pixel origin at the top-left corner.
* Time: frames ``0 .. T-1`` at ``fps`` (30), every camera synchronised
  (``frame_offset = 0``).

The rigs (a *room frame* with ``Y`` up is used to build them; every number
below is drawn uniformly from the range given, from the seed):

``"4cams"``
    No mirror. Four cameras around the person at azimuths ``a0 + 90 k + (+-10)``
    deg (``a0`` any), 3-5 m from the centre of the person's motion, 1.0-1.6 m
    high, looking at that centre (the middle of the motion's vertical extent)
    with +-5 cm of aim jitter and +-2 deg of roll. The person faces any way.
    Each camera is redrawn until it sees the whole person in at least 90 % of
    the frames.
``"2cams1mirror"``
    A wall mirror (the whole wall, vertical) named ``"wall"``. The person
    stands 1.3-2.2 m in front of it, facing it (60 %) or the cameras (40 %),
    +-20 deg. Two cameras on the person's side, 3-5 m from the person, 1.0-1.6 m
    high, at azimuths (around the person, from the mirror's normal) 40-90 deg
    apart, each 15-60 deg off the normal (so the reflection is not hidden
    behind the person), each aimed between the person and the reflection.
``"1cam2mirrors"``
    Two mirrors meeting at a vertical edge with an interior angle of
    ``corner_angle_deg`` (default 90: the two walls of a room corner; 60-140),
    named ``"mirror_left"`` and ``"mirror_right"`` as the camera sees them.
    Each is a half-plane bounded by the edge (a point of one mirror is on the
    reflective side of the other), floor to ceiling. The person stands 2.0-2.6
    m from the edge, 5-12 deg off the bisector, facing the camera or the corner
    (50 % each, +-25 deg); the camera stands 3.5-4.5 m further from the edge,
    3-8 deg off the bisector on the other side (so that the double reflection,
    the person turned about the edge, is not hidden behind the person),
    1.0-1.6 m high, aimed at the middle of the person and both reflections.
    With ``double_reflections=True`` the double reflections (the ray meets one
    mirror, then the other) are detected too: at 90 deg both orders give the
    same virtual person, one view named ``"mirror_left+mirror_right"``; at
    other angles two views ``"mirror_left>mirror_right"`` (seen in
    ``mirror_left``, which shows ``mirror_right``) and
    ``"mirror_right>mirror_left"``. Above 90 deg they are rarely visible (as in
    a real corner of two mirrors); below it, reflections of three and more
    bounces exist physically but are not generated.

In the mirror rigs the placement is redrawn until each camera sees the whole
person in at least 90 % of the frames and the whole of each single reflection
it sees in at least 75 %, the torsos (shoulders and hips) of the person and of
each single reflection do not overlap horizontally in the image in at least
90 % of the frames, and every joint stays 0.2 m in front of every mirror.
(``double_reflections`` has no effect on the other kinds.)

Visibility of a joint in a view (direct, or through a sequence of mirrors):

* direct: at least 0.5 m in front of the camera and projecting inside the
  image (``0 <= u <= w - 1``, ``0 <= v <= h - 1``);
* through mirrors: the camera and the joint are on the reflective side of each
  mirror on the path, the ray from the camera to the virtual point meets each
  mirror on its surface (inside the half-plane of a corner mirror) in order,
  and the virtual point is at least 0.5 m in front of the camera and projects
  inside the image;
* a view (the person, a reflection) is detected in a frame only with at least
  5 visible joints; hidden joints are missing (NaN, confidence 0). Occlusion of
  one view by another is not modelled.

Bystanders (``bystanders=N``, default none): other people near the subject,
the common case of a gym or a dance studio, where everyone in front of the
mirror has a reflection too. Each has their own body (:func:`.body.make_body`),
motion (:func:`.motion.generate_motion`) and height (1.55-1.95 m), faces any
way, and is in the room for one stretch of 40-80 % of the frames (so the
subject is the person seen longest). Their motion's centre is 1-2.5 m from the
subject's, in a direction at least 30 deg from every mirror's normal (a
bystander straight behind the subject along the normal would lie on the
subject's epipolar lines), at least 0.2 m in front of every mirror and 1 m
(horizontally) from every camera. A camera *sees* a bystander when it sees
them whole, directly and in each of its mirrors, in at least half of their
frames: every camera with a mirror and at least half of the cameras must, and
where a camera sees them their torso is apart from the subject's (direct and
single reflections, as above) in at least 80 % of their frames (each draw of
up to 1000 is checked; a ``ValueError`` when none passes). They are detected
by the same detector model, directly and through every mirror, wherever
visible; their views are named ``"bystander1"``, ``"bystander1/wall"``, ...
(:attr:`SyntheticRig.views`, :attr:`SyntheticRig.detection_views`), their truth
is in :attr:`SyntheticRig.bystanders`. They draw from their own generator
(``default_rng([seed, 1])``): with the same seed the rig, the subject and the
subject's detections are those without bystanders.

Detector model (that of :mod:`.scene`, per camera): Gaussian noise of
``noise_std`` px per coordinate (zero mean), outliers, confidences, missing
people and joints as in :func:`mirrorgraph.synth.make_scene`; coordinates
clipped to the image. A single reflection is labelled the way the detector
sees it: anatomically, so its left/right labels are swapped
(:attr:`~mirrorgraph.skeletons.Skeleton.flip`: the detection's ``left_wrist``
images the real right wrist), except in a fraction ``lr_swap_rate`` of the
frames (per camera and mirror) where the detector keeps the real joints'
labels. A double reflection is a proper (rotated) image: its labels are those
of the real joints. People are listed per frame in random order.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..keypoints import RawDetections
from ..skeletons import Skeleton, skeleton_by_name
from .body import BodyModel, make_body, skeleton_points
from .motion import generate_motion
from .scene import _camera_matrix, _observe, _rot_y, _rot_z, check_camera_args, project
from .writer import load_ground_truth_joints

__all__ = ["KINDS", "RigView", "RigBystander", "SyntheticRig", "make_rig", "write_rig",
           "read_rig_ground_truth", "bystander_name"]

#: The rig kinds :func:`make_rig` builds.
KINDS = ("1cam2mirrors", "2cams1mirror", "4cams")

_Z_MIN = 0.5            # m: nearest a visible point may be to the camera plane
_MIRROR_GAP = 0.2       # m: nearest a joint may come to a mirror
_MIN_JOINTS = 5         # visible joints for a view to be detected in a frame
_PERSON_FULL = 0.90     # fraction of frames each camera must see the whole person
_REFLECTION_FULL = 0.75  # ... and the whole of each single reflection it sees
_APART = 0.90          # ... and the torsos of any two of these apart in the image
_MAX_ATTEMPTS = 300
_BYSTANDER_DISTANCE = (1.0, 2.5)   # m: a bystander's motion centre from the subject's
_BYSTANDER_PRESENT = (0.4, 0.8)    # fraction of the frames a bystander is in the room
_BYSTANDER_FULL = 0.5    # ... of which each camera sees them whole, directly and in each mirror
_BYSTANDER_APART = 0.8   # ... and their torso apart from the subject's views
_BYSTANDER_NORMAL_DEG = 30.0   # least angle between their offset and a mirror's normal
_BYSTANDER_CAMERA_GAP = 1.0    # m: nearest (horizontally) a bystander may stand to a camera
_BYSTANDER_ATTEMPTS = 1000     # placements drawn per bystander
_UP = np.array([0.0, 1.0, 0.0])
_DEG = np.pi / 180.0

PERSON = "person"

JOINTS3D_NAME = "joints3d.npz"
GROUND_TRUTH_NAME = "ground_truth.json"
RIG_NAME = "rig.toml"
CALIB_NAME = "Calib.toml"
_KEYPOINT_FORMATS = ("openpose", "easymocap", "mmpose")


# --------------------------------------------------------------------------- containers
@dataclass
class RigView:
    """Ground truth of one view of the person in one camera.

    Attributes:
        name: ``"person"`` (direct), a mirror name, or a double reflection
            (``"a>b"``, ``"a+b"``; see the module docstring); a bystander's views
            are named after them: ``"bystander1"`` (direct), ``"bystander1/wall"``,
            ``"bystander1/a+b"`` (:func:`bystander_name`).
        paths: the mirror sequences (as the ray from the camera meets them)
            that give this image: ``()`` direct, ``(("wall",),)`` a single
            reflection, ``(("a", "b"), ("b", "a"))`` a merged double one.
        flipped: the detector labels this view with left/right swapped (an
            odd number of reflections).
        clean: ``(T, J, 2)`` noise-free pixels, indexed by the *real* joint
            imaged; NaN where not visible.
        visible: ``(T, J)`` the joint is visible (see the module docstring).
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

    Frames and units: see the module docstring (world = camera 0's frame,
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
            in random order per frame (see the module docstring for labels).
        options: every argument given to :func:`make_rig` (``bystanders`` only
            when there are some: rigs without them are written as before).
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
        return _reflect(X, n, d)

    def mirror_in_camera(self, camera: str | int, mirror: str) -> tuple[np.ndarray, float]:
        """The mirror plane in a camera's frame, ``n`` pointing away from that camera."""
        n, d = self.mirror(mirror)
        P = self.poses[self.camera_index(camera)]
        n_c = P[:3, :3].T @ n
        d_c = float(d - n @ P[:3, 3])
        return (n_c, d_c) if d_c > 0 else (-n_c, -d_c)

    def intrinsics(self, camera: str | int):
        """A camera's :class:`mirrorgraph.intrinsics.Intrinsics` (exact)."""
        from ..intrinsics import Intrinsics
        return Intrinsics(K=self.K[self.camera_index(camera)].copy(), dist=None,
                          image_size=tuple(self.image_size), source="synthetic rig",
                          approximate=False)


# --------------------------------------------------------------------------- geometry
def _reflect(X: np.ndarray, n: np.ndarray, d: float) -> np.ndarray:
    return X - 2.0 * ((X @ n) - d)[..., None] * n


def _look_at(C: np.ndarray, target: np.ndarray, roll: float) -> np.ndarray:
    """Camera-to-room rotation (columns: camera x right, y down, z forward), room ``Y`` up."""
    z = target - C
    z = z / np.linalg.norm(z)
    x = np.cross(z, _UP)
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    return np.column_stack([x, y, z]) @ _rot_z(roll)


@dataclass
class _Mirror:
    name: str
    n: np.ndarray                      # room frame, pointing out of the room
    d: float
    limits: list[tuple[np.ndarray, float]] = field(default_factory=list)


@dataclass
class _Camera:
    C: np.ndarray                      # centre, room frame
    R: np.ndarray                      # camera-to-room rotation
    sees: list[str]


def _path_visible(C: np.ndarray, X: np.ndarray, path: tuple[_Mirror, ...]
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Virtual points ``(..., 3)`` of ``X`` seen from ``C`` through ``path`` and
    whether the light path exists (the mirrors met in order, on their surfaces)."""
    virt = X
    for m in reversed(path):
        virt = _reflect(virt, m.n, m.d)
    ok = np.ones(X.shape[:-1], dtype=bool)
    start = np.broadcast_to(C, X.shape)
    target = virt
    for m in path:
        s_side = start @ m.n - m.d                     # < 0: reflective side
        v_side = target @ m.n - m.d                    # > 0: behind the mirror
        ok &= (s_side < 0.0) & (v_side > 0.0)
        denom = np.where(ok, v_side - s_side, 1.0)
        lam = np.clip(-s_side / denom, 0.0, 1.0)
        hit = start + lam[..., None] * (target - start)
        for a, b in m.limits:
            ok &= hit @ a <= b
        start = hit
        target = _reflect(target, m.n, m.d)            # continue toward the next image
    return virt, ok


def _project_visible(cam: _Camera, K: np.ndarray, size: tuple[int, int], V: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    Xc = (V - cam.C) @ cam.R
    front = Xc[..., 2] >= _Z_MIN
    uv = project(K, np.where(front[..., None], Xc, 1.0))
    w, h = size
    inside = front & (uv[..., 0] >= 0.0) & (uv[..., 0] <= w - 1.0) \
        & (uv[..., 1] >= 0.0) & (uv[..., 1] <= h - 1.0)
    return uv, inside


def _camera_views(cam: _Camera, K: np.ndarray, size: tuple[int, int], X: np.ndarray,
                  mirrors: dict[str, _Mirror], double: bool
                  ) -> list[tuple[str, tuple[tuple[str, ...], ...], bool, np.ndarray, np.ndarray]]:
    """``(name, paths, flipped, clean (T, J, 2), visible (T, J))`` of every view."""
    out = []
    uv, vis = _project_visible(cam, K, size, X)
    out.append((PERSON, (), False, uv, vis))
    for name in cam.sees:
        V, ok = _path_visible(cam.C, X, (mirrors[name],))
        uv, vis = _project_visible(cam, K, size, V)
        out.append((name, ((name,),), True, uv, vis & ok))
    if double and len(cam.sees) >= 2:
        pairs = [(a, b) for i, a in enumerate(cam.sees) for b in cam.sees[i + 1:]]
        for a, b in pairs:
            Vab, ok_ab = _path_visible(cam.C, X, (mirrors[a], mirrors[b]))
            Vba, ok_ba = _path_visible(cam.C, X, (mirrors[b], mirrors[a]))
            if np.allclose(Vab, Vba, rtol=0.0, atol=1e-9):
                uv, vis = _project_visible(cam, K, size, Vab)
                out.append((f"{a}+{b}", ((a, b), (b, a)), False, uv, vis & (ok_ab | ok_ba)))
            else:
                for (p, q), V, ok in (((a, b), Vab, ok_ab), ((b, a), Vba, ok_ba)):
                    uv, vis = _project_visible(cam, K, size, V)
                    out.append((f"{p}>{q}", ((p, q),), False, uv, vis & ok))
    return out


def _motion_centre(X: np.ndarray) -> np.ndarray:
    """Horizontal mean and the middle of the vertical extent of a motion ``(T, J, 3)``."""
    flat = X.reshape(-1, 3)
    c = flat.mean(0)
    c[1] = 0.5 * (flat[:, 1].min() + flat[:, 1].max())
    return c


def _aim_between(C: np.ndarray, points: list[np.ndarray], height: float) -> np.ndarray:
    """A target that centres the horizontal angles of ``points`` seen from ``C``."""
    ang = np.array([np.arctan2(p[0] - C[0], p[2] - C[2]) for p in points])
    ref = ang[0]
    rel = np.angle(np.exp(1j * (ang - ref)))
    mid = ref + 0.5 * (rel.min() + rel.max())
    dist = np.mean([np.hypot(p[0] - C[0], p[2] - C[2]) for p in points])
    return np.array([C[0] + dist * np.sin(mid), height, C[2] + dist * np.cos(mid)])


def _full_fraction(vis: np.ndarray) -> float:
    return float(vis.all(-1).mean())


def _apart_fraction(uv1: np.ndarray, uv2: np.ndarray, torso: np.ndarray) -> float:
    """Fraction of frames whose two views' torsos (shoulders and hips) do not
    overlap horizontally in the image."""
    x1, x2 = uv1[:, torso, 0], uv2[:, torso, 0]
    return float(((x1.max(1) < x2.min(1)) | (x2.max(1) < x1.min(1))).mean())


def _gap_ok(X: np.ndarray, mirrors: dict[str, _Mirror]) -> bool:
    """Every joint at least ``_MIRROR_GAP`` in front of every mirror."""
    return all(float((X @ m.n - m.d).max()) <= -_MIRROR_GAP for m in mirrors.values())


def _person(local: np.ndarray, H: float, yaw: float, origin: np.ndarray) -> np.ndarray:
    return (local @ _rot_y(yaw).T) * H + origin


def _sample_camera(rng, centre: np.ndarray, azimuth: float, dist: float) -> np.ndarray:
    h = rng.uniform(1.0, 1.6)
    return np.array([centre[0] + dist * np.sin(azimuth), h, centre[2] + dist * np.cos(azimuth)])


def _roll(rng) -> float:
    return float(np.radians(np.clip(rng.normal(0.0, 1.0), -2.0, 2.0)))


def _build_4cams(rng, local, H, Ks, size):
    yaw = rng.uniform(-np.pi, np.pi)
    X = _person(local, H, yaw, np.zeros(3))
    centre = _motion_centre(X)
    a0 = rng.uniform(-np.pi, np.pi)
    cams, info = [], dict(azimuth_deg=[], distance_m=[], height_m=[], camera_attempts=[])
    for k in range(4):
        for attempt in range(_MAX_ATTEMPTS):
            az = a0 + k * np.pi / 2 + np.radians(rng.uniform(-10.0, 10.0))
            dist = rng.uniform(3.0, 5.0)
            C = _sample_camera(rng, centre, az, dist)
            target = centre + rng.uniform(-0.05, 0.05, 3)
            cam = _Camera(C=C, R=_look_at(C, target, _roll(rng)), sees=[])
            _, vis = _project_visible(cam, Ks[k], size, X)
            if _full_fraction(vis) >= _PERSON_FULL:
                break
        else:
            return None
        cams.append(cam)
        info["azimuth_deg"].append(float(np.degrees(az)))
        info["distance_m"].append(float(dist))
        info["height_m"].append(float(C[1]))
        info["camera_attempts"].append(attempt + 1)
    return X, cams, {}, dict(info, person_yaw_deg=float(np.degrees(yaw)), facing="any")


def _build_2cams1mirror(rng, local, H):
    wall = _Mirror("wall", np.array([0.0, 0.0, 1.0]), 0.0)
    mirrors = {"wall": wall}
    dp = rng.uniform(1.3, 2.2)
    origin = np.array([rng.uniform(-0.3, 0.3), 0.0, -dp])
    sep = rng.uniform(40.0, 90.0)
    mid = rng.uniform(-15.0, 15.0)
    psi = np.radians([mid - sep / 2, mid + sep / 2])
    if np.any(np.abs(np.degrees(psi)) < 15.0) or np.any(np.abs(np.degrees(psi)) > 60.0):
        return None
    dists = rng.uniform(3.0, 5.0, 2)
    facing = "mirror" if rng.random() < 0.6 else "cameras"
    # room -Z points from the wall into the room; body z forward = room Z at yaw 0
    base = 0.0 if facing == "mirror" else np.pi - float(np.mean(psi))
    yaw = base + np.radians(rng.uniform(-20.0, 20.0))
    X = _person(local, H, yaw, origin)
    if not _gap_ok(X, mirrors):
        return None
    centre = _motion_centre(X)
    refl = _reflect(centre, wall.n, wall.d)
    cams = []
    for k in range(2):
        # azimuth psi around the person, from the normal into the room (-Z)
        C = _sample_camera(rng, centre, np.pi - psi[k], dists[k])
        target = _aim_between(C, [centre, refl], centre[1]) + rng.uniform(-0.05, 0.05, 3)
        cams.append(_Camera(C=C, R=_look_at(C, target, _roll(rng)), sees=["wall"]))
    info = dict(person_to_mirror_m=float(dp), camera_azimuth_deg=np.degrees(psi).tolist(),
                camera_separation_deg=float(sep), distance_m=dists.tolist(),
                height_m=[float(c.C[1]) for c in cams], person_yaw_deg=float(np.degrees(yaw)),
                facing=facing)
    return X, cams, mirrors, info


def _build_1cam2mirrors(rng, local, H, alpha):
    h = alpha / 2.0
    # the corner edge is the room's Y axis; the bisector runs into the room along -Z
    nA = np.array([np.cos(h), 0.0, np.sin(h)])       # the wall toward +X (camera's left)
    nB = np.array([-np.cos(h), 0.0, np.sin(h)])
    A = _Mirror("mirror_left", nA, 0.0, [(nB, 0.0)])
    B = _Mirror("mirror_right", nB, 0.0, [(nA, 0.0)])
    mirrors = {"mirror_left": A, "mirror_right": B}
    rp = rng.uniform(2.0, 2.6)
    beta = np.radians(rng.uniform(5.0, 12.0)) * rng.choice([-1.0, 1.0])
    origin = np.array([rp * np.sin(beta), 0.0, -rp * np.cos(beta)])
    # the camera off the bisector on the other side: the double reflection (the
    # person turned about the edge) then does not hide behind the person
    gamma = -np.sign(beta) * np.radians(rng.uniform(3.0, 8.0))
    rc = rp + rng.uniform(3.5, 4.5)
    facing = "camera" if rng.random() < 0.5 else "corner"
    to_corner = np.arctan2(-origin[0], -origin[2])   # body z forward toward the edge
    base = to_corner if facing == "corner" else to_corner + np.pi
    yaw = base + np.radians(rng.uniform(-25.0, 25.0))
    X = _person(local, H, yaw, origin)
    if not _gap_ok(X, mirrors):
        return None
    centre = _motion_centre(X)
    C = np.array([rc * np.sin(gamma), rng.uniform(1.0, 1.6), -rc * np.cos(gamma)])
    pts = [centre, _reflect(centre, nA, 0.0), _reflect(centre, nB, 0.0)]
    target = _aim_between(C, pts, centre[1]) + rng.uniform(-0.05, 0.05, 3)
    cam = _Camera(C=C, R=_look_at(C, target, _roll(rng)), sees=["mirror_left", "mirror_right"])
    info = dict(corner_angle_deg=float(np.degrees(alpha)), person_to_edge_m=float(rp),
                person_off_bisector_deg=float(np.degrees(beta)), camera_to_edge_m=float(rc),
                camera_off_bisector_deg=float(np.degrees(gamma)), height_m=[float(C[1])],
                person_yaw_deg=float(np.degrees(yaw)), facing=facing)
    return X, [cam], mirrors, info


# --------------------------------------------------------------------------- bystanders
def _main_views(views: list) -> list:
    """The direct view and the single reflections of a :func:`_camera_views` list."""
    return [v for v in views if not v[1] or len(v[1][0]) == 1]


def _presence(rng, T: int) -> np.ndarray:
    """``(T,)`` bool: one contiguous stretch of :data:`_BYSTANDER_PRESENT` of the frames."""
    n = min(T, max(1, int(round(rng.uniform(*_BYSTANDER_PRESENT) * T))))
    start = int(rng.integers(0, T - n + 1))
    present = np.zeros(T, dtype=bool)
    present[start:start + n] = True
    return present


def _place_bystander(rng, local: np.ndarray, H: float, X_subject: np.ndarray,
                     cams: list, Ks: list, size: tuple[int, int], mirrors: dict,
                     double: bool, present: np.ndarray, others: list, torso: np.ndarray):
    """Room-frame joints ``(T, J, 3)`` of a bystander, their views per camera and the
    placement numbers, or ``None`` when no placement passes the checks of the
    module docstring in :data:`_BYSTANDER_ATTEMPTS` draws.

    ``others``: per camera, the subject's main views (direct and single
    reflections, :func:`_camera_views` tuples) that the bystander must not overlap.
    """
    centre = _motion_centre(X_subject)
    normals = [m.n for m in mirrors.values()]
    cos_max = np.cos(np.radians(_BYSTANDER_NORMAL_DEG))
    for attempt in range(_BYSTANDER_ATTEMPTS):
        dist = rng.uniform(*_BYSTANDER_DISTANCE)
        az = rng.uniform(-np.pi, np.pi)
        yaw = rng.uniform(-np.pi, np.pi)
        offset = np.array([np.sin(az), 0.0, np.cos(az)])
        if any(abs(offset @ n) > cos_max for n in normals):
            continue           # in line with a mirror's normal: on the subject's epipolar lines
        X = _person(local, H, yaw, np.zeros(3))
        shift = centre + dist * offset - _motion_centre(X)      # their centre there, on the floor
        shift[1] = 0.0
        X = X + shift
        if not _gap_ok(X, mirrors):
            continue
        here = _motion_centre(X)
        if any(np.hypot(*(here - c.C)[[0, 2]]) < _BYSTANDER_CAMERA_GAP for c in cams):
            continue
        views, ok, seen_by = [], True, 0
        for cam, K, other in zip(cams, Ks, others):
            vs = _camera_views(cam, K, size, X, mirrors, double)
            vs = [(n, paths, flipped, uv, vis & present[:, None])
                  for n, paths, flipped, uv, vis in vs]
            main = _main_views(vs)
            seen = all(_full_fraction(v[4][present]) >= _BYSTANDER_FULL for v in main)
            ok = (seen or not cam.sees) and (not seen or all(
                _apart_fraction(v[3][present], o[3][present], torso) >= _BYSTANDER_APART
                for v in main for o in other))
            if not ok:
                break
            seen_by += seen
            views.append(vs)
        if ok and seen_by >= len(cams) / 2:
            info = dict(distance_m=float(dist), azimuth_deg=float(np.degrees(az)),
                        yaw_deg=float(np.degrees(yaw)), attempts=attempt + 1)
            return X, views, info
    return None


def _bystander_rng(seed) -> np.random.Generator:
    """The bystanders' own generator: the subject's draws stay those without them."""
    return np.random.default_rng() if seed is None else np.random.default_rng([seed, 1])


def _make_bystanders(rng, count: int, skel: Skeleton, fps: float, cams: list, Ks: list,
                     size: tuple[int, int], X_subject: np.ndarray, mirrors: dict,
                     double: bool, subject_views: list, torso: np.ndarray) -> list:
    """``count`` bystanders in the room frame: per bystander ``(name, (X (T, J, 3), height,
    present (T,), body), views per camera (named by :func:`bystander_name`), placement)``.

    Raises:
        ValueError: a bystander cannot be placed (see the module docstring).
    """
    T = X_subject.shape[0]
    others = [_main_views(vs) for vs in subject_views]
    out = []
    for k in range(count):
        name = f"bystander{k + 1}"
        body = make_body(rng)
        local = skeleton_points(generate_motion(body, T, fps, rng), skel)
        H = float(rng.uniform(1.55, 1.95))
        present = _presence(rng, T)
        placed = _place_bystander(rng, local, H, X_subject, cams, Ks, size, mirrors, double,
                                  present, others, torso)
        if placed is None:
            raise ValueError(f"cannot place {name} near the subject, seen by the cameras "
                             "and apart from the subject; try another seed or a wider field "
                             "of view")
        X, views, info = placed
        info.update(name=name, height_m=H, first_frame=int(np.argmax(present)),
                    last_frame=int(T - 1 - np.argmax(present[::-1])))
        views = [[(bystander_name(name, v[0]),) + tuple(v[1:]) for v in vs] for vs in views]
        out.append((name, (X, H, present, body), views, info))
    return out


def _detect(rng, views: list, size: tuple[int, int], noise_std: float, outlier_rate: float,
            missing_rate: float, lr_swap_rate: float, flip: np.ndarray,
            joint_bias_px: float = 0.0, rng_bias: np.random.Generator | None = None
            ) -> tuple[list[np.ndarray], dict[str, RigView], np.ndarray]:
    """The detector on one camera's views of one person (:func:`_camera_views` list).

    With ``joint_bias_px`` every view and joint also gets a constant offset (the
    detector's systematic error, as :func:`mirrorgraph.synth.make_scene`'s), and the
    Gaussian noise comes from ``rng_bias`` too (the subject's other draws unchanged).

    Returns:
        per view the ``(T, J, 3)`` detections with the detector's labels, the
        :class:`RigView` per view name, and ``(V, T)`` detected.
    """
    V = len(views)
    T = views[0][3].shape[0]
    clean = np.stack([v[3] for v in views])                    # (V, T, J, 2)
    visible = np.stack([v[4] for v in views])                  # (V, T, J)
    filled = np.where(visible[..., None], clean, 0.0)
    obs, miss, outl, detected = _observe(rng, filled, size, 0.0, noise_std,
                                         outlier_rate, missing_rate, 0.0, 0.0,
                                         joint_bias_px, rng_bias)
    detected &= visible.sum(-1) >= _MIN_JOINTS
    miss |= ~visible
    detected &= ~miss.all(-1)
    miss |= ~detected[..., None]
    outl &= ~miss
    obs[miss] = (np.nan, np.nan, 0.0)
    swapped = np.zeros((V, T), dtype=bool)
    rows_by_view, cam_views = [], {}
    for i, (vname, paths, flipped, _, _) in enumerate(views):
        if flipped:
            swapped[i] = (rng.random(T) < lr_swap_rate) & detected[i]
            labelled = np.where(swapped[i][:, None, None], obs[i], obs[i][:, flip])
        else:
            labelled = obs[i]
        rows_by_view.append(labelled)
        cam_views[vname] = RigView(
            name=vname, paths=paths, flipped=flipped,
            clean=np.where(visible[i][..., None], clean[i], np.nan), visible=visible[i],
            detected=detected[i], observed=obs[i], outliers=outl[i],
            lr_swapped=swapped[i])
    return rows_by_view, cam_views, detected


# --------------------------------------------------------------------------- make_rig
def make_rig(kind: str, *, frames: int = 300, seed: int | None = 0,
             skeleton: str | Skeleton = "BODY_25", noise_std: float = 4.0,
             subject_height: float | None = None, outlier_rate: float = 0.0,
             missing_rate: float = 0.0, lr_swap_rate: float = 0.0,
             double_reflections: bool = False, image_size: tuple[int, int] = (1920, 1080),
             fov_deg: float = 60.0, fps: float = 30.0, corner_angle_deg: float = 90.0,
             bystanders: int = 0, joint_bias_px: float = 0.0) -> SyntheticRig:
    """Generate a synthetic rig (see the module docstring for the geometry and model).

    Args:
        kind: ``"1cam2mirrors"``, ``"2cams1mirror"`` or ``"4cams"``.
        frames: number of frames ``T`` (>= 1).
        seed: seed of :func:`numpy.random.default_rng`; the same seed gives
            identical rigs.
        skeleton: keypoint layout or its name (``BODY_25``, ``COCO_17``, ``COCO_18``).
        noise_std: Gaussian detector noise per coordinate, px (zero mean).
        subject_height: metres (``None``: uniform 1.55-1.95).
        outlier_rate: fraction of observations replaced by gross errors (30-150 px).
        missing_rate: fraction of joint observations missing (beyond the hidden ones).
        lr_swap_rate: fraction of frames, per camera and mirror, whose single
            reflection the detector labels with the real joints' labels.
        double_reflections: also detect double reflections (``"1cam2mirrors"``).
        image_size: ``(width, height)`` px, every camera.
        fov_deg: horizontal field of view, degrees, every camera.
        fps: frame rate.
        corner_angle_deg: interior angle between the two mirrors of
            ``"1cam2mirrors"`` (60-140; 90 = the two walls of a room corner).
        bystanders: other people near the subject, each with their reflections
            (see the module docstring). Drawn from their own generator
            (``default_rng([seed, 1])``): the subject's detections, the rig and
            the truth are those of ``bystanders=0`` with the same seed, only
            the bystanders' rows are added (interleaved at random).
        joint_bias_px: standard deviation (px) of a constant offset per camera view
            and joint, the same in every frame: a detector's systematic error,
            which more frames do not average out. Drawn with the Gaussian noise
            from ``default_rng([seed, 2])``; 0 (default) keeps every output as before.

    Raises:
        ValueError: an unknown kind, an option out of range, or no placement
            found (a field of view too narrow for the rig).
    """
    options = dict(kind=kind, frames=frames, seed=seed,
                   skeleton=skeleton if isinstance(skeleton, str) else skeleton.name,
                   noise_std=noise_std, subject_height=subject_height,
                   outlier_rate=outlier_rate, missing_rate=missing_rate,
                   lr_swap_rate=lr_swap_rate, double_reflections=bool(double_reflections),
                   image_size=list(image_size), fov_deg=fov_deg, fps=fps,
                   corner_angle_deg=corner_angle_deg)
    if bystanders:
        options["bystanders"] = int(bystanders)       # absent by default: files as before
    if joint_bias_px:
        options["joint_bias_px"] = float(joint_bias_px)
    if kind not in KINDS:
        raise ValueError(f"unknown rig kind {kind!r}; known: {', '.join(KINDS)}")
    T, w, h = check_camera_args(frames, image_size, fov_deg, fps, noise_std)
    for name, v in (("outlier_rate", outlier_rate), ("lr_swap_rate", lr_swap_rate),
                    ("missing_rate", missing_rate)):
        if not 0.0 <= v <= 1.0:
            raise ValueError(f"{name} must be in [0, 1], got {v}")
    if subject_height is not None and not subject_height > 0:
        raise ValueError(f"subject_height must be positive, got {subject_height}")
    if not 60.0 <= corner_angle_deg <= 140.0:
        raise ValueError(f"corner_angle_deg must be in [60, 140], got {corner_angle_deg}")
    if not joint_bias_px >= 0:
        raise ValueError(f"joint_bias_px must be >= 0, got {joint_bias_px}")
    if int(bystanders) != bystanders or bystanders < 0:
        raise ValueError(f"bystanders must be a non-negative integer, got {bystanders}")
    skel = skeleton_by_name(skeleton) if isinstance(skeleton, str) else skeleton
    J = skel.num_joints
    size = (w, h)
    n_cams = {"1cam2mirrors": 1, "2cams1mirror": 2, "4cams": 4}[kind]
    names = [f"cam{i + 1:02d}" for i in range(n_cams)]

    rng = np.random.default_rng(seed)
    Ks = [_camera_matrix(rng, size, fov_deg) for _ in range(n_cams)]
    body = make_body(rng)
    local = skeleton_points(generate_motion(body, T, fps, rng), skel)
    H = float(subject_height) if subject_height is not None else float(rng.uniform(1.55, 1.95))

    torso = np.array([skel.index(f"{s}_{j}") for s in ("left", "right")
                      for j in ("shoulder", "hip")])

    # ------------------------------------------------------------- placement (room frame)
    built = None
    for attempt in range(_MAX_ATTEMPTS):
        if kind == "4cams":
            built = _build_4cams(rng, local, H, Ks, size)
        elif kind == "2cams1mirror":
            built = _build_2cams1mirror(rng, local, H)
        else:
            built = _build_1cam2mirrors(rng, local, H, np.radians(corner_angle_deg))
        if built is None:
            continue
        X_r, cams, mirrors_r, info = built
        views_r = [_camera_views(c, K, size, X_r, mirrors_r, double_reflections)
                   for c, K in zip(cams, Ks)]
        ok = True
        for vs in views_r:
            main = [v for v in vs if v[0] == PERSON or len(v[1][0]) == 1]
            for name, _, _, uv, vis in main:
                ok &= _full_fraction(vis) >= (_PERSON_FULL if name == PERSON
                                              else _REFLECTION_FULL)
            for i, a in enumerate(main):
                for b in main[i + 1:]:
                    ok &= _apart_fraction(a[3], b[3], torso) >= _APART
        if ok:
            break
        built = None
    if built is None:
        raise ValueError(f"cannot build a {kind!r} rig in which every camera sees the person "
                         f"(and the reflections) with a {fov_deg:g} deg field of view in "
                         f"{w}x{h} images; try a wider field of view")
    info["attempts"] = attempt + 1
    rng_b = _bystander_rng(seed)
    extra = _make_bystanders(rng_b, int(bystanders), skel, fps, cams, Ks, size, X_r,
                             mirrors_r, double_reflections, views_r, torso)
    if extra:
        info["bystanders"] = [b[3] for b in extra]

    # ------------------------------------------------------------- to camera 0's frame
    R0, C0 = cams[0].R, cams[0].C
    room_to_world = np.eye(4)
    room_to_world[:3, :3] = R0.T
    room_to_world[:3, 3] = -R0.T @ C0
    joints3d = (X_r - C0) @ R0
    poses = []
    for c in cams:
        P = np.eye(4)
        P[:3, :3] = R0.T @ c.R
        P[:3, 3] = R0.T @ (c.C - C0)
        poses.append(P)
    poses[0] = np.eye(4)
    mirror_names = list(mirrors_r)
    mirrors, limits = [], {}
    for name in mirror_names:
        m = mirrors_r[name]
        n_w = R0.T @ m.n
        d_w = float(m.d - m.n @ C0)        # > 0: camera 0 is on the reflective side
        mirrors.append((n_w, d_w))
        limits[name] = [(R0.T @ a, float(b - a @ C0)) for a, b in m.limits]
    sees = {}
    for cname, c, P in zip(names, cams, poses):
        xs = [(P[:3, :3].T @ mirrors[mirror_names.index(m)][0])[0] for m in c.sees]
        sees[cname] = [c.sees[i] for i in np.argsort(xs, kind="stable")]

    # ------------------------------------------------------------- detector
    flip = skel.flip
    detect = dict(size=size, noise_std=noise_std, outlier_rate=outlier_rate,
                  missing_rate=missing_rate, lr_swap_rate=lr_swap_rate, flip=flip,
                  joint_bias_px=float(joint_bias_px),
                  rng_bias=np.random.default_rng([0 if seed is None else seed, 2])
                  if joint_bias_px else None)
    detections, views, det_views = {}, {}, {}
    for c, (cname, vs) in enumerate(zip(names, views_r)):
        rows_by_view, cam_views, detected = _detect(rng, vs, **detect)
        groups = [np.flatnonzero(d) for d in detected]
        vnames = [v[0] for v in vs]
        keys = [rng.random(sum(len(g) for g in groups))]         # random order per frame
        for bname, _, bviews, _ in extra:                        # after the subject's draws
            b_rows, b_views, b_detected = _detect(rng_b, bviews[c], **detect)
            b_groups = [np.flatnonzero(d) for d in b_detected]
            rows_by_view += b_rows
            cam_views.update(b_views)
            groups += b_groups
            vnames += [v[0] for v in bviews[c]]
            keys.append(rng_b.random(sum(len(g) for g in b_groups)))
        row_frame = np.concatenate(groups)
        row_view = np.concatenate([np.full(len(g), i) for i, g in enumerate(groups)])
        order = np.lexsort((np.concatenate(keys), row_frame))
        allrows = np.concatenate([rows_by_view[i][g] for i, g in enumerate(groups)])[order]
        vnames = np.array(vnames, dtype=object)[row_view[order]]
        splits = np.cumsum(np.bincount(row_frame, minlength=T))[:-1]
        people = np.split(allrows.reshape(-1, J, 3), splits)
        det_views[cname] = [tuple(x) for x in np.split(vnames, splits)]
        detections[cname] = RawDetections(
            skeleton=skel, frame_ids=np.arange(T, dtype=np.int64), people=people,
            source=f"synthetic-rig({kind}, seed={seed}):{cname}", format="synthetic",
            image_size=size, fps=float(fps))
        views[cname] = cam_views

    placement = dict(info, room_to_world=room_to_world)
    truth = [RigBystander(name=bname, joints3d=(Xb - C0) @ R0, height=Hb, present=present,
                          body=bbody) for bname, (Xb, Hb, present, bbody), _, _ in extra]
    return SyntheticRig(
        kind=kind, skeleton=skel, frame_ids=np.arange(T, dtype=np.int64), camera_names=names,
        K=Ks, image_size=size, poses=poses, mirror_names=mirror_names, mirrors=mirrors,
        sees=sees, joints3d=joints3d, subject_height=H, detections=detections,
        options=options, fps=float(fps), seed=seed, mirror_limits=limits, views=views,
        detection_views=det_views, body=body, placement=placement, bystanders=truth)


# --------------------------------------------------------------------------- writing
def _keypoints_path(camera: str, fmt: str) -> str:
    return f"pose/{camera}.json" if fmt == "mmpose" else f"pose/{camera}_json"


def _rig_toml(rig: SyntheticRig, fmt: str, include_height: bool) -> str:
    """The text of ``rig.toml`` (arrays of tables written here: the package's TOML
    writer does not do them; every value goes through its ``format_value``)."""
    from ..io.toml_writer import format_value

    lines = [f"# synthetic {rig.kind} rig (mirrorgraph.synth.make_rig, seed {rig.seed}); "
             "paths relative to this file", ""]
    if include_height:
        lines += [f"subject_height = {format_value(float(rig.subject_height))}", ""]
    for name in rig.camera_names:
        entry: dict[str, Any] = dict(name=name, keypoints=_keypoints_path(name, fmt),
                                     intrinsics=CALIB_NAME, intrinsics_section=name,
                                     skeleton=rig.skeleton.name)
        if rig.sees[name]:
            entry["mirrors"] = list(rig.sees[name])
        entry["frame_offset"] = 0
        lines.append("[[cameras]]")
        lines += [f"{k} = {format_value(v)}" for k, v in entry.items()]
        lines.append("")
    for name in rig.mirror_names:
        lines += ["[[mirrors]]", f"name = {format_value(name)}", ""]
    return "\n".join(lines).rstrip("\n") + "\n"


def write_rig(rig: SyntheticRig, out_dir: str | os.PathLike, fmt: str = "openpose", *,
              include_height: bool = True) -> Path:
    """Write a rig as a user of ``mirrorgraph calibrate-rig`` would have it, with the truth.

    Writes into ``out_dir``:

    ========================  ==========================================================
    ``pose/<camera>_json/``   each camera's detections (``fmt`` ``"openpose"`` or
                              ``"easymocap"``); ``pose/<camera>.json`` for ``"mmpose"``
    ``Calib.toml``            every camera's intrinsics, Pose2Sim's format, one section
                              per camera named after it; rotation and translation are
                              zero (the extrinsics are what is to be found)
    ``rig.toml``              the rig file (``subject_height`` only with
                              ``include_height``)
    ``ground_truth.json``     kind, skeleton, subject height, camera poses
                              (camera-to-world and Pose2Sim's world-to-camera
                              ``rvec``/``tvec``), mirrors, what each camera sees
    ``joints3d.npz``          ``joints3d`` (T, J, 3) world metres, ``frame_ids``,
                              ``joint_names``; with bystanders also
                              ``bystanders_joints3d`` (B, T, J, 3)
    ========================  ==========================================================

    With bystanders ``ground_truth.json`` also lists them (``bystanders``: name,
    height, the frames they are in the room); their detections are in the
    keypoint files with the subject's, as a detector would give them.

    Returns:
        the path of ``rig.toml``.
    """
    from ..io import write_keypoints
    from ..io.atomic import atomic_path, atomic_write_text
    from ..io.calibration import write_json
    from ..io.camera_toml import TomlCamera, rotation_to_rodrigues, write_camera_toml

    if fmt not in _KEYPOINT_FORMATS:
        raise ValueError(f"unknown keypoint format {fmt!r}; known: "
                         f"{', '.join(_KEYPOINT_FORMATS)}")
    out = Path(out_dir)
    (out / "pose").mkdir(parents=True, exist_ok=True)
    for name in rig.camera_names:
        write_keypoints(rig.detections[name], out / _keypoints_path(name, fmt), fmt)

    write_camera_toml(
        out / CALIB_NAME,
        [TomlCamera(key=name, name=name, matrix=K, distortions=np.zeros(4),
                    size=tuple(rig.image_size)) for name, K in zip(rig.camera_names, rig.K)],
        "pose2sim",
        header="Intrinsics of the cameras of a synthetic rig (mirrorgraph.synth.write_rig).\n"
               "rotation and translation are placeholders (zero): the extrinsics are unknown.")

    extra = {}
    if rig.bystanders:                              # only then: rigs without them as before
        extra["bystanders_joints3d"] = np.stack([b.joints3d for b in rig.bystanders])
    with atomic_path(out / JOINTS3D_NAME) as tmp:
        with open(tmp, "wb") as f:
            np.savez_compressed(f, joints3d=rig.joints3d,
                                frame_ids=np.asarray(rig.frame_ids, dtype=np.int64),
                                joint_names=np.array(rig.skeleton.joints), **extra)

    cameras = []
    for name, K, P in zip(rig.camera_names, rig.K, rig.poses):
        R, t = rig.world_to_camera(name)
        cameras.append({
            "name": name, "K": K, "image_size": list(rig.image_size),
            "camera_to_world": P, "R": R, "rvec": rotation_to_rodrigues(R), "tvec": t,
            "centre": P[:3, 3], "sees": list(rig.sees[name]),
            "keypoints": _keypoints_path(name, fmt),
            "frames_detected": {v.name: int(v.detected.sum())
                                for v in rig.views[name].values()},
        })
    mirrors = [{"name": name, "normal": n, "distance": d,
                "limits": [{"a": a, "b": b} for a, b in rig.mirror_limits.get(name, [])]}
               for name, (n, d) in zip(rig.mirror_names, rig.mirrors)]
    gt = {
        "kind": rig.kind,
        "skeleton": rig.skeleton.name,
        "subject_height": rig.subject_height,
        "frames": len(rig),
        "fps": rig.fps,
        "seed": rig.seed,
        "world": "camera 0's frame (x right, y down, z forward), metres; camera_to_world "
                 "maps camera to world coordinates; R, rvec, tvec: X_cam = R X + tvec "
                 "(Pose2Sim); mirror n . X = d, n pointing away from camera 0",
        "cameras": cameras,
        "mirrors": mirrors,
        "options": rig.options,
        "placement": rig.placement,
        "joints3d": JOINTS3D_NAME,
    }
    if rig.bystanders:
        gt["bystanders"] = [{"name": b.name, "height": b.height,
                             "frames_present": np.flatnonzero(b.present).tolist(),
                             "joints3d": f"{JOINTS3D_NAME}:bystanders_joints3d[{i}]"}
                            for i, b in enumerate(rig.bystanders)]
    write_json(out / GROUND_TRUTH_NAME, gt)
    rig_path = out / RIG_NAME
    atomic_write_text(rig_path, _rig_toml(rig, fmt, include_height))
    return rig_path


def read_rig_ground_truth(path: str | os.PathLike) -> dict[str, Any]:
    """Read a rig's ``ground_truth.json`` (or the folder holding it, or its ``rig.toml``).

    Returns:
        the JSON content plus NumPy arrays: ``camera_names`` (list),
        ``poses`` (C, 4, 4) camera-to-world, ``K`` (C, 3, 3), ``R`` (C, 3, 3) and
        ``tvec`` (C, 3) world-to-camera, ``rvec`` (C, 3), ``mirror_names``
        (list), ``normals`` (M, 3), ``distances`` (M,), ``sees`` (camera ->
        mirror names), ``joints3d`` (T, J, 3), ``frame_ids`` (T,),
        ``joint_names`` (J,), ``image_size`` (tuple); for a rig with bystanders
        also ``bystanders_joints3d`` (B, T, J, 3).
    """
    from ..io.calibration import read_json

    p = Path(path)
    if p.is_dir():
        p = p / GROUND_TRUTH_NAME
    elif p.suffix.lower() == ".toml":
        p = p.parent / GROUND_TRUTH_NAME
    gt = read_json(p)
    out = dict(gt)
    cams = gt["cameras"]
    out["camera_names"] = [c["name"] for c in cams]
    out["poses"] = np.array([c["camera_to_world"] for c in cams], dtype=float).reshape(-1, 4, 4)
    out["K"] = np.array([c["K"] for c in cams], dtype=float).reshape(-1, 3, 3)
    out["R"] = np.array([c["R"] for c in cams], dtype=float).reshape(-1, 3, 3)
    out["rvec"] = np.array([c["rvec"] for c in cams], dtype=float).reshape(-1, 3)
    out["tvec"] = np.array([c["tvec"] for c in cams], dtype=float).reshape(-1, 3)
    out["image_size"] = tuple(cams[0]["image_size"]) if cams else None
    out["sees"] = {c["name"]: list(c["sees"]) for c in cams}
    out["mirror_names"] = [m["name"] for m in gt["mirrors"]]
    out["normals"] = np.array([m["normal"] for m in gt["mirrors"]], dtype=float).reshape(-1, 3)
    out["distances"] = np.array([m["distance"] for m in gt["mirrors"]], dtype=float)
    out["subject_height"] = float(gt["subject_height"])
    out.update(load_ground_truth_joints(p.parent, gt.get("joints3d")))
    if gt.get("bystanders") and isinstance(gt.get("joints3d"), str):
        with np.load(p.parent / gt["joints3d"], allow_pickle=False) as z:
            out["bystanders_joints3d"] = z["bystanders_joints3d"]
    return out
