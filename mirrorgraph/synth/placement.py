"""Where the mirror and the person go in a synthetic scene (:func:`place`).

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

The ranges drawn are a geometry preset's (:mod:`.geometry`); the scene's module docstring
(:mod:`.scene`) has the placement's conventions.
"""

from __future__ import annotations

import numpy as np

from .camera import Z_MIN, distort_pixels, project, rot_x, rot_y, rot_z
from .geometry import GeometryPreset, parallax_deg, vertical_mirror_normal

__all__ = ["MAX_ATTEMPTS", "place"]

_MIRROR_GAP = 0.2     # m: nearest a joint may come to the mirror
MAX_ATTEMPTS = 400
_CANDIDATES = 4096
_HULL_MIN_POINTS = 3000

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
    b_img = np.array([0.0, 0.0, 0.0, 0.0, -Z_MIN])
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


def _tilt(rng: np.random.Generator, gp: GeometryPreset) -> np.ndarray:
    """A camera tilt ``(3, 3)`` (level camera to camera): pitch about ``x``, then roll
    about ``z``, each drawn from the preset's clipped normal distribution."""
    return rot_x(np.radians(np.clip(rng.normal(0.0, gp.pitch_std_deg), -gp.pitch_max_deg,
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


def place(rng: np.random.Generator, gp: GeometryPreset, K: np.ndarray, size: tuple[int, int],
           local: np.ndarray, dist: np.ndarray | None, *, subject_height: float | None,
           take_height: float | None, mirror_angle_deg: float | None,
           mirror_distance: float | None, focal: bool):
    """Place the mirror and the person (this module's docstring).

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
