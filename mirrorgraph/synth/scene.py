"""Synthetic mirror scenes: placement, projection and a pose-detector noise model.

Geometry (the conventions of the whole package): one pinhole camera at the
origin of the real camera frame (``x`` right, ``y`` down, ``z`` forward,
metres); the mirror plane is ``n . X = d`` with ``n`` a unit vector pointing
away from the camera and ``d > 0``. A point ``X`` is imaged directly at
``pi(K X)`` and in the mirror at ``pi(K S(X))``, ``S(X) = X - 2 (n . X - d) n``.

Camera matrix: ``fx = fy = (w / 2) / tan(fov / 2)`` (``fov`` horizontal),
zero skew, principal point ``(w / 2 + dx, h / 2 + dy)`` with ``dx, dy`` drawn
uniformly in +-4 px (a real camera's principal point is never exactly central).

The scene: a camera with a small random tilt (pitch +-10 deg, roll +-3 deg
around level) looks at a person who exercises (see
:mod:`~mirrorgraph.synth.motion`) between the camera and the mirror, facing
roughly the camera or roughly the mirror (50 % each, +-15 deg), turning up to
+-70 deg. The mirror normal makes ``mirror_angle_deg`` with the optical axis and
turns to the left or the right of it (a vertical mirror, as in gyms and
studios), its azimuth around the axis within +-20 deg of horizontal.

Placement is exact and cheap: every requirement ("all joints of the person and
of the reflection project inside the image with a margin of 4 % of the shorter
image side and lie at least 0.5 m in front of the camera; every joint at least
0.2 m in front of the mirror") is a half-space constraint on the 3D point,
therefore satisfied by every joint in every frame if and only if it is by the
vertices of the convex hull of the motion. For a given orientation the feasible
positions of the person form a polyhedron; candidates are sampled in a box and
one of the feasible ones is picked (preferring ones where the person and their
reflection lie apart in the image). When no position is feasible, every
parameter that the caller left random (mirror azimuth, and angle, distance and
height when not given; facing and camera tilt) is drawn again. With the default
1920x1080, 60 deg camera a tall subject does not fit the frame near the camera,
so infeasible short mirror distances are redrawn: the distribution of the
distance actually used leans to the far end of 2.5-4.5 m.

Real motion: with ``motion="take.bvh"`` a motion-capture take replaces the
procedural motion (:mod:`~mirrorgraph.synth.bvh`: CMU skeleton mapped to the
body model's joints, resampled to ``fps``, in the same body frame; the first
``frames`` frames, played back and forth when the take is shorter). The
subject's height is then the skeleton's own standing height, or
``subject_height`` when given (the take is scaled to it); everything else
(placement, detector model) is unchanged. A take that travels far (the CMU
playground jumps cover 3.7 m) needs a long enough view: if no placement fits,
use fewer frames, a wider field of view or a larger mirror distance.

Detector model (MirrorCalib, Liao, Zheng and Mitchell): every observed
coordinate gets Gaussian noise of mean ``noise_mean`` and standard deviation
``noise_std`` pixels (added after lens distortion, i.e. in the image). Then:

* outliers: each (frame, joint, view) observation with probability
  ``outlier_rate`` is replaced by the true point displaced 30-150 px in a
  uniformly random direction;
* confidences: ``0.3 + 0.7 * Beta(4, 1.2)`` for inliers,
  ``0.3 + 0.7 * Beta(2, 2)`` for outliers (lower on average, overlapping);
* missing: each person (direct or reflection) is dropped from a frame with
  probability ``missing_rate / 5``, and each remaining joint observation is
  missing with the probability that makes the total missing fraction
  ``missing_rate``; a person with no joint left is dropped;
* single person: in a fraction ``single_person_rate`` of frames one of the two
  (either, at random) is not detected;
* left/right swaps: in a fraction ``lr_swap_rate`` of frames (where the
  reflection is detected) the detector labels the reflection with the real
  joints' labels instead of the flipped ones;
* extra people: in a fraction ``extra_person_rate`` of frames a bystander is
  added: a pose of the same motion at another time, another height
  (1.50-1.95 m) and facing, imaged whole inside the image at 35-80 % of its
  usable height, with its own noise and missing joints;
* observed coordinates are clipped to the image; people are listed per frame in
  random order.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..keypoints import PairedKeypoints, RawDetections
from ..skeletons import Skeleton, skeleton_by_name
from .body import BodyModel, check_skeleton, make_body, skeleton_points
from .motion import generate_motion

#: Reflection of the x axis that makes the virtual camera's rotation proper.
D_FLIP = np.diag([-1.0, 1.0, 1.0])

_Z_MIN = 0.5          # m: nearest a joint (or its reflection) may be to the camera plane
_MIRROR_GAP = 0.2     # m: nearest a joint may come to the mirror
_MAX_ATTEMPTS = 400
_CANDIDATES = 4096
_HULL_MIN_POINTS = 3000


@dataclass
class SyntheticScene:
    """A synthetic mirror video: ground truth and what a detector would output.

    Attributes:
        K: ``(3, 3)`` camera matrix.
        dist: ``(5,)`` OpenCV distortion coefficients of the observations, or ``None``.
        image_size: ``(width, height)`` px.
        normal: ``(3,)`` unit mirror normal ``n`` (pointing away from the camera).
        distance: mirror distance ``d`` (m); the plane is ``n . X = d``.
        subject_height: standing height of the person (m).
        skeleton: the keypoint layout.
        fps: frame rate.
        frame_ids: ``(T,)`` int frame numbers (``0 .. T-1``).
        joints3d: ``(T, J, 3)`` joint positions, metres, real camera frame.
        real_clean: ``(T, J, 2)`` pinhole image ``pi(K X)`` of the joints.
        mirror_clean: ``(T, J, 2)`` pinhole image ``pi(K S(X))`` of the reflection,
            indexed by the real joint it images.
        detections: what a detector outputs (see the module docstring).
        outlier_mask_real: ``(T, J)`` observed direct joints replaced by an outlier.
        outlier_mask_mirror: ``(T, J)`` same for the reflection (real-joint labels).
        lr_swapped: ``(T,)`` frames whose reflection the detector labelled unflipped.
        real_image: ``(T, J, 2)`` noise-free points as the camera images them
            (``real_clean`` distorted by ``dist``; the same as ``real_clean`` without).
        mirror_image: ``(T, J, 2)`` the same for the reflection.
        real_observed: ``(T, J, 3)`` the direct observations (x, y, confidence;
            NaN/0 when missing), whatever the detector output order.
        mirror_observed: ``(T, J, 3)`` the reflection observations in real-joint
            labels (swaps undone).
        missing_real: ``(T, J)`` direct observations missing (incl. person not detected).
        missing_mirror: ``(T, J)`` same for the reflection.
        real_detected: ``(T,)`` the person is in the detections.
        mirror_detected: ``(T,)`` the reflection is in the detections.
        extra_person: ``(T,)`` a bystander was added to the frame.
        seed: the seed given to :func:`make_scene`.
        options: every option given to :func:`make_scene`.
        body: the individual body model (segment lengths in units of height).
        placement: how the person was placed: ``R_body`` (body frame -> camera),
            ``origin`` (body-frame origin, on the floor, in camera coordinates),
            ``facing`` ("camera"/"mirror"), ``attempts``, ``margin_px``.
        motion: with a motion-capture take (``make_scene(motion=...)``): ``file``,
            ``source_fps``, ``source_frames``, ``skipped`` (leading reference
            frames left out), ``take_frames`` (frames after resampling),
            ``pingpong`` (the take was shorter than ``frames``),
            ``skeleton_height`` (m) and ``scale`` (subject height / skeleton
            height); ``None`` with the procedural motion (``body`` is then set;
            with a take it is ``None``).
    """

    K: np.ndarray
    dist: np.ndarray | None
    image_size: tuple[int, int]
    normal: np.ndarray
    distance: float
    subject_height: float
    skeleton: Skeleton
    fps: float
    frame_ids: np.ndarray
    joints3d: np.ndarray
    real_clean: np.ndarray
    mirror_clean: np.ndarray
    detections: RawDetections
    outlier_mask_real: np.ndarray
    outlier_mask_mirror: np.ndarray
    lr_swapped: np.ndarray
    real_image: np.ndarray
    mirror_image: np.ndarray
    real_observed: np.ndarray
    mirror_observed: np.ndarray
    missing_real: np.ndarray
    missing_mirror: np.ndarray
    real_detected: np.ndarray
    mirror_detected: np.ndarray
    extra_person: np.ndarray
    seed: Any = None
    options: dict[str, Any] = field(default_factory=dict)
    body: BodyModel | None = None
    placement: dict[str, Any] = field(default_factory=dict)
    motion: dict[str, Any] | None = None

    def __len__(self) -> int:
        return int(self.joints3d.shape[0])

    def __repr__(self) -> str:
        ang = float(np.degrees(np.arccos(np.clip(self.normal[2], -1.0, 1.0))))
        return (f"SyntheticScene({self.skeleton.name}, {len(self)} frames at {self.fps:g} fps, "
                f"{self.image_size[0]}x{self.image_size[1]}, mirror at {self.distance:.3f} m, "
                f"{ang:.1f} deg, subject {self.subject_height:.3f} m, seed={self.seed})")

    @property
    def D(self) -> np.ndarray:
        """``diag(-1, 1, 1)``."""
        return D_FLIP.copy()

    @property
    def virtual_R(self) -> np.ndarray:
        """Rotation of the virtual camera: ``D (I - 2 n n^T)``."""
        n = self.normal
        return D_FLIP @ (np.eye(3) - 2.0 * np.outer(n, n))

    @property
    def virtual_t(self) -> np.ndarray:
        """Translation of the virtual camera: ``2 d D n``."""
        return 2.0 * self.distance * (D_FLIP @ self.normal)

    @property
    def intrinsics(self):
        """The camera as :class:`mirrorgraph.intrinsics.Intrinsics` (exact, not approximate)."""
        from ..intrinsics import Intrinsics
        return Intrinsics(K=self.K.copy(), dist=None if self.dist is None else self.dist.copy(),
                          image_size=tuple(self.image_size), source="synthetic",
                          approximate=False)

    def reflect(self, X: np.ndarray) -> np.ndarray:
        """Mirror image ``S(X)`` of points ``(..., 3)``."""
        n = self.normal
        return X - 2.0 * ((X @ n) - self.distance)[..., None] * n

    def paired(self, fix_lr: bool = True) -> PairedKeypoints:
        """The ground-truth pairing of the detections.

        ``real`` and ``mirror`` are the noisy observations (outliers and missing
        joints included; confidence 0 rows where a person was not detected),
        ``mirror`` in the real joints' labels. With ``fix_lr=True`` (what a perfect
        pairing step returns) the detector's left/right swaps are undone and
        counted in ``lr_fixes``; with ``fix_lr=False`` the pairs are exactly as the
        detector labelled them (swapped frames stay swapped), ``lr_fixes = 0``.
        """
        real = self.real_observed.copy()
        mirror = self.mirror_observed.copy()
        if not fix_lr and self.lr_swapped.any():
            flip = self.skeleton.flip
            mirror[self.lr_swapped] = mirror[self.lr_swapped][:, flip]
        return PairedKeypoints(
            skeleton=self.skeleton, frame_ids=self.frame_ids.copy(), real=real, mirror=mirror,
            source=f"synthetic(seed={self.seed})", format="synthetic",
            image_size=tuple(self.image_size), fps=self.fps,
            lr_fixes=int(self.lr_swapped.sum()) if fix_lr else 0,
            frames_read=len(self))


# ------------------------------------------------------------------ projection helpers
def tilted_normal(normal: np.ndarray, deg: float, rng: np.random.Generator) -> np.ndarray:
    """A unit vector ``deg`` degrees from the unit ``normal`` ``(3,)``, in a random direction:
    a perturbed initial mirror (the virtual camera then turns by ``2 deg``)."""
    n = np.asarray(normal, dtype=float)
    a = rng.normal(size=3)
    a -= (a @ n) * n
    a /= np.linalg.norm(a)
    m = np.cos(np.radians(deg)) * n + np.sin(np.radians(deg)) * a
    return m / np.linalg.norm(m)


def project(K: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Pinhole projection ``pi(K X)`` of points ``(..., 3)`` -> ``(..., 2)``."""
    x = X[..., :2] / X[..., 2:3]
    return x * np.array([K[0, 0], K[1, 1]]) + x[..., ::-1] * np.array([K[0, 1], 0.0]) \
        + K[:2, 2]


