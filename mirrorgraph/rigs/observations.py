"""Per-camera keypoints of a rig, sorted into the person and their reflections, on one clock.

For each camera of a :class:`~mirrorgraph.rigs.config.RigConfig`: read the
keypoints (any format of :func:`mirrorgraph.io.read_keypoints`), read the
intrinsics and undistort, then sort every frame into the person and, for each
mirror the camera sees, their reflection (labels flipped to the real joints,
:func:`mirrorgraph.pairing.pair_reflections`). Cameras without a mirror keep,
per frame, the most confident detection, or, where a frame holds several people,
the one consistent with the first camera's person (:mod:`.matching`). Frames are
put on the rig's clock with each camera's ``frame_offset``.

Shapes: ``(T, J, 3)`` arrays (x px, y px, confidence) on the rig's ``T``
frames, undistorted pixels; NaN coordinates and confidence 0 where a camera
has no observation.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..errors import InputError
from ..intrinsics import Intrinsics, intrinsics_from_fov, load_intrinsics
from ..io import read_keypoints
from ..keypoints import PairedKeypoints, RawDetections
from ..pairing import pair_detections, pair_reflections
from ..pipeline import check_image_size, undistort_keypoints
from ..skeletons import Skeleton
from .config import CameraEntry, RigConfig

__all__ = ["CameraObservations", "RigObservations", "load_observations", "DEFAULT_FOV_DEG"]

#: Horizontal field of view assumed for a camera without intrinsics, degrees.
DEFAULT_FOV_DEG = 60.0


@dataclass
class CameraObservations:
    """One camera's keypoints on the rig's clock.

    Attributes:
        name: camera name.
        intrinsics: its intrinsics (``K`` pixels, distortion already removed from
            the keypoints below).
        real: ``(T, J, 3)`` the person.
        reflections: mirror name -> ``(T, J, 3)`` the person's reflection in that
            mirror, labels flipped (entry ``j`` images the real joint ``j``).
        source: the keypoint input.
        lr_fixes: reflection frames whose left/right labels were corrected.
        people: for a camera without mirrors, ``T`` arrays ``(P_t, J, 3)`` of every
            detection per frame (:func:`mirrorgraph.rigs.matching.match_people` picks
            the person among them); ``None`` otherwise.
        matched: frames where the cross-camera match chose another detection than
            the most confident one.
    """

    name: str
    intrinsics: Intrinsics
    real: np.ndarray
    reflections: dict[str, np.ndarray] = field(default_factory=dict)
    source: str = ""
    lr_fixes: int = 0
    people: list[np.ndarray] | None = None
    matched: int = 0


@dataclass
class RigObservations:
    """Every camera's observations on one clock.

    Attributes:
        skeleton: the keypoint layout (the same for every camera).
        frame_ids: ``(T,)`` rig frame numbers (camera frame minus its offset).
        cameras: per camera, in the rig file's order.
        mirrors: mirror names.
        fps: frame rate if an input carries it.
        warnings: what the user should know (assumed intrinsics, ...).
    """

    skeleton: Skeleton
    frame_ids: np.ndarray
    cameras: list[CameraObservations]
    mirrors: tuple[str, ...]
    fps: float | None = None
    warnings: list[str] = field(default_factory=list)


def _intrinsics(entry: CameraEntry, data, warnings: list[str]) -> Intrinsics:
    if entry.intrinsics is not None:
        section = entry.intrinsics_section
        if entry.intrinsics.suffix.lower() != ".toml" and section is not None:
            raise InputError("intrinsics_section applies to a .toml file only",
                             source=entry.intrinsics, field="intrinsics_section")
        intr = load_intrinsics(entry.intrinsics, camera=section)
    else:
        if data.image_size is None:
            raise InputError(f"camera {entry.name!r} has no intrinsics and its keypoints no "
                             "image size: add intrinsics = FILE to its [[cameras]] table",
                             source=data.source)
        intr = intrinsics_from_fov(data.image_size, DEFAULT_FOV_DEG)
        warnings.append(f"camera {entry.name}: no intrinsics given, assumed a "
                        f"{DEFAULT_FOV_DEG:g} deg field of view")
    check_image_size(data, intr, warnings)
    return intr


def _most_confident(raw: RawDetections, joints: np.ndarray) -> np.ndarray:
    """``(T, J, 3)``: per frame the detection with the largest summed confidence."""
    T, J = len(raw.people), raw.skeleton.num_joints
    out = np.full((T, J, 3), np.nan)
    out[..., 2] = 0.0
    for t, p in enumerate(raw.people):
        if len(p):
            conf = np.nan_to_num(np.asarray(p)[:, joints, 2])
            out[t] = p[int(np.argmax(conf.sum(1)))]
    return out


def _order_by_normal_x(K: np.ndarray, epipoles: list[np.ndarray]) -> np.ndarray:
    """Order of the mirrors by the ``x`` component of their normals (camera frame,
    normal turned to ``z > 0``): the mirror on the camera's left first."""
    xs = []
    for e in epipoles:
        n = np.linalg.solve(K, np.asarray(e, dtype=float))
        n = n / np.linalg.norm(n)
        xs.append(n[0] * (1.0 if n[2] >= 0 else -1.0))
    return np.argsort(xs, kind="stable")


