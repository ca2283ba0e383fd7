"""Bystanders of the synthetic rigs of :mod:`.rig` (``make_rig(..., bystanders=N)``).

Draws other people and places them near the subject, in the room frame of
:mod:`.rig_placement` (``Y`` up, floor at ``Y = 0``, metres), and gives their
views per camera; :func:`~.rig.make_rig` runs the detector on them and moves
them to the world frame (camera 0's).

Each bystander has their own body (:func:`.body.make_body`),
motion (:func:`.motion.generate_motion`) and height (1.55-1.95 m), faces any
way, and is in the room for one stretch of 40-80 % of the frames (so the
subject is the person seen longest). Their motion's centre is 1-2.5 m from the
subject's, in a direction at least 30 deg from every mirror's normal (a
bystander straight behind the subject along the normal would lie on the
subject's epipolar lines), at least 0.2 m in front of every mirror and 1 m
(horizontally) from every camera. A camera *sees* a bystander when it sees
them whole, directly and in each of its mirrors, in at least half of their
frames: every camera with a mirror and at least half of the cameras must, and
where a camera sees them their torso (shoulders and hips) and the subject's do
not overlap horizontally in the image, in the direct views and the single
reflections, in at least 80 % of their frames (each draw of up to 1000 is
checked; a ``ValueError`` when none passes). Their views are
named after them (:func:`~.rig_types.bystander_name`). They draw from their own
generator (``default_rng([seed, 1])``): with the same seed the rig, the subject
and the subject's detections are those without bystanders.
"""

from __future__ import annotations

import numpy as np

from ..skeletons import Skeleton
from .body import make_body, skeleton_points
from .motion import generate_motion
from .rig_placement import (apart_fraction, camera_views, full_fraction, gap_ok,
                            motion_centre, place_person)
from .rig_types import bystander_name

_BYSTANDER_DISTANCE = (1.0, 2.5)   # m: a bystander's motion centre from the subject's
_BYSTANDER_PRESENT = (0.4, 0.8)    # fraction of the frames a bystander is in the room
_BYSTANDER_FULL = 0.5    # ... of which each camera sees them whole, directly and in each mirror
_BYSTANDER_APART = 0.8   # ... and their torso apart from the subject's views
_BYSTANDER_NORMAL_DEG = 30.0   # least angle between their offset and a mirror's normal
_BYSTANDER_CAMERA_GAP = 1.0    # m: nearest (horizontally) a bystander may stand to a camera
_BYSTANDER_ATTEMPTS = 1000     # placements drawn per bystander


def _main_views(views: list) -> list:
    """The direct view and the single reflections of a :func:`camera_views` list."""
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
    reflections, :func:`camera_views` tuples) that the bystander must not overlap.
    """
    centre = motion_centre(X_subject)
    normals = [m.n for m in mirrors.values()]
    cos_max = np.cos(np.radians(_BYSTANDER_NORMAL_DEG))
    for attempt in range(_BYSTANDER_ATTEMPTS):
        dist = rng.uniform(*_BYSTANDER_DISTANCE)
        az = rng.uniform(-np.pi, np.pi)
        yaw = rng.uniform(-np.pi, np.pi)
        offset = np.array([np.sin(az), 0.0, np.cos(az)])
        if any(abs(offset @ n) > cos_max for n in normals):
            continue           # in line with a mirror's normal: on the subject's epipolar lines
        X = place_person(local, H, yaw, np.zeros(3))
        shift = centre + dist * offset - motion_centre(X)      # their centre there, on the floor
        shift[1] = 0.0
        X = X + shift
        if not gap_ok(X, mirrors):
            continue
        here = motion_centre(X)
        if any(np.hypot(*(here - c.C)[[0, 2]]) < _BYSTANDER_CAMERA_GAP for c in cams):
            continue
        views, ok, seen_by = [], True, 0
        for cam, K, other in zip(cams, Ks, others):
            vs = camera_views(cam, K, size, X, mirrors, double)
            vs = [(n, paths, flipped, uv, vis & present[:, None])
                  for n, paths, flipped, uv, vis in vs]
            main = _main_views(vs)
            seen = all(full_fraction(v[4][present]) >= _BYSTANDER_FULL for v in main)
            ok = (seen or not cam.sees) and (not seen or all(
                apart_fraction(v[3][present], o[3][present], torso) >= _BYSTANDER_APART
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


def bystander_rng(seed) -> np.random.Generator:
    """The bystanders' own generator: the subject's draws stay those without them."""
    return np.random.default_rng() if seed is None else np.random.default_rng([seed, 1])


def make_bystanders(rng, count: int, skel: Skeleton, fps: float, cams: list, Ks: list,
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
