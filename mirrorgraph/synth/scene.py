"""Synthetic mirror scenes: placement, projection and a pose-detector noise model.

Geometry (the conventions of the whole package): one pinhole camera at the origin of the
real camera frame (``x`` right, ``y`` down, ``z`` forward, metres); the mirror plane is
``n . X = d`` with ``n`` a unit vector pointing away from the camera and ``d > 0``. A
point ``X`` is imaged directly at ``pi(K X)`` and in the mirror at ``pi(K S(X))``,
``S(X) = X - 2 (n . X - d) n``.

Camera matrix: ``fx = fy = (w / 2) / tan(fov / 2)`` (``fov`` horizontal), zero skew,
principal point ``(w / 2 + dx, h / 2 + dy)``, ``dx, dy`` uniform in +-4 px.

The scene: a slightly tilted camera looks at a person who exercises
(:mod:`~mirrorgraph.synth.motion`) between the camera and the mirror, facing roughly the
camera or the mirror, turning up to +-70 deg; the geometry's ranges are a preset of
:mod:`.geometry` (``geometry=``). Placement (:mod:`.placement`) is exact: every
requirement is a half-space constraint met by the convex hull of the motion. With
``motion="take.bvh"`` a motion-capture take replaces the procedural motion
(:mod:`~mirrorgraph.synth.mocap`).

Detector model (after MirrorCalib, Liao, Zheng and Mitchell), in image pixels: Gaussian
noise of mean ``noise_mean`` and std ``noise_std`` added after lens distortion; then
outliers displaced 30-150 px (``outlier_rate``), confidences from Beta distributions,
missing people and joints (``missing_rate``), one of the two undetected
(``single_person_rate``), left/right swaps (``lr_swap_rate``, ``lr_swap_views``; in long
runs of one view: ``lr_crossed_view``),
outliers along the epipolar line (``epipolar_outlier_rate``), per-joint bias
(``joint_bias_px``, ``joint_bias_shared``), AR(1) noise (``noise_correlation``) and
bystanders (``extra_person_rate``); :mod:`.detector` names a ``"realistic"`` detector
built of these. Coordinates are clipped to the image; people are listed per frame in
random order. Each term in full: ``docs/internals.md``.
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
from .camera import D_FLIP, check_camera_args, distort_pixels, random_camera_matrix
from .detector import (bystander_keypoints, crossed_runs, displace_along_epipolar_lines,
                       observe_keypoints)
from .geometry import PRESETS, GeometryPreset, resolve_geometry
from .motion import generate_motion
from .placement import place

__all__ = ["SyntheticScene", "make_scene"]


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
            left and right swapped (``lr_swap_views="both"`` or
            ``lr_crossed_view="real"``; all False otherwise).
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
               joint_bias_shared: bool = False,
               body_variation: float | str = 0.03, lr_crossed_view: str | None = None,
               lr_crossed_fraction: float = 1.0,
               lr_crossed_run: float = 90.0) -> SyntheticScene:
    """Generate a synthetic mirror scene (see the module docstring for the model).

    Long for its 29 documented options only: the body is the named steps below it.

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
        body_variation: the individual's proportions: the relative std of each
            segment kind, or ``"population"``, each kind's spread among adults
            (:func:`~mirrorgraph.synth.body.make_body`; the same draws either way, so
            only the body changes). Not used with ``motion`` (the take's own body).
        lr_crossed_view: ``"real"`` or ``"mirror"``: the view whose labels the detector
            crosses in long runs (a body seen from behind labelled as one facing the
            camera; :func:`~mirrorgraph.synth.detector.crossed_runs`), on top of the
            per-frame swaps; ``None``: none.
        lr_crossed_fraction: the share of that view's frames crossed (``1``: the
            whole clip).
        lr_crossed_run: the mean length of a crossed run, frames.

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
    _record_variant_options(options, gp, focal_px=focal_px, lr_swap_views=lr_swap_views,
                            epipolar_outlier_rate=epipolar_outlier_rate,
                            joint_bias_shared=joint_bias_shared, body_variation=body_variation,
                            lr_crossed_view=lr_crossed_view,
                            lr_crossed_fraction=lr_crossed_fraction,
                            lr_crossed_run=lr_crossed_run)
    T, w, h = check_camera_args(frames, image_size, 60.0 if fov_deg is None else fov_deg, fps,
                                noise_std)
    _check_scene_args(options, epipolar_outlier_rate, focal_px, lr_swap_views)
    _check_crossed_args(lr_crossed_view, lr_crossed_fraction, lr_crossed_run)
    dist = _distortion_coefficients(distortion)
    skel = skeleton_by_name(skeleton) if isinstance(skeleton, str) else skeleton
    check_skeleton(skel)
    size = (w, h)

    rng = np.random.default_rng(seed)
    K = random_camera_matrix(rng, size, 60.0 if fov_deg is None else fov_deg)
    if focal_px is not None:
        K[0, 0] = K[1, 1] = float(focal_px)
    body, local, take_height, take_info = _person_motion(rng, motion, T, fps, skel,
                                                         body_variation)
    chosen, H_m, n, d, X, rc, mc, ri, mi = place(
        rng, gp, K, size, local, dist, subject_height=subject_height, take_height=take_height,
        mirror_angle_deg=mirror_angle_deg, mirror_distance=mirror_distance,
        focal=fov_deg is not None or focal_px is not None)
    if chosen is None:
        raise _no_placement_error(gp, size, fov_deg, focal_px, motion, take_height,
                                  mirror_angle_deg, mirror_distance, subject_height)

    seed0 = 0 if seed is None else int(seed)
    obs, miss, outl, epi, detected = _observe(
        rng, seed0, np.stack([ri, mi]), np.stack([rc, mc]), K, n, size, dist, skel.flip,
        noise_mean, noise_std, outlier_rate, missing_rate, single_person_rate,
        noise_correlation, joint_bias_px, joint_bias_shared, epipolar_outlier_rate)
    swap, swap_real, det_real, det_mirror = _lr_swaps(
        rng, seed0, obs, detected, skel.flip, lr_swap_rate, lr_swap_views,
        (lr_crossed_view, lr_crossed_fraction, lr_crossed_run))
    extra = rng.random(T) < extra_person_rate
    extra_people = bystander_keypoints(rng, local, np.flatnonzero(extra), K, size,
                                       chosen["margin_px"], chosen["R_world"], noise_mean,
                                       noise_std, missing_rate)
    frame_ids = np.arange(T, dtype=np.int64)
    people = _people_per_frame(rng, T, skel.num_joints, (det_real, det_mirror, extra_people),
                               (detected[0], detected[1], extra))
    del det_real, det_mirror, extra_people
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


