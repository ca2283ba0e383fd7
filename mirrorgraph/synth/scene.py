"""Synthetic mirror scenes: placement, projection and a pose-detector noise model.

Geometry (the conventions of the whole package): one pinhole camera at the
origin of the real camera frame (``x`` right, ``y`` down, ``z`` forward,
metres); the mirror plane is ``n . X = d`` with ``n`` a unit vector pointing
away from the camera and ``d > 0``. A point ``X`` is imaged directly at
``pi(K X)`` and in the mirror at ``pi(K S(X))``, ``S(X) = X - 2 (n . X - d) n``.

Camera matrix: ``fx = fy = (w / 2) / tan(fov / 2)`` (``fov`` horizontal),
zero skew, principal point ``(w / 2 + dx, h / 2 + dy)`` with ``dx, dy`` drawn
uniformly in +-4 px (a real camera's principal point is never exactly central).

Geometry presets (``geometry=``, :mod:`.geometry`): the ranges below are those
of ``"favourable"``, the generator's original scenes (the default,
:data:`~.geometry.DEFAULT_GEOMETRY`); ``"gym"``, ``"wide"`` and ``"low_parallax"``
widen them (mirror 2.5-10 m, the person 0.5-3.5 m in front of it, focal
700-2200 px, mirror 5-70 deg off the axis, camera height and tilt varied, the
person near the camera-mirror line) and place a vertical mirror in the world the
tilted camera sees; the placement below is the same for all of them, with the
preset's own candidate positions and constraints (:mod:`.geometry`).

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
procedural motion (:mod:`~mirrorgraph.synth.mocap`: CMU skeleton mapped to the
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
  joints' labels instead of the flipped ones; with ``lr_swap_views="both"``
  also, independently, the person's labels in a fraction ``lr_swap_rate`` of
  frames are swapped;
* outliers along the epipolar line: a fraction ``epipolar_outlier_rate`` of the
  other observations is moved 15-100 px along the line through the epipole
  (:func:`~.detector.displace_along_epipolar_lines`): no epipolar test sees
  them, the depth triangulated from them is wrong;
* a per-joint bias (``joint_bias_px``) per view, or with
  ``joint_bias_shared=True`` per detector label in both views (mirrored
  horizontally on the reflection), and AR(1) noise (``noise_correlation``);
  :mod:`.detector` names a ``"realistic"`` detector built of these;
* extra people: in a fraction ``extra_person_rate`` of frames a bystander is
  added: a pose of the same motion at another time, another height
  (1.50-1.95 m) and facing, imaged whole inside the image at 35-80 % of its
  usable height, with its own noise and missing joints;
* observed coordinates are clipped to the image; people are listed per frame in
  random order.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from ..intrinsics import Intrinsics
from ..keypoints import PairedKeypoints, RawDetections
from ..skeletons import Skeleton, skeleton_by_name
from .body import BodyModel, check_skeleton, make_body, skeleton_points
from .detector import displace_along_epipolar_lines
from .geometry import (PRESETS, GeometryPreset, parallax_deg, resolve_geometry,
                       vertical_mirror_normal)
from .motion import generate_motion

#: Reflection of the x axis that makes the virtual camera's rotation proper.
D_FLIP = np.diag([-1.0, 1.0, 1.0])

_Z_MIN = 0.5          # m: nearest a joint (or its reflection) may be to the camera plane
_MIRROR_GAP = 0.2     # m: nearest a joint may come to the mirror
MAX_ATTEMPTS = 400
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
            Both include the outliers along the epipolar line.
        epipolar_outlier_mask_real: ``(T, J)`` direct observations displaced along
            their epipolar line (``epipolar_outlier_rate``).
        epipolar_outlier_mask_mirror: ``(T, J)`` the same for the reflection.
        lr_swapped: ``(T,)`` frames whose reflection the detector labelled unflipped.
        lr_swapped_real: ``(T,)`` frames whose person the detector labelled with
            left and right swapped (``lr_swap_views="both"``; all False otherwise).
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
            ``facing`` ("camera"/"mirror"), ``attempts``, ``margin_px``,
            ``camera_tilt`` (level camera -> camera), ``R_world`` (world, ``y`` up,
            -> camera), ``geometry`` (the preset's name), ``focal_px``,
            ``camera_height`` (m above the floor), ``person_to_mirror`` (m, the
            centre of the motion) and ``parallax_deg`` (the angle between the two
            rays of that centre, :mod:`.geometry`).
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
    lr_swapped_real: np.ndarray | None = None
    epipolar_outlier_mask_real: np.ndarray | None = None
    epipolar_outlier_mask_mirror: np.ndarray | None = None

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
        counted in ``lr_fixes`` (the frames where only one of the two views is
        swapped: the ones a left/right check sees); with ``fix_lr=False`` the pairs
        are exactly as the detector labelled them (swapped frames stay swapped, in
        either view), ``lr_fixes = 0``.
        """
        real = self.real_observed.copy()
        mirror = self.mirror_observed.copy()
        flip = self.skeleton.flip
        swapped_real = (np.zeros(len(self), dtype=bool) if self.lr_swapped_real is None
                        else self.lr_swapped_real)
        if not fix_lr and self.lr_swapped.any():
            mirror[self.lr_swapped] = mirror[self.lr_swapped][:, flip]
        if not fix_lr and swapped_real.any():
            real[swapped_real] = real[swapped_real][:, flip]
        return PairedKeypoints(
            skeleton=self.skeleton, frame_ids=self.frame_ids.copy(), real=real, mirror=mirror,
            source=f"synthetic(seed={self.seed})", format="synthetic",
            image_size=tuple(self.image_size), fps=self.fps,
            lr_fixes=int((self.lr_swapped ^ swapped_real).sum()) if fix_lr else 0,
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


def random_camera_matrix(rng: np.random.Generator, image_size: tuple[int, int], fov_deg: float
                   ) -> np.ndarray:
    w, h = image_size
    f = (w / 2.0) / np.tan(np.radians(fov_deg) / 2.0)
    dx, dy = rng.uniform(-4.0, 4.0, 2)
    return np.array([[f, 0.0, w / 2.0 + dx], [0.0, f, h / 2.0 + dy], [0.0, 0.0, 1.0]])


def _rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1.0, 0], [-s, 0, c]])