def distort_pixels(K: np.ndarray, dist: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Apply OpenCV's lens distortion (``k1, k2, p1, p2[, k3]``) to pinhole pixels.

    The same mapping as :func:`cv2.projectPoints` with these coefficients, so
    that undistorting the result with ``K, dist`` recovers ``pts``.
    """
    d = np.zeros(5)
    dist = np.asarray(dist, dtype=float).ravel()
    d[:len(dist)] = dist
    k1, k2, p1, p2, k3 = d
    fx, fy, s, cx, cy = K[0, 0], K[1, 1], K[0, 1], K[0, 2], K[1, 2]
    y = (pts[..., 1] - cy) / fy
    x = (pts[..., 0] - cx - s * y) / fx
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return np.stack([fx * xd + s * yd + cx, fy * yd + cy], -1)


def _camera_matrix(rng: np.random.Generator, image_size: tuple[int, int], fov_deg: float
                   ) -> np.ndarray:
    w, h = image_size
    f = (w / 2.0) / np.tan(np.radians(fov_deg) / 2.0)
    dx, dy = rng.uniform(-4.0, 4.0, 2)
    return np.array([[f, 0.0, w / 2.0 + dx], [0.0, f, h / 2.0 + dy], [0.0, 0.0, 1.0]])


def _rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def _rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1.0, 0], [-s, 0, c]])


def _rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


#: Body/world frame (x left, y up, z forward) to a level camera (x right, y down, z fwd).
_WORLD_TO_LEVEL_CAMERA = np.diag([-1.0, -1.0, 1.0])


def _constraints(K: np.ndarray, image_size: tuple[int, int], margin: float,
                 n: np.ndarray, d: float) -> tuple[np.ndarray, np.ndarray]:
    """Half-spaces ``A X + b >= 0`` (camera frame) that every joint must satisfy."""
    w, h = image_size
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    img = np.array([[fx, 0.0, cx - margin],          # u >= margin
                    [-fx, 0.0, w - margin - cx],     # u <= w - margin
                    [0.0, fy, cy - margin],          # v >= margin
                    [0.0, -fy, h - margin - cy],     # v <= h - margin
                    [0.0, 0.0, 1.0]])                # Z >= Z_MIN
    b_img = np.array([0.0, 0.0, 0.0, 0.0, -_Z_MIN])
    H = np.eye(3) - 2.0 * np.outer(n, n)              # a . S(X) = (H a) . X + 2 d (a . n)
    A = np.vstack([img, img @ H, -n[None]])
    b = np.concatenate([b_img, b_img + 2.0 * d * (img @ n), [d - _MIRROR_GAP]])
    return A, b


def _hull_points(pts: np.ndarray) -> np.ndarray:
    """Vertices of the convex hull of ``pts`` (all points if that fails or is small)."""
    if len(pts) < _HULL_MIN_POINTS:
        return pts
    try:
        from scipy.spatial import ConvexHull
        return pts[ConvexHull(pts).vertices]
    except Exception:  # degenerate input: fall back to every point
        return pts


# ------------------------------------------------------------------ make_scene
def check_camera_args(frames: int, image_size: tuple[int, int], fov_deg: float, fps: float,
                      noise_std: float) -> tuple[int, int, int]:
    """Check the arguments a synthetic scene and a synthetic rig share.

    Returns:
        ``(T, width, height)`` as ints.

    Raises:
        ValueError: naming the argument out of range.
    """
    T = int(frames)
    if T < 1:
        raise ValueError(f"frames must be >= 1, got {frames}")
    w, h = (int(image_size[0]), int(image_size[1]))
    if w <= 0 or h <= 0:
        raise ValueError(f"image_size must be positive, got {image_size}")
    if not 0.0 < fov_deg < 180.0:
        raise ValueError(f"fov_deg must be in (0, 180), got {fov_deg}")
    if fps <= 0:
        raise ValueError(f"fps must be positive, got {fps}")
    if noise_std < 0:
        raise ValueError(f"noise_std must be >= 0, got {noise_std}")
    return T, w, h


def make_scene(*, frames: int = 1000, seed: int | None = 0, skeleton: str | Skeleton = "COCO_17",
               image_size: tuple[int, int] = (1920, 1080), fov_deg: float = 60.0,
               mirror_angle_deg: float | None = None, mirror_distance: float | None = None,
               subject_height: float | None = None, noise_mean: float = 0.076,
               noise_std: float = 4.0, outlier_rate: float = 0.0, lr_swap_rate: float = 0.0,
               missing_rate: float = 0.0, extra_person_rate: float = 0.0,
               single_person_rate: float = 0.0, distortion: Any = None,
               fps: float = 30.0, motion: str | os.PathLike | None = None,
               noise_correlation: float = 0.0, joint_bias_px: float = 0.0
               ) -> SyntheticScene:
    """Generate a synthetic mirror scene (see the module docstring for the model).

    Args:
        frames: number of frames ``T`` (>= 1).
        seed: seed of :func:`numpy.random.default_rng`; the same seed gives
            identical arrays.
        skeleton: keypoint layout or its name (``COCO_17``, ``BODY_25``, ``COCO_18``).
        image_size: ``(width, height)`` px.
        fov_deg: horizontal field of view, degrees.
        mirror_angle_deg: angle between mirror normal and optical axis (``None``:
            uniform 10-60 deg); the normal turns left or right of the axis
            (azimuth within +-20 deg of horizontal).
        mirror_distance: ``d`` in metres (``None``: uniform 2.5-4.5).
        subject_height: metres (``None``: uniform 1.55-1.95, or with ``motion``
            the skeleton's own height).
        noise_mean, noise_std: Gaussian detector noise per coordinate, px.
        outlier_rate: fraction of observations replaced by gross errors.
        lr_swap_rate: fraction of frames whose reflection is labelled unflipped.
        missing_rate: fraction of joint observations missing.
        extra_person_rate: fraction of frames with a bystander.
        single_person_rate: fraction of frames with only one of person/reflection.
        distortion: ``(5,)`` OpenCV coefficients ``k1, k2, p1, p2, k3`` (4 also
            accepted) applied to the observations, or ``None``.
        fps: frame rate.
        motion: a BVH motion-capture take (CMU skeleton) to use instead of the
            procedural motion (see the module docstring and
            :mod:`mirrorgraph.synth.bvh`); recorded in ``options["motion"]``.
        noise_correlation: correlation of each coordinate's noise from one frame
            to the next (AR(1) coefficient in [0, 1); the standard deviation
            stays ``noise_std``): a real detector's errors persist over frames.
        joint_bias_px: standard deviation of a constant offset per view, joint
            and coordinate, px: a real detector places some joints
            consistently off (e.g. hips too high). Both are drawn from a
            generator of their own, so scenes without them are unchanged.

    Raises:
        ValueError: an option out of range, or no placement satisfies the
            constraints with the parameters given.
        InputError: ``motion`` cannot be read or is not a usable BVH take.
    """
    options = dict(frames=frames, seed=seed, skeleton=skeleton if isinstance(skeleton, str)
                   else skeleton.name, image_size=list(image_size), fov_deg=fov_deg,
                   mirror_angle_deg=mirror_angle_deg, mirror_distance=mirror_distance,
                   subject_height=subject_height, noise_mean=noise_mean, noise_std=noise_std,
                   outlier_rate=outlier_rate, lr_swap_rate=lr_swap_rate,
                   missing_rate=missing_rate, extra_person_rate=extra_person_rate,
                   single_person_rate=single_person_rate,
                   distortion=None if distortion is None else
                   [float(v) for v in np.asarray(distortion, dtype=float).ravel()], fps=fps,
                   motion=None if motion is None else os.fspath(motion),
                   noise_correlation=noise_correlation, joint_bias_px=joint_bias_px)
    T, w, h = check_camera_args(frames, image_size, fov_deg, fps, noise_std)
    if not 0.0 <= noise_correlation < 1.0:
        raise ValueError(f"noise_correlation must be in [0, 1), got {noise_correlation}")
    if joint_bias_px < 0:
        raise ValueError(f"joint_bias_px must be >= 0, got {joint_bias_px}")
    for name, v in (("outlier_rate", outlier_rate), ("lr_swap_rate", lr_swap_rate),
                    ("missing_rate", missing_rate), ("extra_person_rate", extra_person_rate),
                    ("single_person_rate", single_person_rate)):
        if not 0.0 <= v <= 1.0:
            raise ValueError(f"{name} must be in [0, 1], got {v}")
    if mirror_angle_deg is not None and not 0.0 <= mirror_angle_deg < 90.0:
        raise ValueError(f"mirror_angle_deg must be in [0, 90), got {mirror_angle_deg}")
    if mirror_distance is not None and mirror_distance <= 0:
        raise ValueError(f"mirror_distance must be positive, got {mirror_distance}")
    if subject_height is not None and subject_height <= 0:
        raise ValueError(f"subject_height must be positive, got {subject_height}")
    dist = None
    if distortion is not None:
        dist = np.zeros(5)
        dv = np.asarray(distortion, dtype=float).ravel()
        if len(dv) not in (4, 5) or not np.all(np.isfinite(dv)):
            raise ValueError("distortion must be 4 or 5 finite OpenCV coefficients "
                             "(k1, k2, p1, p2[, k3])")
        dist[:len(dv)] = dv
    skel = skeleton_by_name(skeleton) if isinstance(skeleton, str) else skeleton
    check_skeleton(skel)
    J = skel.num_joints
    size = (w, h)

    rng = np.random.default_rng(seed)
    K = _camera_matrix(rng, size, fov_deg)
    take_info = None
    if motion is None:
        body = make_body(rng)
        full = generate_motion(body, T, fps, rng)        # (T, 25, 3), units of height
        take_height = None
    else:
        from .bvh import motion_for_scene
        body = None
        full, take = motion_for_scene(motion, T, fps)    # (T, 25, 3), units of height
        take_height = take.height
        take_info = dict(file=take.source, source_fps=take.source_fps,
                         source_frames=take.source_frames, skipped=take.skipped,
                         take_frames=len(take), pingpong=T > len(take),
                         skeleton_height=take.height)
    local = skeleton_points(full, skel)                  # (T, J, 3)
    del full
    hull = _hull_points(local.reshape(-1, 3))
    centre = local.reshape(-1, 3).mean(0)

    # ------------------------------------------------------------- placement
    margin = 0.04 * min(w, h)
    chosen = None
    for attempt in range(_MAX_ATTEMPTS):
        if attempt == 0 or (subject_height is None and take_height is None):
            H_m = (float(subject_height) if subject_height is not None
                   else take_height if take_height is not None else rng.uniform(1.55, 1.95))
        if attempt == 0 or mirror_angle_deg is None:
            ang = np.radians(mirror_angle_deg if mirror_angle_deg is not None
                             else rng.uniform(10.0, 60.0))
        if attempt == 0 or mirror_distance is None:
            d = float(mirror_distance) if mirror_distance is not None else rng.uniform(2.5, 4.5)
        # gym and studio mirrors hang vertically: the normal turns left or right
        # of the optical axis, with up to +-20 deg of azimuth (a tilted mirror
        # or camera) around that
        az = rng.choice([0.0, np.pi]) + np.radians(rng.uniform(-20.0, 20.0))
        n = np.array([np.sin(ang) * np.cos(az), np.sin(ang) * np.sin(az), np.cos(ang)])
        tilt = _rot_x(np.radians(np.clip(rng.normal(0.0, 4.0), -10, 10))) \
            @ _rot_z(np.radians(np.clip(rng.normal(0.0, 1.5), -3, 3)))
        R_cw = tilt @ _WORLD_TO_LEVEL_CAMERA                 # world (y up) -> camera
        facing = "camera" if rng.random() < 0.5 else "mirror"
        n_w = R_cw.T @ n
        if facing == "mirror" and np.hypot(n_w[0], n_w[2]) > 0.2:
            base = np.arctan2(n_w[0], n_w[2])
        else:
            facing = "camera"
            base = np.pi
        base += np.radians(rng.uniform(-15.0, 15.0))
        R = R_cw @ _rot_y(base)                              # body -> camera
        A, b = _constraints(K, size, margin, n, d)
        support = (hull @ (R.T @ A.T)).min(0) * H_m          # min_x a . (R x H)
        # candidate origins (floor point of the body frame) in camera coordinates
        cand = rng.uniform([-3.5, -0.2, 0.5], [3.5, 2.2, 2.0 * d + 1.5], (_CANDIDATES, 3))
        ok = np.all(cand @ A.T + b + support >= 0.0, axis=1)
        if not ok.any():
            continue
        cand = cand[ok]
        # prefer placements where person and reflection lie apart in the image
        c3 = cand + H_m * (R @ centre)
        sep = np.linalg.norm(project(K, c3) - project(K, c3 - 2.0 * ((c3 @ n) - d)[:, None] * n),
                             axis=-1)
        good = np.flatnonzero(sep >= np.quantile(sep, 0.5))
        origin = cand[good[rng.integers(len(good))]]
        X = (local @ R.T) * H_m + origin
        rc = project(K, X)
        mc = project(K, X - 2.0 * ((X @ n) - d)[..., None] * n)
        if dist is not None:
            ri, mi = distort_pixels(K, dist, rc), distort_pixels(K, dist, mc)
            lo, hi = margin / 2, np.array([w - margin / 2, h - margin / 2])
            if not (np.all(ri >= lo) and np.all(ri <= hi) and np.all(mi >= lo)
                    and np.all(mi <= hi)):
                continue
        else:
            ri, mi = rc, mc
        chosen = dict(R_body=R, origin=origin, facing=facing, attempts=attempt + 1,
                      margin_px=margin, camera_tilt=tilt)
        break
    if chosen is None:
        fixed = [k for k, v in (("mirror_angle_deg", mirror_angle_deg),
                                ("mirror_distance", mirror_distance),
                                ("subject_height", subject_height)) if v is not None]
        if motion is not None:
            fixed.append("motion" + ("" if subject_height is not None
                                     else f" (subject {take_height:.2f} m)"))
        raise ValueError(
            "cannot place the person so that they and their reflection stay inside the "
            f"{w}x{h} image with a {fov_deg:g} deg field of view"
            + (f" with the given {', '.join(fixed)}" if fixed else "")
            + ("; try fewer frames, a wider field of view or a larger mirror distance"
               if motion is not None else
               "; try a wider field of view, a larger mirror distance or a shorter subject"))

    # ------------------------------------------------------------- observations
    obs_clean = np.stack([ri, mi])                          # (2, T, J, 2) in the image
    out = _observe(rng, obs_clean, size, noise_mean, noise_std, outlier_rate, missing_rate,
                   single_person_rate, noise_correlation, joint_bias_px,
                   np.random.default_rng([0 if seed is None else int(seed), 7919]))
    obs, miss, outl, detected = out
    swap = (rng.random(T) < lr_swap_rate) & detected[1]
    flip = skel.flip
    det_mirror = np.where(swap[:, None, None], obs[1], obs[1][:, flip])

    extra = rng.random(T) < extra_person_rate
    extra_people = _bystanders(rng, local, np.flatnonzero(extra), K, size, margin,
                               R_cw, noise_mean, noise_std, missing_rate)

    frame_ids = np.arange(T, dtype=np.int64)
    groups = (np.flatnonzero(detected[0]), np.flatnonzero(detected[1]), np.flatnonzero(extra))
    row_frame = np.concatenate(groups)
    key = rng.random(len(row_frame))
    order = np.lexsort((key, row_frame))             # people in random order per frame
    dest = np.empty_like(order)
    dest[order] = np.arange(len(order))
    allrows = np.empty((len(order), J, 3))
    start = 0
    for src, g in zip((obs[0], det_mirror, None), groups):
        rows = extra_people if src is None else src[g]
        allrows[dest[start:start + len(g)]] = rows
        start += len(g)
    del det_mirror, extra_people, rows
    counts = np.bincount(row_frame, minlength=T)
    people = np.split(allrows, np.cumsum(counts)[:-1])
    detections = RawDetections(skeleton=skel, frame_ids=frame_ids, people=people,
                               source=f"synthetic(seed={seed})", format="synthetic",
                               image_size=size, fps=float(fps))

    return SyntheticScene(
        K=K, dist=dist, image_size=size, normal=n, distance=float(d), subject_height=float(H_m),
        skeleton=skel, fps=float(fps), frame_ids=frame_ids, joints3d=X, real_clean=rc,
        mirror_clean=mc, detections=detections, outlier_mask_real=outl[0],
        outlier_mask_mirror=outl[1], lr_swapped=swap, real_image=ri, mirror_image=mi,
        real_observed=obs[0], mirror_observed=obs[1], missing_real=miss[0],
        missing_mirror=miss[1], real_detected=detected[0], mirror_detected=detected[1],
        extra_person=extra, seed=seed, options=options, body=body, placement=chosen,
        motion=None if take_info is None else dict(take_info, scale=float(H_m) / take_height))


def _confidences(rng: np.random.Generator, outlier: np.ndarray) -> np.ndarray:
    conf = rng.beta(4.0, 1.2, outlier.shape)
    k = int(outlier.sum())
    if k:
        conf[outlier] = rng.beta(2.0, 2.0, k)
    conf *= 0.7
    conf += 0.3
    return conf


def _correlated_noise(rng: np.random.Generator, shape: tuple[int, ...], rho: float
                      ) -> np.ndarray:
    """Unit-variance AR(1) noise along axis 1 (frames): ``e_t = rho e_(t-1) + sqrt(1-rho^2) w_t``."""
    from scipy.signal import lfilter

    w = rng.standard_normal(shape)
    w[:, 0] /= np.sqrt(1.0 - rho ** 2)          # start in the stationary distribution
    return lfilter([np.sqrt(1.0 - rho ** 2)], [1.0, -rho], w, axis=1)


def _observe(rng: np.random.Generator, clean: np.ndarray, size: tuple[int, int],
             noise_mean: float, noise_std: float, outlier_rate: float, missing_rate: float,
             single_person_rate: float, noise_correlation: float = 0.0,
             joint_bias_px: float = 0.0, rng_detector: np.random.Generator | None = None):
    """Noisy detections ``(V, T, J, 3)`` of clean points ``(V, T, J, 2)``."""
    V, T, J, _ = clean.shape
    if noise_correlation > 0 or joint_bias_px > 0:
        xy = clean + noise_mean
        if noise_std > 0:
            xy = xy + noise_std * _correlated_noise(rng_detector, clean.shape, noise_correlation)
        if joint_bias_px > 0:
            xy = xy + rng_detector.normal(0.0, joint_bias_px, (V, 1, J, 2))
    elif noise_std > 0:
        xy = rng.normal(noise_mean, noise_std, clean.shape)
        xy += clean
    else:
        xy = clean + noise_mean
    outl = rng.random((V, T, J)) < outlier_rate if outlier_rate > 0 \
        else np.zeros((V, T, J), bool)
    k = int(outl.sum())
    if k:
        ang = rng.uniform(0.0, 2 * np.pi, k)
        rad = rng.uniform(30.0, 150.0, k)
        xy[outl] = clean[outl] + np.stack([np.cos(ang), np.sin(ang)], -1) * rad[:, None]
    w, h = size
    np.clip(xy[..., 0], 0.0, w - 1.0, out=xy[..., 0])
    np.clip(xy[..., 1], 0.0, h - 1.0, out=xy[..., 1])
    conf = _confidences(rng, outl)
    p_person = missing_rate / 5.0
    p_joint = max(0.0, (missing_rate - p_person) / (1.0 - p_person)) if p_person < 1 else 1.0
    drop = rng.random((V, T)) < p_person if p_person > 0 else np.zeros((V, T), bool)
    if single_person_rate > 0:
        single = np.flatnonzero(rng.random(T) < single_person_rate)
        drop[rng.integers(0, V, len(single)), single] = True
    miss = rng.random((V, T, J)) < p_joint if p_joint > 0 else np.zeros((V, T, J), bool)
    detected = ~drop & ~miss.all(-1)
    miss |= ~detected[..., None]
    outl &= ~miss
    obs = np.empty(xy.shape[:-1] + (3,))
    obs[..., :2] = xy
    obs[..., 2] = conf
    del xy, conf
    obs[miss] = (np.nan, np.nan, 0.0)
    return obs, miss, outl, detected


def _bystanders(rng: np.random.Generator, poses: np.ndarray, frames: np.ndarray,
                K: np.ndarray, size: tuple[int, int], margin: float, R_cw: np.ndarray,
                noise_mean: float, noise_std: float, missing_rate: float) -> np.ndarray:
    """Keypoints ``(E, J, 3)`` of unrelated people, whole inside the image."""
    E, J = len(frames), poses.shape[1]
    if E == 0:
        return np.zeros((0, J, 3))
    w, h = size
    T = poses.shape[0]
    p = poses[rng.integers(0, T, E)]                    # (E, J, 3) units of height, copy
    p[..., [0, 2]] -= p[..., [0, 2]].mean(1, keepdims=True)
    height = rng.uniform(1.50, 1.95, E)
    yaw = rng.uniform(-np.pi, np.pi, E)
    c, s = np.cos(yaw), np.sin(yaw)
    Ry = np.zeros((E, 3, 3))
    Ry[:, 0, 0], Ry[:, 0, 2], Ry[:, 1, 1], Ry[:, 2, 0], Ry[:, 2, 2] = c, s, 1.0, -s, c
    Rb = R_cw @ Ry                                       # (E, 3, 3) body -> camera
    X = np.einsum("eij,ekj->eki", Rb, p) * height[:, None, None]
    depth = rng.uniform(3.0, 9.0, E)
    X = X + np.stack([np.zeros(E), 0.9 * height, depth], -1)[:, None, :]
    X[..., 2] = np.maximum(X[..., 2], _Z_MIN)
    uv = project(K, X)
    lo, hi = uv.min(1), uv.max(1)                        # (E, 2) bounding boxes
    box = np.maximum(hi - lo, 1e-6)
    avail = np.array([w - 2 * margin, h - 2 * margin])
    frac = rng.uniform(0.35, 0.8, E)
    scale = np.minimum(np.minimum(1.0, avail[1] * frac / box[:, 1]), avail[0] / box[:, 0])
    uv = (uv - lo[:, None]) * scale[:, None, None]
    box = box * scale[:, None]
    corner = margin + rng.random((E, 2)) * np.maximum(avail - box, 0.0)
    uv = uv + corner[:, None]
    xy = uv + rng.normal(noise_mean, noise_std, uv.shape) if noise_std > 0 else uv + noise_mean
    xy[..., 0] = np.clip(xy[..., 0], 0.0, w - 1.0)
    xy[..., 1] = np.clip(xy[..., 1], 0.0, h - 1.0)
    conf = _confidences(rng, np.zeros((E, J), bool))
    miss = rng.random((E, J)) < missing_rate
    miss[miss.all(1), 0] = False                         # keep at least one joint
    out = np.concatenate([xy, conf[..., None]], -1)
    out[miss] = (np.nan, np.nan, 0.0)
    return out