# ------------------------------------------------------------------ make_scene's steps
def _record_variant_options(options: dict, gp: GeometryPreset, **variants) -> None:
    """Add to ``options`` the options of the presets and detector models where they are not
    the default (a ``"favourable"`` scene's options name no geometry)."""
    if gp.name != "favourable" or PRESETS.get(gp.name) is not gp:
        options["geometry"] = gp.name if PRESETS.get(gp.name) is gp else asdict(gp)
    defaults = dict(focal_px=None, lr_swap_views="mirror", epipolar_outlier_rate=0.0,
                    joint_bias_shared=False, body_variation=0.03, lr_crossed_view=None,
                    lr_crossed_fraction=1.0, lr_crossed_run=90.0)
    for key, default in defaults.items():
        if variants[key] != default:
            options[key] = variants[key]


def _check_scene_args(options: dict, epipolar_outlier_rate: float, focal_px: float | None,
                      lr_swap_views: str) -> None:
    """Raise ValueError naming the first of :func:`make_scene`'s options out of range
    (``options``: the ones it records; the camera's are :func:`check_camera_args`'s)."""
    if not 0.0 <= options["noise_correlation"] < 1.0:
        raise ValueError(f"noise_correlation must be in [0, 1), got {options['noise_correlation']}")
    if options["joint_bias_px"] < 0:
        raise ValueError(f"joint_bias_px must be >= 0, got {options['joint_bias_px']}")
    rates = [(name, options[name]) for name in ("outlier_rate", "lr_swap_rate", "missing_rate",
                                                "extra_person_rate", "single_person_rate")]
    for name, v in rates + [("epipolar_outlier_rate", epipolar_outlier_rate)]:
        if not 0.0 <= v <= 1.0:
            raise ValueError(f"{name} must be in [0, 1], got {v}")
    mirror_angle_deg = options["mirror_angle_deg"]
    if mirror_angle_deg is not None and not 0.0 <= mirror_angle_deg < 90.0:
        raise ValueError(f"mirror_angle_deg must be in [0, 90), got {mirror_angle_deg}")
    if options["mirror_distance"] is not None and options["mirror_distance"] <= 0:
        raise ValueError(f"mirror_distance must be positive, got {options['mirror_distance']}")
    if options["subject_height"] is not None and options["subject_height"] <= 0:
        raise ValueError(f"subject_height must be positive, got {options['subject_height']}")
    if focal_px is not None and not focal_px > 0:
        raise ValueError(f"focal_px must be positive, got {focal_px}")
    if lr_swap_views not in ("mirror", "both"):
        raise ValueError(f"lr_swap_views must be 'mirror' or 'both', got {lr_swap_views!r}")