def rot_z(a: float) -> np.ndarray:
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
    from scipy.spatial import ConvexHull     # 0.3-0.8 s to import: at first use

    try:
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
               image_size: tuple[int, int] = (1920, 1080), fov_deg: float | None = None,
               mirror_angle_deg: float | None = None, mirror_distance: float | None = None,
               subject_height: float | None = None, noise_mean: float = 0.076,
               noise_std: float = 4.0, outlier_rate: float = 0.0, lr_swap_rate: float = 0.0,
               missing_rate: float = 0.0, extra_person_rate: float = 0.0,
               single_person_rate: float = 0.0, distortion: Any = None,
               fps: float = 30.0, motion: str | os.PathLike | None = None,
               noise_correlation: float = 0.0, joint_bias_px: float = 0.0,
               geometry: str | GeometryPreset | None = None, focal_px: float | None = None,
               lr_swap_views: str = "mirror", epipolar_outlier_rate: float = 0.0,
               joint_bias_shared: bool = False) -> SyntheticScene:
    """Generate a synthetic mirror scene (see the module docstring for the model).

    Args:
        frames: number of frames ``T`` (>= 1).
        seed: seed of :func:`numpy.random.default_rng`; the same seed gives
            identical arrays.
        skeleton: keypoint layout or its name (``COCO_17``, ``BODY_25``, ``COCO_18``).
        image_size: ``(width, height)`` px.
        fov_deg: horizontal field of view, degrees (``None``: the geometry's focal
            range, or 60 deg where it has none, as the ``"favourable"`` one).
        mirror_angle_deg: angle between mirror normal and optical axis (``None``:
            the geometry's range, 10-60 deg for ``"favourable"``); the normal turns
            left or right of the axis.
        mirror_distance: ``d`` in metres (``None``: the geometry's range, 2.5-4.5
            for ``"favourable"``).
        subject_height: metres (``None``: uniform 1.55-1.95, or with ``motion``
            the skeleton's own height).
        noise_mean, noise_std: Gaussian detector noise per coordinate, px.
        outlier_rate: fraction of observations replaced by gross errors.
        lr_swap_rate: fraction of frames whose reflection is labelled unflipped
            (with ``lr_swap_views="both"`` also, independently, the fraction of
            frames whose person has left and right swapped).
        missing_rate: fraction of joint observations missing.
        extra_person_rate: fraction of frames with a bystander.
        single_person_rate: fraction of frames with only one of person/reflection.
        distortion: ``(5,)`` OpenCV coefficients ``k1, k2, p1, p2, k3`` (4 also
            accepted) applied to the observations, or ``None``.
        fps: frame rate.
        motion: a BVH motion-capture take (CMU skeleton) to use instead of the
            procedural motion (see the module docstring and
            :mod:`mirrorgraph.synth.mocap`); recorded in ``options["motion"]``.
        noise_correlation: correlation of each coordinate's noise from one frame
            to the next (AR(1) coefficient in [0, 1); the standard deviation
            stays ``noise_std``): a real detector's errors persist over frames.
        joint_bias_px: standard deviation of a constant offset per view, joint
            and coordinate, px: a real detector places some joints
            consistently off (e.g. hips too high). Both are drawn from a
            generator of their own, so scenes without them are unchanged.
        geometry: a preset name of :data:`~mirrorgraph.synth.geometry.PRESETS`
            (``"favourable"``, ``"gym"``, ``"wide"``, ``"low_parallax"``) or a
            :class:`~mirrorgraph.synth.geometry.GeometryPreset`; ``None``:
            :data:`~mirrorgraph.synth.geometry.DEFAULT_GEOMETRY`. The arguments
            above that fix a quantity (``fov_deg``, ``mirror_angle_deg``, ...)
            override its range.
        focal_px: focal length ``fx = fy`` in px instead of ``fov_deg``.
        lr_swap_views: ``"mirror"`` (the reflection only) or ``"both"``.
        epipolar_outlier_rate: fraction of the observations (either view)
            displaced along their epipolar lines
            (:func:`~mirrorgraph.synth.detector.displace_along_epipolar_lines`).
        joint_bias_shared: the per-joint bias follows the detector's label in
            both views (mirrored on the reflection) instead of one per view.

    Raises:
        ValueError: an option out of range, or no placement satisfies the
            constraints with the parameters given.
        InputError: ``motion`` cannot be read or is not a usable BVH take.
    """
    gp = resolve_geometry(geometry)
    if fov_deg is not None and focal_px is not None:
        raise ValueError("give fov_deg or focal_px, not both")
    if fov_deg is None and focal_px is None and gp.focal_px is None:
        fov_deg = 60.0
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
    # the options of the presets and detector models, recorded where not the default
    # (the files of a "favourable" scene stay as they were)
    if gp.name != "favourable" or PRESETS.get(gp.name) is not gp:
        options["geometry"] = gp.name if PRESETS.get(gp.name) is gp else asdict(gp)
    for key, value, default in (("focal_px", focal_px, None), ("lr_swap_views", lr_swap_views,
                                "mirror"), ("epipolar_outlier_rate", epipolar_outlier_rate, 0.0),
                                ("joint_bias_shared", joint_bias_shared, False)):
        if value != default:
            options[key] = value
    T, w, h = check_camera_args(frames, image_size, 60.0 if fov_deg is None else fov_deg, fps,
                                noise_std)
    if not 0.0 <= noise_correlation < 1.0:
        raise ValueError(f"noise_correlation must be in [0, 1), got {noise_correlation}")
    if joint_bias_px < 0:
        raise ValueError(f"joint_bias_px must be >= 0, got {joint_bias_px}")
    for name, v in (("outlier_rate", outlier_rate), ("lr_swap_rate", lr_swap_rate),
                    ("missing_rate", missing_rate), ("extra_person_rate", extra_person_rate),
                    ("single_person_rate", single_person_rate),
                    ("epipolar_outlier_rate", epipolar_outlier_rate)):
        if not 0.0 <= v <= 1.0:
            raise ValueError(f"{name} must be in [0, 1], got {v}")
    if mirror_angle_deg is not None and not 0.0 <= mirror_angle_deg < 90.0:
        raise ValueError(f"mirror_angle_deg must be in [0, 90), got {mirror_angle_deg}")
    if mirror_distance is not None and mirror_distance <= 0:
        raise ValueError(f"mirror_distance must be positive, got {mirror_distance}")
    if subject_height is not None and subject_height <= 0:
        raise ValueError(f"subject_height must be positive, got {subject_height}")
    if focal_px is not None and not focal_px > 0:
        raise ValueError(f"focal_px must be positive, got {focal_px}")
    if lr_swap_views not in ("mirror", "both"):
        raise ValueError(f"lr_swap_views must be 'mirror' or 'both', got {lr_swap_views!r}")
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
    K = random_camera_matrix(rng, size, 60.0 if fov_deg is None else fov_deg)
    if focal_px is not None:
        K[0, 0] = K[1, 1] = float(focal_px)
    take_info = None
    if motion is None:
        body = make_body(rng)
        full = generate_motion(body, T, fps, rng)        # (T, 25, 3), units of height
        take_height = None
    else:
        # lazy: the motion-capture reader (mocap, io.bvh) adds ~7 ms to `import
        # mirrorgraph.synth` and so to `mirrorgraph --help`; only a take needs it
        from .mocap import motion_for_scene
        body = None
        full, take = motion_for_scene(motion, T, fps)    # (T, 25, 3), units of height
        take_height = take.height
        take_info = dict(file=take.source, source_fps=take.source_fps,
                         source_frames=take.source_frames, skipped=take.skipped,
                         take_frames=len(take), pingpong=T > len(take),
                         skeleton_height=take.height)
    local = skeleton_points(full, skel)                  # (T, J, 3)
    del full

    # ------------------------------------------------------------- placement
    fixed = dict(subject_height=subject_height, take_height=take_height,
                 mirror_angle_deg=mirror_angle_deg, mirror_distance=mirror_distance,
                 focal=fov_deg is not None or focal_px is not None)
    chosen, H_m, n, d, X, rc, mc, ri, mi = _place(rng, gp, K, size, local, dist, **fixed)
    if chosen is None:
        given = [k for k, v in (("mirror_angle_deg", mirror_angle_deg),
                                ("mirror_distance", mirror_distance),
                                ("subject_height", subject_height)) if v is not None]
        if motion is not None:
            given.append("motion" + ("" if subject_height is not None
                                     else f" (subject {take_height:.2f} m)"))
        view = (f"a {fov_deg:g} deg field of view" if fov_deg is not None else
                f"a focal length of {focal_px:g} px" if focal_px is not None else
                f"focal lengths of {gp.focal_px[0]:g}-{gp.focal_px[1]:g} px")
        raise ValueError(
            "cannot place the person so that they and their reflection stay inside the "
            f"{w}x{h} image with {view}"
            + ("" if gp.name == "favourable" else f" (geometry {gp.name!r})")
            + (f" with the given {', '.join(given)}" if given else "")
            + ("; try fewer frames, a wider field of view or a larger mirror distance"
               if motion is not None else
               "; try a wider field of view, a larger mirror distance or a shorter subject"))

    # ------------------------------------------------------------- observations
    flip = skel.flip
    seed0 = 0 if seed is None else int(seed)
    obs_clean = np.stack([ri, mi])                          # (2, T, J, 2) in the image
    out = observe_keypoints(rng, obs_clean, size, noise_mean, noise_std, outlier_rate, missing_rate,
                   single_person_rate, noise_correlation, joint_bias_px,
                   np.random.default_rng([seed0, 7919]),
                   bias_flip=flip if joint_bias_shared else None)
    obs, miss, outl, detected = out
    epi = np.zeros_like(outl)
    if epipolar_outlier_rate > 0:                           # a generator of their own
        epi = displace_along_epipolar_lines(
            np.random.default_rng([seed0, 104729]), obs[..., :2], obs[..., 2],
            np.stack([rc, mc]), obs_clean, ~miss & ~outl, epipolar_outlier_rate, K, n, size,
            dist, distort_pixels)
        outl |= epi
    swap = (rng.random(T) < lr_swap_rate) & detected[1]
    swap_real = np.zeros(T, dtype=bool)
    if lr_swap_views == "both":
        swap_real = (np.random.default_rng([seed0, 15485863]).random(T) < lr_swap_rate) \
            & detected[0]
    det_real = np.where(swap_real[:, None, None], obs[0][:, flip], obs[0]) if swap_real.any() \
        else obs[0]
    det_mirror = np.where(swap[:, None, None], obs[1], obs[1][:, flip])

    extra = rng.random(T) < extra_person_rate
    extra_people = _bystanders(rng, local, np.flatnonzero(extra), K, size, chosen["margin_px"],
                               chosen["R_world"], noise_mean, noise_std, missing_rate)

    frame_ids = np.arange(T, dtype=np.int64)
    groups = (np.flatnonzero(detected[0]), np.flatnonzero(detected[1]), np.flatnonzero(extra))
    row_frame = np.concatenate(groups)
    key = rng.random(len(row_frame))
    order = np.lexsort((key, row_frame))             # people in random order per frame
    dest = np.empty_like(order)
    dest[order] = np.arange(len(order))
    allrows = np.empty((len(order), J, 3))
    start = 0
    for src, rows_of in zip((det_real, det_mirror, None), groups):
        rows = extra_people if src is None else src[rows_of]
        allrows[dest[start:start + len(rows_of)]] = rows
        start += len(rows_of)
    del det_real, det_mirror, extra_people, rows
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
        motion=None if take_info is None else dict(take_info, scale=float(H_m) / take_height),
        lr_swapped_real=swap_real, epipolar_outlier_mask_real=epi[0],
        epipolar_outlier_mask_mirror=epi[1])


