"""Synthetic gym scenes: several people exercising before one mirror (:func:`make_crowd`).

The camera of :mod:`.camera` (a pinhole of horizontal field of view ``fov_deg``, the
principal point within +-4 px of the centre) stands ``camera_height`` metres above the
floor, pitched down by a few degrees; a vertical mirror wall faces it, its normal
``mirror_angle_deg`` off the optical axis (left or right), ``mirror_distance`` metres
from the camera along its normal (the plane ``n . X = d`` of :mod:`mirrorgraph.geometry`,
real camera frame). ``people`` people, each a body of :mod:`.body` with its own
proportions and height (1.55-1.95 m), exercise (:mod:`.motion`, each their own motion)
on the floor ``1-4 m`` in front of the mirror (``person_to_mirror``), facing the camera or
the mirror, at least ``min_spacing`` metres apart; a position is drawn again until every
joint of the person and of their reflection projects inside the image (4 % margin) in
every frame, lies 0.5 m or more in front of the camera, and the person's image and their
reflection's lie apart (centroids :data:`APART` of the person's image height or more:
a person standing before their own reflection hides it, which the detector model does
not simulate). Occlusions of one person by another are not simulated either, only the
scripted ones below.

Detector (:func:`~.detector.observe_keypoints`, the model of :mod:`.scene`): each person
and each reflection gets Gaussian noise, outliers, missing joints, left/right swaps of
the reflection; occlusions: each person is hidden, with probability ``occluded_rate``,
during one to three intervals of 5-40 frames, the direct view, the reflection or both
(someone passes in front). The detections of a frame are listed in random order; the
truth of every listed detection (whose it is, direct or reflection) is kept.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..keypoints import RawDetections
from ..skeletons import Skeleton, skeleton_by_name
from .body import check_skeleton, make_body, skeleton_points
from .camera import Z_MIN, check_camera_args, project, random_camera_matrix, rot_x, rot_y
from .detector import observe_keypoints
from .motion import generate_motion

__all__ = ["SyntheticCrowd", "make_crowd"]

#: Least distance between a person's and their reflection's centroids in the image, in
#: units of the person's height there: a person does not stand before their reflection.
APART = 0.4

#: Body/world frame (x left, y up, z forward) to a level camera (x right, y down, z fwd).
_WORLD_TO_LEVEL_CAMERA = np.diag([-1.0, -1.0, 1.0])


@dataclass
class SyntheticCrowd:
    """Several people before one mirror: ground truth and a detector's output.

    Attributes:
        K: ``(3, 3)`` camera matrix.
        image_size: ``(width, height)`` px.
        normal: ``(3,)`` unit mirror normal (away from the camera); distance: ``d`` (m).
        skeleton: the keypoint layout.
        fps: frame rate.
        frame_ids: ``(T,)`` frame numbers.
        joints3d: ``(P, T, J, 3)`` every person's joints, metres, real camera frame.
        heights: ``(P,)`` standing heights, m.
        person_to_mirror: ``(P,)`` each person's mean distance from the mirror, m.
        detections: what the detector lists per frame.
        truth_person: ``T`` int arrays, the person of each listed detection.
        truth_reflection: ``T`` bool arrays, the listed detection is a reflection.
        occluded: ``(P, 2, T)`` bool, the direct view / reflection hidden by an occlusion.
        seed: the seed; options: the arguments.
    """

    K: np.ndarray
    image_size: tuple[int, int]
    normal: np.ndarray
    distance: float
    skeleton: Skeleton
    fps: float
    frame_ids: np.ndarray
    joints3d: np.ndarray
    heights: np.ndarray
    person_to_mirror: np.ndarray
    detections: RawDetections
    truth_person: list[np.ndarray]
    truth_reflection: list[np.ndarray]
    occluded: np.ndarray
    seed: int | None = None
    options: dict = field(default_factory=dict)

    @property
    def num_people(self) -> int:
        """``P``."""
        return int(self.joints3d.shape[0])


def _mirror(rng: np.random.Generator, R_cw: np.ndarray, angle_deg: float, distance: float
            ) -> tuple[np.ndarray, float]:
    """A vertical mirror: unit normal (camera frame) ``angle_deg`` off the optical axis in
    the horizontal plane of the world, to the left or right at random, and ``d``."""
    side = rng.choice([-1.0, 1.0])
    a = np.radians(angle_deg) * side
    axis_w = R_cw.T @ np.array([0.0, 0.0, 1.0])
    yaw0 = np.arctan2(axis_w[0], axis_w[2])
    n_w = np.array([np.sin(yaw0 + a), 0.0, np.cos(yaw0 + a)])
    n = R_cw @ n_w
    return n / np.linalg.norm(n), float(distance)


def _inside(K, size, margin, X, n, d) -> bool:
    """Every joint of ``X`` ``(T, J, 3)`` and of its reflection in front of the camera,
    inside the image with ``margin`` px, in front of the mirror, and the two images
    :data:`APART`."""
    w, h = size
    S = X - 2.0 * ((X @ n) - d)[..., None] * n
    seen = []
    for P in (X, S):
        if not np.all(P[..., 2] > Z_MIN):
            return False
        uv = project(K, P)
        if not (np.all(uv[..., 0] >= margin) and np.all(uv[..., 0] <= w - margin)
                and np.all(uv[..., 1] >= margin) and np.all(uv[..., 1] <= h - margin)):
            return False
        seen.append(uv)
    # the person does not hide their own reflection: the two lie apart in every frame
    tall = np.ptp(seen[0][..., 1], axis=-1)                                  # (T,)
    apart = np.linalg.norm(seen[0].mean(-2) - seen[1].mean(-2), axis=-1)     # (T,)
    return bool(np.all(X @ n < d - 0.2) and np.all(apart >= APART * tall))


def _place_people(rng, K, size, R_cw, n, d, locals_, heights, camera_height, to_mirror,
                  min_spacing, margin, attempts):
    """Floor positions: ``(P, T, J, 3)`` joints and each person's distance from the mirror,
    or ``None`` when a person finds no place in ``attempts`` draws."""
    up_c = R_cw @ np.array([0.0, 1.0, 0.0])            # world up in camera coordinates
    n_w = R_cw.T @ n
    yaw_mirror = np.arctan2(n_w[0], n_w[2])
    lateral_w = np.array([np.cos(yaw_mirror), 0.0, -np.sin(yaw_mirror)])
    out, dist, placed = [], [], []
    for local, H in zip(locals_, heights):
        ok = False
        for _ in range(attempts):
            s = rng.uniform(*to_mirror)
            # a floor point s from the mirror (n is horizontal: n . foot = 0), sideways
            # along the mirror within the camera's view at about that depth
            lat = rng.uniform(-1.0, 1.0) * (d - s) * np.tan(np.radians(30.0))
            c = -camera_height * up_c + (d - s) * n + lat * (R_cw @ lateral_w)
            if any(np.linalg.norm(c - p) < min_spacing for p in placed):
                continue
            facing = yaw_mirror + (0.0 if rng.random() < 0.5 else np.pi)
            facing += np.radians(rng.uniform(-20.0, 20.0))
            R = R_cw @ rot_y(facing)                     # body -> camera
            X = (local @ R.T) * H + c
            if _inside(K, size, margin, X, n, d):
                ok = True
                break
        if not ok:
            return None
        placed.append(c)
        out.append(X)
        dist.append(float(d - np.mean(X.reshape(-1, 3) @ n)))
    return np.stack(out), np.array(dist)


def _occlusions(rng: np.random.Generator, P: int, T: int, rate: float) -> np.ndarray:
    """``(P, 2, T)`` bool: the hidden intervals of each person's direct view / reflection."""
    occ = np.zeros((P, 2, T), dtype=bool)
    for p in range(P):
        if rng.random() >= rate:
            continue
        for _ in range(rng.integers(1, 4)):
            length = int(rng.integers(5, 41))
            start = int(rng.integers(0, max(T - length, 1)))
            which = rng.integers(0, 3)                  # direct, reflection, both
            views = [0] if which == 0 else [1] if which == 1 else [0, 1]
            occ[p, views, start:start + length] = True
    return occ