def _sort_camera(entry: CameraEntry, data, intr: Intrinsics
                 ) -> tuple[np.ndarray, dict[str, np.ndarray], int]:
    sk = data.skeleton
    joints = sk.calibration_joints
    k = len(entry.mirrors)
    if isinstance(data, PairedKeypoints):
        if k > 1:
            raise InputError(f"a paired .npz holds one reflection but camera {entry.name!r} "
                             f"lists {k} mirrors", source=data.source, field="mirrors")
        return data.real, ({entry.mirrors[0]: data.mirror} if k else {}), 0
    if k == 0:
        return _most_confident(data, joints), {}, 0
    if k == 1:
        paired = pair_detections(data)
        return paired.real, {entry.mirrors[0]: paired.mirror}, paired.lr_fixes
    pairing = pair_reflections(data, k)
    order = _order_by_normal_x(intr.K, pairing.epipoles)
    refl = {entry.mirrors[i]: pairing.reflections[j] for i, j in enumerate(order)}
    return pairing.real, refl, pairing.lr_fixes


def _match_across_cameras(cameras: list[CameraObservations], skeleton: Skeleton) -> None:
    """For every camera without mirrors but the first, the person consistent with the
    first camera's person (:func:`mirrorgraph.rigs.matching.match_people`), in place."""
    from .matching import match_people

    ref = cameras[0]
    for cam in cameras[1:]:
        if cam.people is None or not any(len(p) > 1 for p in cam.people):
            continue
        cam.real, cam.matched = match_people(ref.real, ref.intrinsics.K, cam.people,
                                             cam.intrinsics.K, skeleton)


def load_observations(config: RigConfig, *, skeleton: Skeleton | str | None = None,
                      progress: Callable[[str], None] | None = None) -> RigObservations:
    """Read, undistort and sort every camera's keypoints (see the module docstring).

    Args:
        config: the rig.
        skeleton: layout for cameras whose table names none (default: from the
            keypoint count).
        progress: called with the camera's name before it is read.

    Raises:
        InputError: unreadable input (naming the file), cameras with different
            skeletons.
        DegenerateGeometryError: a camera's reflections cannot be sorted out.
    """
    warnings: list[str] = []
    per_camera, layouts, fps = [], [], None
    for entry in config.cameras:
        if progress is not None:
            progress(entry.name)
        data = read_keypoints(entry.keypoints, skeleton=entry.skeleton or skeleton)
        intr = _intrinsics(entry, data, warnings)
        data = undistort_keypoints(data, intr)
        real, refl, fixes = _sort_camera(entry, data, intr)
        frames = np.asarray(data.frame_ids, dtype=np.int64) - entry.frame_offset
        people = data.people if isinstance(data, RawDetections) and not entry.mirrors else None
        per_camera.append((entry, intr, frames, real, refl, fixes, data.source, people))
        layouts.append(data.skeleton)
        fps = fps or data.fps
    names = {s.name for s in layouts}
    if len(names) > 1:
        raise InputError(f"the cameras' keypoints use different skeletons ({', '.join(sorted(names))});"
                         " name one with skeleton = ... in each [[cameras]] table",
                         source=config.source, field="cameras")
    sk = layouts[0]
    frame_ids = np.unique(np.concatenate([f for _, _, f, *_ in per_camera]))
    T, J = len(frame_ids), sk.num_joints
    cameras = []
    for entry, intr, frames, real, refl, fixes, source, people in per_camera:
        rows = np.searchsorted(frame_ids, frames)
        if people is not None:
            everyone = [np.zeros((0, J, 3))] * T
            for r, p in zip(rows, people):
                everyone[r] = np.asarray(p, dtype=float).reshape(-1, J, 3)
            people = everyone

        def place(a: np.ndarray) -> np.ndarray:
            out = np.full((T, J, 3), np.nan)
            out[..., 2] = 0.0
            out[rows] = a
            return out

        cameras.append(CameraObservations(
            name=entry.name, intrinsics=intr, real=place(real),
            reflections={m: place(a) for m, a in refl.items()}, source=source, lr_fixes=fixes,
            people=people))
    _match_across_cameras(cameras, sk)
    return RigObservations(skeleton=sk, frame_ids=frame_ids, cameras=cameras,
                           mirrors=config.mirrors, fps=fps, warnings=warnings)