def _tilt(rng: np.random.Generator, gp: GeometryPreset) -> np.ndarray:
    """A camera tilt ``(3, 3)`` (level camera to camera): pitch about ``x``, then roll
    about ``z``, each drawn from the preset's clipped normal distribution."""
    return _rot_x(np.radians(np.clip(rng.normal(0.0, gp.pitch_std_deg), -gp.pitch_max_deg,
                                     gp.pitch_max_deg))) \
        @ rot_z(np.radians(np.clip(rng.normal(0.0, gp.roll_std_deg), -gp.roll_max_deg,
                                    gp.roll_max_deg)))


def _candidates(rng: np.random.Generator, gp: GeometryPreset, K: np.ndarray, width: int,
                n: np.ndarray, d: float, tilt: np.ndarray, offset: np.ndarray
                ) -> np.ndarray | None:
    """Candidate origins ``(N, 3)`` (the body frame's floor point, camera frame) of one attempt.

    ``offset`` ``(3,)`` is the centre of the motion relative to the origin
    (camera frame, metres). ``None`` when the attempt's draw admits no candidate.
    """
    if gp.sampler == "box":                              # "favourable": the camera frame's box
        lo, hi = gp.camera_height
        return rng.uniform([-3.5, lo, 0.5], [3.5, hi, 2.0 * d + 1.5], (_CANDIDATES, 3))
    lo, hi = gp.person_to_mirror
    hi = min(hi, d - 0.5)                                # the person in front of the camera
    if hi < lo:
        return None
    if gp.sampler == "slab":
        # distance to the mirror near a target, camera height, image column: solve the depth
        t = rng.uniform(lo, hi)
        pm = np.clip(t + rng.uniform(-0.1, 0.1, _CANDIDATES), lo, hi)
        height = rng.uniform(*gp.camera_height, _CANDIDATES)
        half = np.arctan(0.5 * gp.column_frac * width / K[0, 0])
        tan = np.tan(rng.uniform(-half, half, _CANDIDATES))
        m = tilt.T @ n                                   # the normal in the level frame
        den = m[0] * tan + m[2]
        z = (d - pm - offset @ n - m[1] * height) / np.where(den > 0.05, den, np.nan)
        level = np.stack([z * tan, height, z], 1)        # x right, y down (the floor), z
        level = level[np.isfinite(z) & (z > 0.0)]
        return level @ tilt.T if len(level) else None
    # "axis": the motion's centre near the camera's line along the normal
    pm = rng.uniform(lo, hi, _CANDIDATES)
    a = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    b1 = np.cross(n, a)
    b1 /= np.linalg.norm(b1)
    b2 = np.cross(n, b1)
    rho = (d - pm) * np.tan(np.radians(gp.parallax_deg[1])) * np.sqrt(rng.random(_CANDIDATES))
    phi = rng.uniform(0.0, 2.0 * np.pi, _CANDIDATES)
    c3 = (d - pm)[:, None] * n + rho[:, None] * (np.cos(phi)[:, None] * b1
                                                  + np.sin(phi)[:, None] * b2)
    return c3 - offset