def _check_crossed_args(view: str | None, fraction: float, run: float) -> None:
    """Raise ValueError naming the first of the crossed runs' options out of range."""
    if view not in (None, "real", "mirror"):
        raise ValueError(f"lr_crossed_view must be None, 'real' or 'mirror', got {view!r}")
    if not 0.0 <= fraction <= 1.0:
        raise ValueError(f"lr_crossed_fraction must be in [0, 1], got {fraction}")
    if not run >= 1.0:
        raise ValueError(f"lr_crossed_run must be >= 1 frame, got {run}")


def _distortion_coefficients(distortion: Any) -> np.ndarray | None:
    """``(5,)`` OpenCV coefficients from 4 or 5 given ones, or ``None``."""
    if distortion is None:
        return None
    dist = np.zeros(5)
    dv = np.asarray(distortion, dtype=float).ravel()
    if len(dv) not in (4, 5) or not np.all(np.isfinite(dv)):
        raise ValueError("distortion must be 4 or 5 finite OpenCV coefficients "
                         "(k1, k2, p1, p2[, k3])")
    dist[:len(dv)] = dv
    return dist


def _person_motion(rng: np.random.Generator, motion, T: int, fps: float, skel: Skeleton,
                   variation: float | str = 0.03):
    """The person's motion in the body frame, units of height: ``(body, local, take_height,
    take_info)``, ``local`` ``(T, J, 3)`` the skeleton's joints; the procedural motion of a
    body drawn with ``variation`` (:func:`~.body.make_body`), or a motion-capture take
    (``body`` ``None``, the take's height and record)."""
    take_info = None
    if motion is None:
        body = make_body(rng, variation)
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
    return body, skeleton_points(full, skel), take_height, take_info


def _no_placement_error(gp: GeometryPreset, size: tuple[int, int], fov_deg: float | None,
                        focal_px: float | None, motion, take_height: float | None,
                        mirror_angle_deg: float | None, mirror_distance: float | None,
                        subject_height: float | None) -> ValueError:
    """The error of a scene no placement fits: what was given, what to try."""
    w, h = size
    given = [k for k, v in (("mirror_angle_deg", mirror_angle_deg),
                            ("mirror_distance", mirror_distance),
                            ("subject_height", subject_height)) if v is not None]
    if motion is not None:
        given.append("motion" + ("" if subject_height is not None
                                 else f" (subject {take_height:.2f} m)"))
    view = (f"a {fov_deg:g} deg field of view" if fov_deg is not None else
            f"a focal length of {focal_px:g} px" if focal_px is not None else
            f"focal lengths of {gp.focal_px[0]:g}-{gp.focal_px[1]:g} px")
    return ValueError(
        "cannot place the person so that they and their reflection stay inside the "
        f"{w}x{h} image with {view}"
        + ("" if gp.name == "favourable" else f" (geometry {gp.name!r})")
        + (f" with the given {', '.join(given)}" if given else "")
        + ("; try fewer frames, a wider field of view or a larger mirror distance"
           if motion is not None else
           "; try a wider field of view, a larger mirror distance or a shorter subject"))