def make_crowd(*, people: int = 4, frames: int = 300, seed: int | None = 0,
               skeleton: str | Skeleton = "COCO_17", image_size: tuple[int, int] = (1920, 1080),
               fov_deg: float = 70.0, mirror_angle_deg: float | None = None,
               mirror_distance: float | None = None,
               person_to_mirror: tuple[float, float] = (1.0, 4.0),
               camera_height: float = 1.6, noise_std: float = 4.0, noise_mean: float = 0.0,
               outlier_rate: float = 0.0, missing_rate: float = 0.0, lr_swap_rate: float = 0.0,
               occluded_rate: float = 0.0, min_spacing: float = 0.9, fps: float = 30.0,
               attempts: int = 400, lr_swap_views: str = "mirror") -> SyntheticCrowd:
    """A gym scene: ``people`` people before one mirror (the module docstring's model).

    Args:
        people: ``P`` (>= 1).
        frames: ``T``.
        seed: seed of :func:`numpy.random.default_rng` (the same seed, the same scene).
        skeleton: keypoint layout or its name.
        image_size: ``(width, height)`` px.
        fov_deg: horizontal field of view, degrees.
        mirror_angle_deg: the normal's angle to the optical axis (``None``: 10-35 deg).
        mirror_distance: ``d``, m (``None``: 7.5-9.5 m).
        person_to_mirror: range of each person's distance from the mirror, m.
        camera_height: above the floor, m.
        noise_std, noise_mean: the detector's Gaussian noise, px.
        outlier_rate, missing_rate, lr_swap_rate: as :func:`~.scene.make_scene`'s.
        occluded_rate: fraction of people hidden during a few short intervals.
        min_spacing: nearest two people's floor points may be, m.
        fps: frame rate.
        attempts: draws of a person's position before the whole scene is drawn again.
        lr_swap_views: ``"mirror"``: the swaps label the reflection unflipped (its labels
            against the person's); ``"both"``: also the person's own left/right swapped in
            both views in other frames (a detector mistaking which way a person faces), at
            the same rate.

    Raises:
        ValueError: an option out of range, or no placement fits after 20 scenes.
    """
    T, w, h = check_camera_args(frames, image_size, fov_deg, fps, noise_std)
    if people < 1:
        raise ValueError(f"people must be >= 1, got {people}")
    for name, v in (("outlier_rate", outlier_rate), ("missing_rate", missing_rate),
                    ("lr_swap_rate", lr_swap_rate), ("occluded_rate", occluded_rate)):
        if not 0.0 <= v <= 1.0:
            raise ValueError(f"{name} must be in [0, 1], got {v}")
    if lr_swap_views not in ("mirror", "both"):
        raise ValueError(f"lr_swap_views must be 'mirror' or 'both', got {lr_swap_views!r}")
    skel = skeleton_by_name(skeleton) if isinstance(skeleton, str) else skeleton
    check_skeleton(skel)
    size = (w, h)
    rng = np.random.default_rng(seed)
    K = random_camera_matrix(rng, size, fov_deg)
    bodies = [make_body(rng) for _ in range(people)]
    locals_ = [skeleton_points(generate_motion(b, T, fps, rng), skel) for b in bodies]
    heights = rng.uniform(1.55, 1.95, people)
    margin = 0.04 * min(w, h)
    for _ in range(20):
        R_cw = rot_x(np.radians(rng.uniform(-12.0, -4.0))) @ _WORLD_TO_LEVEL_CAMERA
        ang = mirror_angle_deg if mirror_angle_deg is not None else rng.uniform(10.0, 35.0)
        dist = mirror_distance if mirror_distance is not None else rng.uniform(7.5, 9.5)
        n, d = _mirror(rng, R_cw, ang, dist)
        placed = _place_people(rng, K, size, R_cw, n, d, locals_, heights, camera_height,
                               person_to_mirror, min_spacing, margin, attempts)
        if placed is not None:
            break
    else:
        raise ValueError(f"cannot place {people} people before the mirror inside the "
                         f"{w}x{h} image; try fewer people or a wider field of view")
    X, to_m = placed
    flip = skel.flip
    J = skel.num_joints
    occ = _occlusions(rng, people, T, occluded_rate)
    dets, owner = [], []
    for p in range(people):
        S = X[p] - 2.0 * ((X[p] @ n) - d)[..., None] * n
        clean = np.stack([project(K, X[p]), project(K, S)])
        obs, _, _, detected = observe_keypoints(rng, clean, size, noise_mean, noise_std,
                                                outlier_rate, missing_rate, 0.0)
        detected &= ~occ[p]
        swap = (rng.random(T) < lr_swap_rate) & detected[1]
        mirror_labels = np.where(swap[:, None, None], obs[1], obs[1][:, flip])
        real_labels = obs[0]
        if lr_swap_views == "both":
            both = (rng.random(T) < lr_swap_rate)[:, None, None]
            real_labels = np.where(both, real_labels[:, flip], real_labels)
            mirror_labels = np.where(both, mirror_labels[:, flip], mirror_labels)
        dets.append((real_labels, mirror_labels))
        owner.append(detected)
    frame_people, frame_owner, frame_refl = [], [], []
    for t in range(T):
        rows, who, is_r = [], [], []
        for p in range(people):
            for v in (0, 1):
                if owner[p][v, t]:
                    rows.append(dets[p][v][t])
                    who.append(p)
                    is_r.append(v == 1)
        order = rng.permutation(len(rows))
        frame_people.append(np.array(rows, dtype=float).reshape(-1, J, 3)[order])
        frame_owner.append(np.array(who, dtype=int)[order])
        frame_refl.append(np.array(is_r, dtype=bool)[order])
    frame_ids = np.arange(T, dtype=np.int64)
    raw = RawDetections(skeleton=skel, frame_ids=frame_ids, people=frame_people,
                        source=f"synthetic-crowd(seed={seed})", format="synthetic",
                        image_size=size, fps=float(fps))
    options = dict(people=people, frames=frames, seed=seed, skeleton=skel.name,
                   image_size=list(size), fov_deg=fov_deg, mirror_angle_deg=mirror_angle_deg,
                   mirror_distance=mirror_distance, person_to_mirror=list(person_to_mirror),
                   camera_height=camera_height, noise_std=noise_std, noise_mean=noise_mean,
                   outlier_rate=outlier_rate, missing_rate=missing_rate,
                   lr_swap_rate=lr_swap_rate, occluded_rate=occluded_rate,
                   min_spacing=min_spacing, fps=fps, lr_swap_views=lr_swap_views)
    return SyntheticCrowd(K=K, image_size=size, normal=n, distance=d, skeleton=skel,
                          fps=float(fps), frame_ids=frame_ids, joints3d=X, heights=heights,
                          person_to_mirror=to_m, detections=raw, truth_person=frame_owner,
                          truth_reflection=frame_refl, occluded=occ, seed=seed,
                          options=options)