def _place(rng: np.random.Generator, gp: GeometryPreset, K: np.ndarray, size: tuple[int, int],
           local: np.ndarray, dist: np.ndarray | None, *, subject_height: float | None,
           take_height: float | None, mirror_angle_deg: float | None,
           mirror_distance: float | None, focal: bool):
    """Place the mirror and the person (the module docstring's placement).

    Draws, per attempt, every quantity the caller left free from the ranges of
    ``gp`` and keeps the first attempt with a feasible position. ``K`` gets the
    attempt's focal length in place when the preset draws one (``focal=False``).

    Returns:
        ``(chosen, H, n, d, X, rc, mc, ri, mi)``: the placement record (``None``
        and the rest ``None`` when no attempt fits), the subject's height, the
        normal ``(3,)``, the distance, the joints ``(T, J, 3)``, their pinhole
        pixels ``(T, J, 2)`` in both views and the same as imaged (distorted).
    """
    w, h = size
    hull = _hull_points(local.reshape(-1, 3))
    centre = local.reshape(-1, 3).mean(0)
    margin = gp.margin_frac * min(w, h)
    for attempt in range(MAX_ATTEMPTS):
        if attempt == 0 or (subject_height is None and take_height is None):
            H_m = (float(subject_height) if subject_height is not None
                   else take_height if take_height is not None else rng.uniform(1.55, 1.95))
        if attempt == 0 or mirror_angle_deg is None:
            ang = np.radians(mirror_angle_deg if mirror_angle_deg is not None
                             else rng.uniform(*gp.mirror_angle_deg))
        if attempt == 0 or mirror_distance is None:
            d = float(mirror_distance) if mirror_distance is not None \
                else rng.uniform(*gp.mirror_distance)
        if gp.focal_px is not None and not focal:
            K[0, 0] = K[1, 1] = rng.uniform(*gp.focal_px)
        if gp.vertical_mirror:
            # a vertical mirror in the world the tilted camera sees
            tilt = _tilt(rng, gp)
            R_cw = tilt @ _WORLD_TO_LEVEL_CAMERA
            side = rng.choice([-1.0, 1.0])
            lean = np.radians(rng.uniform(-gp.mirror_lean_deg, gp.mirror_lean_deg))
            n = vertical_mirror_normal(R_cw, ang, lean, side)
            if n is None:
                continue
        else:
            # gym and studio mirrors hang vertically: the normal turns left or right
            # of the optical axis, with up to +-20 deg of azimuth (a tilted mirror
            # or camera) around that
            az = rng.choice([0.0, np.pi]) + np.radians(rng.uniform(-gp.mirror_azimuth_deg,
                                                                   gp.mirror_azimuth_deg))
            n = np.array([np.sin(ang) * np.cos(az), np.sin(ang) * np.sin(az), np.cos(ang)])
            tilt = _tilt(rng, gp)
            R_cw = tilt @ _WORLD_TO_LEVEL_CAMERA                 # world (y up) -> camera
        facing = "camera" if rng.random() < 1.0 - gp.facing_mirror else "mirror"
        n_w = R_cw.T @ n
        if facing == "mirror" and np.hypot(n_w[0], n_w[2]) > 0.2:
            base = np.arctan2(n_w[0], n_w[2])
        else:
            facing = "camera"
            base = np.pi
        base += np.radians(rng.uniform(-gp.facing_jitter_deg, gp.facing_jitter_deg))
        R = R_cw @ rot_y(base)                              # body -> camera
        A, b = _constraints(K, size, margin, n, d)
        if gp.between:                                       # n . X >= 0
            A, b = np.vstack([A, n]), np.append(b, 0.0)
        support = (hull @ (R.T @ A.T)).min(0) * H_m          # min_x a . (R x H)
        # candidate origins (floor point of the body frame) in camera coordinates
        offset = H_m * (R @ centre)
        cand = _candidates(rng, gp, K, w, n, d, tilt, offset)
        if cand is None:
            continue
        ok = np.all(cand @ A.T + b + support >= 0.0, axis=1)
        if not ok.any():
            continue
        cand = cand[ok]
        c3 = cand + offset
        if not gp.favourable:
            keep = _preset_filter(gp, cand, c3, R_cw, n, d, K, H_m)
            cand, c3 = cand[keep], c3[keep]
            if not len(cand):
                continue
        # prefer placements where person and reflection lie apart in the image
        sep = np.linalg.norm(project(K, c3) - project(K, c3 - 2.0 * ((c3 @ n) - d)[:, None] * n),
                             axis=-1)
        good = np.flatnonzero(sep >= np.quantile(sep, gp.prefer_apart))
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
        c = origin + offset
        chosen = dict(R_body=R, origin=origin, facing=facing, attempts=attempt + 1,
                      margin_px=margin, camera_tilt=tilt, R_world=R_cw, geometry=gp.name,
                      focal_px=float(K[0, 0]),
                      camera_height=float(-origin @ R_cw[:, 1]),
                      person_to_mirror=float(d - c @ n),
                      parallax_deg=float(parallax_deg(c[None], n, d)[0]))
        return chosen, H_m, n, d, X, rc, mc, ri, mi
    return (None,) * 9