def _observe(rng: np.random.Generator, seed0: int, obs_clean: np.ndarray, clean: np.ndarray,
             K: np.ndarray, n: np.ndarray, size: tuple[int, int], dist: np.ndarray | None,
             flip: np.ndarray, noise_mean: float, noise_std: float, outlier_rate: float,
             missing_rate: float, single_person_rate: float, noise_correlation: float,
             joint_bias_px: float, joint_bias_shared: bool, epipolar_outlier_rate: float):
    """The detector's observations of both views (the module docstring's detector model
    but the left/right swaps and the bystanders): ``(obs, miss, outl, epi, detected)``.

    ``obs_clean`` ``(2, T, J, 2)`` the points as imaged, ``clean`` the pinhole ones; the
    AR(1) noise and bias, and the outliers along the epipolar line, draw from generators
    of their own (seeded from ``seed0``)."""
    out = observe_keypoints(rng, obs_clean, size, noise_mean, noise_std, outlier_rate,
                            missing_rate, single_person_rate, noise_correlation, joint_bias_px,
                            np.random.default_rng([seed0, 7919]),
                            bias_flip=flip if joint_bias_shared else None)
    obs, miss, outl, detected = out
    epi = np.zeros_like(outl)
    if epipolar_outlier_rate > 0:                           # a generator of their own
        epi = displace_along_epipolar_lines(
            np.random.default_rng([seed0, 104729]), obs[..., :2], obs[..., 2],
            clean, obs_clean, ~miss & ~outl, epipolar_outlier_rate, K, n, size,
            dist, distort_pixels)
        outl |= epi
    return obs, miss, outl, epi, detected


def _lr_swaps(rng: np.random.Generator, seed0: int, obs: np.ndarray, detected: np.ndarray,
              flip: np.ndarray, lr_swap_rate: float, lr_swap_views: str,
              crossed: tuple[str | None, float, float] = (None, 1.0, 90.0)):
    """The detector's left/right labels: ``(swap, swap_real, det_real, det_mirror)``, the
    frames whose reflection (person) is labelled unflipped (swapped) and the keypoints of
    both views as the detector labels them. ``crossed``: ``(view, fraction, mean run)`` of
    the runs of crossed labels (:func:`~.detector.crossed_runs`, a generator of their
    own), which cross the per-frame swaps' labels again (a swap within a run labels the
    frame right)."""
    T = obs.shape[1]
    swap = (rng.random(T) < lr_swap_rate) & detected[1]
    swap_real = np.zeros(T, dtype=bool)
    if lr_swap_views == "both":
        swap_real = (np.random.default_rng([seed0, 15485863]).random(T) < lr_swap_rate) \
            & detected[0]
    view, fraction, run = crossed
    if view is not None:
        runs = crossed_runs(np.random.default_rng([seed0, 32452843]), T, fraction, run)
        if view == "real":
            swap_real = (swap_real ^ runs) & detected[0]
        else:
            swap = (swap ^ runs) & detected[1]
    det_real = np.where(swap_real[:, None, None], obs[0][:, flip], obs[0]) if swap_real.any() \
        else obs[0]
    det_mirror = np.where(swap[:, None, None], obs[1], obs[1][:, flip])
    return swap, swap_real, det_real, det_mirror


def _people_per_frame(rng: np.random.Generator, T: int, J: int, keypoints: tuple,
                      present: tuple) -> list[np.ndarray]:
    """Each frame's people ``(P_t, J, 3)`` in random order: the person, the reflection and the
    bystanders (``keypoints``: ``(T, J, 3)``, ``(T, J, 3)`` and ``(E, J, 3)``; ``present``:
    ``(T,)`` bool, the frames each is detected in)."""
    groups = tuple(np.flatnonzero(p) for p in present)
    row_frame = np.concatenate(groups)
    key = rng.random(len(row_frame))
    order = np.lexsort((key, row_frame))             # people in random order per frame
    dest = np.empty_like(order)
    dest[order] = np.arange(len(order))
    allrows = np.empty((len(order), J, 3))
    start = 0
    for i, (src, rows_of) in enumerate(zip(keypoints, groups)):
        rows = src if i == 2 else src[rows_of]      # the bystanders' rows are all theirs
        allrows[dest[start:start + len(rows_of)]] = rows
        start += len(rows_of)
    counts = np.bincount(row_frame, minlength=T)
    return np.split(allrows, np.cumsum(counts)[:-1])
