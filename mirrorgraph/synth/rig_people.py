"""Synthetic rigs of several cameras watching several people (:func:`make_rig_people`).

The test and benchmark data of ``mirrorgraph calibrate-rig --people all``. ``people``
people, each a body of :mod:`.body` with their own proportions, height (1.55-1.95 m) and
exercise (:mod:`.motion`), stand on the floor of the room frame of :mod:`.rig_placement`
(``Y`` up, metres) within :data:`AREA_RADIUS` of the centre, each drifting along a
straight line of up to :data:`DRIFT_M` over the clip, any two at least
:data:`MIN_SPACING` apart (horizontally, motion centres) in every frame. ``cameras``
cameras stand on a ring about the centre (azimuths evenly spaced, +-15 deg; 4.5-7 m away;
1.2-2.5 m high; aimed at the centre with a small roll), drawn again until each sees every
person whole in 90 % of the frames.

Detector (:func:`~.detector.observe_keypoints`, the model of :mod:`.scene`): Gaussian
noise, outliers, missing joints; with ``lr_swap_rate`` a person's detection in a camera
carries swapped left/right labels in that fraction of frames; occlusions: with
probability ``occlusion_rate`` a person is hidden from a camera during one interval of
5-20 frames (someone passes in front). The detections of a frame are listed in random
order; :attr:`SyntheticRigPeople.owner` keeps whose each is.

With ``still`` the last ``still`` people stand still: one frame of their motion held,
no drift (the detector's noise alone moves their keypoints), and with ``bias_px`` their
keypoints carry a constant error per camera and joint (each coordinate drawn once from a
normal of std ``bias_px``): a real detector's error on a person who keeps their place
and pose, repeated in every frame.

With ``snapshots`` every frame is a snapshot :data:`SNAPSHOT_GAP` frames after the last:
each person stands within :data:`SNAPSHOT_MOVE` of their own place (staff at their posts),
turned any way, in a frame of their motion drawn at random: nothing continues from one
frame to the next but where people tend to stand.

World frame = camera 0's (``x`` right, ``y`` down, ``z`` forward), metres; poses
camera-to-world; pinhole cameras without distortion.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..io import write_keypoints
from ..io.atomic import atomic_write_text
from ..io.camera_toml import TomlCamera, write_camera_toml
from ..io.toml_writer import format_value
from ..keypoints import RawDetections
from ..skeletons import Skeleton, skeleton_by_name
from .body import make_body, skeleton_points
from .camera import check_camera_args, random_camera_matrix
from .detector import observe_keypoints
from .motion import generate_motion
from .camera import project, rot_z
from .rig_placement import first_camera_frame, full_fraction, motion_centre, place_person

__all__ = ["SyntheticRigPeople", "make_rig_people", "write_rig_people", "AREA_RADIUS",
           "DRIFT_M", "MIN_SPACING", "SNAPSHOT_GAP"]

#: m: the people's motion centres lie within this radius of the room's centre.
AREA_RADIUS = 1.6
#: m: the longest straight drift of a person over a clip.
DRIFT_M = 0.6
#: m: least horizontal distance between two people's centres in any frame.
MIN_SPACING = 0.9
#: Frames between two snapshots.
SNAPSHOT_GAP = 2250
#: m: how far (each horizontal axis) a person stands from their own place in a snapshot.
SNAPSHOT_MOVE = 0.4
_CAMERA_DISTANCE = (4.5, 7.0)
_CAMERA_HEIGHT = (1.2, 2.5)
_OCCLUSION_FRAMES = (5, 20)
_ATTEMPTS = 400


@dataclass
class SyntheticRigPeople:
    """Several cameras, several people: ground truth and a detector's output.

    Attributes:
        camera_names: ``cam01``, ``cam02``, ...
        K: ``(3, 3)`` per camera; image_size: ``(width, height)`` px.
        poses: ``(4, 4)`` camera-to-world per camera (camera 0: identity).
        skeleton: the keypoint layout; fps: frame rate.
        frame_ids: ``(T,)``.
        joints3d: ``(P, T, J, 3)`` every person's joints, world frame, metres.
        heights: ``(P,)`` m.
        detections: camera name -> :class:`~mirrorgraph.keypoints.RawDetections`.
        owner: camera name -> ``T`` int arrays ``(P_t,)``: whose each detection is.
        occluded: camera name -> ``(P, T)`` bool, the scripted occlusions.
        swapped: camera name -> ``(P, T)`` bool, detections with swapped left/right labels.
        options: the arguments.
    """

    camera_names: list[str]
    K: list[np.ndarray]
    image_size: tuple[int, int]
    poses: list[np.ndarray]
    skeleton: Skeleton
    fps: float
    frame_ids: np.ndarray
    joints3d: np.ndarray
    heights: np.ndarray
    detections: dict[str, RawDetections]
    owner: dict[str, list[np.ndarray]]
    occluded: dict[str, np.ndarray]
    options: dict
    swapped: dict[str, np.ndarray] | None = None

    @property
    def num_people(self) -> int:
        """``P``."""
        return int(self.joints3d.shape[0])


@dataclass
class _Cam:
    C: np.ndarray                      # centre, room frame
    R: np.ndarray                      # camera-to-room rotation (x right, y down, z forward)


def _aimed(C: np.ndarray, target: np.ndarray, roll: float) -> _Cam:
    """A camera at ``C`` looking at ``target`` (room ``Y`` up), rolled by ``roll`` rad."""
    z = (target - C) / np.linalg.norm(target - C)
    x = np.cross(z, [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    return _Cam(C, np.column_stack([x, np.cross(z, x), z]) @ rot_z(roll))


def _seen(cam: _Cam, K: np.ndarray, size, X: np.ndarray):
    """``(uv (..., 2), visible (...))``: in front (0.5 m or more) and inside the image."""
    Xc = (X - cam.C) @ cam.R
    front = Xc[..., 2] >= 0.5
    uv = project(K, np.where(front[..., None], Xc, 1.0))
    w, h = size
    return uv, front & (uv[..., 0] >= 0) & (uv[..., 0] <= w - 1) & (uv[..., 1] >= 0) \
        & (uv[..., 1] <= h - 1)


def _spaced(rng, P: int, home: np.ndarray | None = None) -> np.ndarray:
    """``(P, 2)`` centres within :data:`AREA_RADIUS` (or within :data:`SNAPSHOT_MOVE` of
    ``home``), :data:`MIN_SPACING` apart."""
    for _ in range(_ATTEMPTS):
        c = (rng.uniform(-1, 1, (P, 2)) * AREA_RADIUS if home is None
             else home + rng.uniform(-1, 1, (P, 2)) * SNAPSHOT_MOVE)
        d = np.linalg.norm(c[:, None] - c[None], axis=-1) + np.eye(P) * 1e9
        if d.min() >= MIN_SPACING and (np.linalg.norm(c, axis=1) <= AREA_RADIUS).all():
            return c
    raise ValueError(f"cannot place {P} people {MIN_SPACING} m apart within "
                     f"{AREA_RADIUS} m of the centre")


def _people(rng, P: int, T: int, fps: float, skel: Skeleton, snapshots: bool,
            still: int = 0):
    """Room-frame joints ``(P, T, J, 3)`` and heights ``(P,)`` (module docstring); the last
    ``still`` people hold their first frame, without drift."""
    motions, heights = [], []
    for _ in range(P):
        body = make_body(rng)
        motions.append(skeleton_points(generate_motion(body, T, fps, rng), skel))
        heights.append(float(rng.uniform(1.55, 1.95)))
    for _ in range(_ATTEMPTS):
        if snapshots:      # per frame: a place, a turn, a frame of the motion
            home = _spaced(rng, P)
            centres = np.stack([_spaced(rng, P, home) for _ in range(T)])
            yaws = rng.uniform(-np.pi, np.pi, (T, P))
            pick = rng.integers(0, T, (T, P))
        else:
            start = rng.uniform(-1, 1, (P, 2)) * AREA_RADIUS
            drift = rng.uniform(-1, 1, (P, 2)) * DRIFT_M / np.sqrt(2)
            drift[P - still:] = 0.0
            s = np.linspace(0.0, 1.0, T)[:, None, None]
            centres = start[None] + s * drift[None]
            yaws = np.repeat(rng.uniform(-np.pi, np.pi, P)[None], T, 0)
            pick = np.repeat(np.arange(T)[:, None], P, 1)
            pick[:, P - still:] = 0
        inside = np.linalg.norm(centres, axis=-1) <= AREA_RADIUS + DRIFT_M
        d = np.linalg.norm(centres[:, :, None] - centres[:, None], axis=-1)
        d[:, np.arange(P), np.arange(P)] = np.inf
        if inside.all() and d.min() >= MIN_SPACING:
            break
    else:
        raise ValueError(f"cannot place {P} people {MIN_SPACING} m apart within "
                         f"{AREA_RADIUS} m of the centre")
    J = skel.num_joints
    X = np.empty((P, T, J, 3))
    for p in range(P):
        local = motions[p][pick[:, p]]                                   # (T, J, 3)
        for t in range(T) if snapshots else [None]:
            rows = slice(None) if t is None else slice(t, t + 1)
            Xp = place_person(local[rows], heights[p], float(yaws[0 if t is None else t, p]),
                              np.zeros(3))
            c = motion_centre(place_person(motions[p], heights[p],
                                           float(yaws[0 if t is None else t, p]), np.zeros(3)))
            c[1] = 0.0
            Xp = Xp - c
            if t is None:
                Xp = Xp + np.stack([centres[:, p, 0], np.zeros(T), centres[:, p, 1]], -1)[:, None]
            else:
                Xp = Xp + np.array([centres[t, p, 0], 0.0, centres[t, p, 1]])
            X[p, rows] = Xp
    return X, np.array(heights)


def _cameras(rng, C: int, Ks: list, size, X: np.ndarray) -> list[_Cam]:
    """Cameras on a ring about the centre, each seeing every person whole in 90 % of the
    frames (drawn again until they do)."""
    a0 = rng.uniform(-np.pi, np.pi)
    centre = np.array([0.0, 0.9, 0.0])
    cams = []
    for k in range(C):
        for _ in range(_ATTEMPTS):
            az = a0 + 2 * np.pi * k / C + np.radians(rng.uniform(-15.0, 15.0))
            dist = rng.uniform(*_CAMERA_DISTANCE)
            Cc = np.array([dist * np.sin(az), rng.uniform(*_CAMERA_HEIGHT), dist * np.cos(az)])
            roll = float(np.radians(np.clip(rng.normal(0.0, 1.0), -2.0, 2.0)))
            cam = _aimed(Cc, centre + rng.uniform(-0.1, 0.1, 3), roll)
            if all(full_fraction(_seen(cam, Ks[k], size, Xp)[1]) >= 0.9
                   for Xp in X):
                break
        else:
            raise ValueError(f"cannot place camera {k + 1} to see every person; try fewer "
                             "people or a wider field of view")
        cams.append(cam)
    return cams


def make_rig_people(cameras: int = 4, people: int = 3, *, frames: int = 300,
                    seed: int | None = 0, skeleton: str | Skeleton = "BODY_25",
                    noise_std: float = 4.0, outlier_rate: float = 0.0,
                    missing_rate: float = 0.0, lr_swap_rate: float = 0.0,
                    occlusion_rate: float = 0.3, snapshots: bool = False,
                    still: int = 0, bias_px: float = 0.0,
                    image_size: tuple[int, int] = (1920, 1080), fov_deg: float = 60.0,
                    fps: float = 30.0) -> SyntheticRigPeople:
    """Generate a rig of ``cameras`` cameras watching ``people`` people (module docstring).

    Args:
        cameras: 2 or more; people: 1 or more.
        frames: ``T``; seed: of :func:`numpy.random.default_rng`.
        skeleton: the layout or its name.
        noise_std, outlier_rate, missing_rate: the detector's (px; fractions).
        lr_swap_rate: fraction of frames a camera's detection of a person carries
            swapped left/right labels.
        occlusion_rate: probability that a person is hidden from a camera once.
        snapshots: frames :data:`SNAPSHOT_GAP` apart, nothing continuing between them.
        still: the last ``still`` people stand still (not with ``snapshots``).
        bias_px: std of a still person's constant keypoint error per camera and joint, px.
        image_size, fov_deg, fps: the cameras'.

    Raises:
        ValueError: an option out of range, or no placement found.
    """
    if int(cameras) != cameras or cameras < 2:
        raise ValueError(f"cameras must be an integer >= 2, got {cameras}")
    if int(people) != people or people < 1:
        raise ValueError(f"people must be an integer >= 1, got {people}")
    for name, v in (("outlier_rate", outlier_rate), ("missing_rate", missing_rate),
                    ("lr_swap_rate", lr_swap_rate), ("occlusion_rate", occlusion_rate)):
        if not 0.0 <= v <= 1.0:
            raise ValueError(f"{name} must be in [0, 1], got {v}")
    if int(still) != still or not 0 <= still <= people or (still and snapshots):
        raise ValueError(f"still must be an integer in [0, people] without snapshots, "
                         f"got {still}")
    if not (bias_px >= 0 and np.isfinite(bias_px)):
        raise ValueError(f"bias_px must be >= 0, got {bias_px}")
    T, w, h = check_camera_args(frames, image_size, fov_deg, fps, noise_std)
    options = dict(cameras=int(cameras), people=int(people), frames=T, seed=seed,
                   noise_std=noise_std, outlier_rate=outlier_rate, missing_rate=missing_rate,
                   lr_swap_rate=lr_swap_rate, occlusion_rate=occlusion_rate,
                   snapshots=bool(snapshots), still=int(still), bias_px=float(bias_px),
                   image_size=[w, h], fov_deg=fov_deg, fps=fps)
    skel = skeleton_by_name(skeleton) if isinstance(skeleton, str) else skeleton
    size = (w, h)
    rng = np.random.default_rng(seed)
    Ks = [random_camera_matrix(rng, size, fov_deg) for _ in range(cameras)]
    X_r, H = _people(rng, int(people), T, fps, skel, snapshots, int(still))
    cams = _cameras(rng, int(cameras), Ks, size, X_r)
    joints3d, poses = first_camera_frame(cams, X_r)
    names = [f"cam{i + 1:02d}" for i in range(cameras)]
    frame_ids = np.arange(T, dtype=np.int64) * (SNAPSHOT_GAP if snapshots else 1)
    detections, owner, occluded, swapped = {}, {}, {}, {}
    J = skel.num_joints
    flip = np.asarray(skel.flip)
    for name, cam, K in zip(names, cams, Ks):
        uv, vis = zip(*[_seen(cam, K, size, Xp) for Xp in X_r])
        uv, vis = np.stack(uv), np.stack(vis)                       # (P, T, J, 2), (P, T, J)
        hidden = np.zeros((people, T), bool)
        for p in range(people):
            if rng.random() < occlusion_rate and not snapshots:
                n = int(rng.integers(_OCCLUSION_FRAMES[0], _OCCLUSION_FRAMES[1] + 1))
                s = int(rng.integers(0, max(T - n, 1)))
                hidden[p, s:s + n] = True
        if bias_px > 0 and still:   # a still person's constant error per joint, this camera
            uv = uv.copy()
            uv[people - still:] += rng.normal(0.0, bias_px, (still, 1, J, 2))
        filled = np.where(vis[..., None], uv, 0.0)
        obs, miss, _, detected = observe_keypoints(rng, filled, size, 0.0, noise_std,
                                                   outlier_rate, missing_rate, 0.0, 0.0)
        detected &= (vis.sum(-1) >= 5) & ~hidden
        miss |= ~vis | ~detected[..., None]
        obs[miss] = (np.nan, np.nan, 0.0)
        swap = (rng.random((people, T)) < lr_swap_rate) & detected
        obs = np.where(swap[..., None, None], obs[:, :, flip], obs)
        rows, own = [], []
        for t in range(T):
            who = np.flatnonzero(detected[:, t])
            who = who[rng.permutation(len(who))]
            rows.append(obs[who, t].reshape(-1, J, 3))
            own.append(who.astype(int))
        detections[name] = RawDetections(skeleton=skel, frame_ids=frame_ids, people=rows,
                                         source=f"synthetic-rig-people(seed={seed}):{name}",
                                         format="synthetic", image_size=size, fps=float(fps))
        owner[name] = own
        occluded[name] = hidden
        swapped[name] = swap
    return SyntheticRigPeople(camera_names=names, K=Ks, image_size=size, poses=poses,
                              skeleton=skel, fps=float(fps), frame_ids=frame_ids,
                              joints3d=joints3d, heights=H, detections=detections,
                              owner=owner, occluded=occluded, options=options,
                              swapped=swapped)


def write_rig_people(rig: SyntheticRigPeople, out_dir: str | os.PathLike, *,
                     subject_height: float | None = None) -> Path:
    """Write ``rig`` as a user of ``calibrate-rig`` has it: ``pose/<camera>.json`` (MMPose),
    ``Calib.toml`` (intrinsics, Pose2Sim's format), ``rig.toml`` (with
    ``subject_height`` where given). Returns the path of ``rig.toml``."""
    out = Path(out_dir)
    (out / "pose").mkdir(parents=True, exist_ok=True)
    for name in rig.camera_names:
        write_keypoints(rig.detections[name], out / "pose" / f"{name}.json", "mmpose",
                        meta=True)
    write_camera_toml(out / "Calib.toml",
                      [TomlCamera(key=n, name=n, matrix=K, distortions=np.zeros(4),
                                  size=tuple(rig.image_size))
                       for n, K in zip(rig.camera_names, rig.K)], "pose2sim",
                      header="Intrinsics of a synthetic rig of several people "
                             "(mirrorgraph.synth.rig_people); extrinsics unknown (zero).")
    lines = [f"# synthetic rig of {rig.num_people} people (mirrorgraph.synth.rig_people)", ""]
    if subject_height is not None:
        lines += [f"subject_height = {format_value(float(subject_height))}", ""]
    for n in rig.camera_names:
        lines += ["[[cameras]]", f"name = {format_value(n)}",
                  f"keypoints = {format_value(f'pose/{n}.json')}",
                  'intrinsics = "Calib.toml"', f"intrinsics_section = {format_value(n)}",
                  f"skeleton = {format_value(rig.skeleton.name)}", ""]
    path = out / "rig.toml"
    atomic_write_text(path, "\n".join(lines).rstrip("\n") + "\n")
    return path