def _preset_filter(gp: GeometryPreset, cand: np.ndarray, c3: np.ndarray, R_cw: np.ndarray,
                   n: np.ndarray, d: float, K: np.ndarray, H_m: float) -> np.ndarray:
    """``(N,)`` the candidates (origins ``cand``, motion centres ``c3``, ``(N, 3)``) that
    keep the preset's ranges: distance to the mirror, camera height, the centre's
    parallax and the reflection's least height in the image."""
    pm = d - c3 @ n
    keep = (pm >= gp.person_to_mirror[0] - 1e-9) & (pm <= gp.person_to_mirror[1] + 1e-9)
    height = -cand @ R_cw[:, 1]                              # R_cw[:, 1]: the world's up
    keep &= (height >= gp.camera_height[0]) & (height <= gp.camera_height[1])
    if gp.parallax_deg is not None:
        par = parallax_deg(c3, n, d)
        keep &= (par >= gp.parallax_deg[0]) & (par <= gp.parallax_deg[1])
    if gp.min_reflection_px is not None:
        depth = (c3 + 2.0 * pm[:, None] * n)[:, 2]              # S(c) = c + 2 (d - n . c) n
        keep &= K[0, 0] * H_m >= gp.min_reflection_px * depth
    return keep


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
    # lazy: importing scipy.signal costs ~0.35 s, and this module is loaded by
    # `import mirrorgraph.synth` and `mirrorgraph --help`
    from scipy.signal import lfilter

    w = rng.standard_normal(shape)
    w[:, 0] /= np.sqrt(1.0 - rho ** 2)          # start in the stationary distribution
    return lfilter([np.sqrt(1.0 - rho ** 2)], [1.0, -rho], w, axis=1)


def observe_keypoints(rng: np.random.Generator, clean: np.ndarray, size: tuple[int, int],
             noise_mean: float, noise_std: float, outlier_rate: float, missing_rate: float,
             single_person_rate: float, noise_correlation: float = 0.0,
             joint_bias_px: float = 0.0, rng_detector: np.random.Generator | None = None,
             bias_flip: np.ndarray | None = None):
    """Noisy detections ``(V, T, J, 3)`` of clean points ``(V, T, J, 2)``.

    With ``bias_flip`` (the skeleton's left/right map; ``V = 2``, view 1 the
    reflection in real-joint labels) the per-joint bias follows the detector's
    label: label ``j`` is off by ``b_j`` on the person and by ``b_j`` mirrored
    horizontally on the reflection, whose real joint ``k`` the detector labels
    ``flip[k]``.
    """
    V, T, J, _ = clean.shape
    if noise_correlation > 0 or joint_bias_px > 0:
        xy = clean + noise_mean
        if noise_std > 0:
            xy = xy + noise_std * _correlated_noise(rng_detector, clean.shape, noise_correlation)
        if joint_bias_px > 0 and bias_flip is None:
            xy = xy + rng_detector.normal(0.0, joint_bias_px, (V, 1, J, 2))
        elif joint_bias_px > 0:
            b = rng_detector.normal(0.0, joint_bias_px, (J, 2))
            xy = xy + np.stack([b, b[bias_flip] * np.array([-1.0, 1.0])])[:, None]
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
