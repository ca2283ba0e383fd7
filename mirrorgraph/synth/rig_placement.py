"""Placement of the synthetic rigs of :mod:`.rig`: the cameras, the mirrors and the person.

Builds each rig kind (:func:`build_4cams`, :func:`build_2cams1mirror`,
:func:`build_1cam2mirrors`) in a *room frame*: ``Y`` up, floor at ``Y = 0``,
metres. A camera is its centre ``C`` and its camera-to-room rotation ``R``
(columns: the camera's ``x`` right, ``y`` down, ``z`` forward); a mirror is the
plane ``n . X = d``, ``n`` pointing out of the room, with the reflective side
``n . X < d``. :func:`camera_views` gives what a camera sees of joints
``(T, J, 3)``: the pixels and visibility of the direct view and of the
reflections. :func:`~.rig.make_rig` checks the placement and moves it to the
world frame (camera 0's).

Visibility of a joint in a view (direct, or through a sequence of mirrors):

* direct: at least 0.5 m in front of the camera and projecting inside the
  image (``0 <= u <= w - 1``, ``0 <= v <= h - 1``);
* through mirrors: the camera and the joint are on the reflective side of each
  mirror on the path, the ray from the camera to the virtual point meets each
  mirror on its surface (inside the half-plane of a corner mirror) in order,
  and the virtual point is at least 0.5 m in front of the camera and projects
  inside the image.

Ranges (:class:`RigRanges`, :data:`RIG_PRESETS`, chosen by
``make_rig(geometry=...)``): ``"favourable"`` holds the ranges the rigs always
had (the default, bit for bit); ``"gym"`` and ``"wide"`` widen them as
:mod:`.geometry` does for one camera and a mirror: the person 0.8-2.5 m
(``"wide"``: 0.5-3.5 m) in front of the wall mirror, cameras 2.5-6 m (2-7 m)
from the person, 0.6-1.6 m (0.3-2.5 m) high, 8-45 deg (5-70 deg) off the
mirror's normal, focal lengths of 800-1600 px (700-2200 px) drawn per camera,
and every camera 3-8.5 m (2.5-10 m) from every mirror it sees.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..geometry import reflect_points
from .camera import project, rot_y, rot_z

_Z_MIN = 0.5            # m: nearest a visible point may be to the camera plane
_MIRROR_GAP = 0.2       # m: nearest a joint may come to a mirror
PERSON_FULL = 0.90     # fraction of frames each camera must see the whole person
REFLECTION_FULL = 0.75  # ... and the whole of each single reflection it sees
TORSOS_APART = 0.90          # ... and the torsos of any two of these apart in the image
MAX_ATTEMPTS = 300
_UP = np.array([0.0, 1.0, 0.0])
_DEG = np.pi / 180.0

PERSON = "person"       # the name of the direct view (re-exported by .rig_types and .rig)


@dataclass(frozen=True)
class RigRanges:
    """Ranges of a rig's placement (``(low, high)``, sampled uniformly; metres, degrees).

    Attributes:
        name: the preset's name.
        camera_distance: camera to the centre of the person's motion
            (``"4cams"``, ``"2cams1mirror"``).
        camera_height: camera height above the floor.
        roll_std_deg, roll_max_deg: camera roll ``N(0, std)`` clipped at +-max.
        person_to_mirror: the person's distance to the wall mirror (``"2cams1mirror"``).
        camera_separation_deg: azimuth between the two cameras around the person.
        camera_mid_deg: azimuth of their bisector from the mirror's normal.
        camera_off_normal_deg: each camera's azimuth from the normal (|angle|).
        corner_person_to_edge: the person's distance to the corner's edge (``"1cam2mirrors"``).
        corner_camera_further: the camera's distance to the edge beyond the person's.
        focal_px: focal length of each camera, px; ``None``: from ``fov_deg``.
        camera_to_mirror: every camera's distance to every mirror it sees;
            ``None``: not checked.
    """

    name: str
    camera_distance: tuple[float, float] = (3.0, 5.0)
    camera_height: tuple[float, float] = (1.0, 1.6)
    roll_std_deg: float = 1.0
    roll_max_deg: float = 2.0
    person_to_mirror: tuple[float, float] = (1.3, 2.2)
    camera_separation_deg: tuple[float, float] = (40.0, 90.0)
    camera_mid_deg: tuple[float, float] = (-15.0, 15.0)
    camera_off_normal_deg: tuple[float, float] = (15.0, 60.0)
    corner_person_to_edge: tuple[float, float] = (2.0, 2.6)
    corner_camera_further: tuple[float, float] = (3.5, 4.5)
    focal_px: tuple[float, float] | None = None
    camera_to_mirror: tuple[float, float] | None = None

    def replace(self, **changes) -> "RigRanges":
        """A copy with some ranges changed."""
        return replace(self, **changes)


#: The rig geometries ``make_rig(geometry=NAME)`` knows (see the module docstring).
RIG_PRESETS: dict[str, RigRanges] = {
    "favourable": RigRanges("favourable"),
    "gym": RigRanges("gym", camera_distance=(2.5, 6.0), camera_height=(0.6, 1.6),
                     roll_std_deg=1.5, roll_max_deg=4.0, person_to_mirror=(0.8, 2.5),
                     camera_separation_deg=(30.0, 90.0), camera_mid_deg=(-20.0, 20.0),
                     camera_off_normal_deg=(8.0, 45.0), corner_person_to_edge=(1.5, 3.0),
                     corner_camera_further=(2.5, 5.0), focal_px=(800.0, 1600.0),
                     camera_to_mirror=(3.0, 8.5)),
    "wide": RigRanges("wide", camera_distance=(2.0, 7.0), camera_height=(0.3, 2.5),
                      roll_std_deg=2.5, roll_max_deg=6.0, person_to_mirror=(0.5, 3.5),
                      camera_separation_deg=(20.0, 100.0), camera_mid_deg=(-30.0, 30.0),
                      camera_off_normal_deg=(5.0, 70.0), corner_person_to_edge=(1.0, 3.5),
                      corner_camera_further=(2.0, 6.5), focal_px=(700.0, 2200.0),
                      camera_to_mirror=(2.5, 10.0)),
}


#: The ranges ``make_rig`` uses when ``geometry`` is not given.
DEFAULT_RIG_GEOMETRY = "favourable"


def resolve_rig_ranges(geometry: "str | RigRanges | None") -> RigRanges:
    """The :class:`RigRanges` of a name (``None``: :data:`DEFAULT_RIG_GEOMETRY`) or the
    ranges themselves.

    Raises:
        ValueError: an unknown name.
    """
    if geometry is None:
        geometry = DEFAULT_RIG_GEOMETRY
    if isinstance(geometry, RigRanges):
        return geometry
    if geometry not in RIG_PRESETS:
        raise ValueError(f"unknown rig geometry {geometry!r}; known: {', '.join(RIG_PRESETS)}")
    return RIG_PRESETS[geometry]


_LEGACY = RIG_PRESETS["favourable"]


# --------------------------------------------------------------------------- geometry
def _look_at(C: np.ndarray, target: np.ndarray, roll: float) -> np.ndarray:
    """Camera-to-room rotation (columns: camera x right, y down, z forward), room ``Y`` up."""
    z = target - C
    z = z / np.linalg.norm(z)
    x = np.cross(z, _UP)
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    return np.column_stack([x, y, z]) @ rot_z(roll)


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
        virt = reflect_points(virt, m.n, m.d)
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
        target = reflect_points(target, m.n, m.d)            # continue toward the next image
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


def camera_views(cam: _Camera, K: np.ndarray, size: tuple[int, int], X: np.ndarray,
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


def first_camera_frame(cams: list, X_r: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
    """Room-frame points and cameras in the first camera's frame (the rig's world).

    Args:
        cams: placed cameras (``R`` world-to-camera rotation, ``C`` centre, room frame).
        X_r: ``(..., 3)`` points in the room frame.

    Returns:
        ``X_r`` in the first camera's frame, and every camera's ``(4, 4)``
        camera-to-world pose in it (the first: the identity).
    """
    R0, C0 = cams[0].R, cams[0].C
    poses = []
    for c in cams:
        P = np.eye(4)
        P[:3, :3] = R0.T @ c.R
        P[:3, 3] = R0.T @ (c.C - C0)
        poses.append(P)
    poses[0] = np.eye(4)
    return (X_r - C0) @ R0, poses


def motion_centre(X: np.ndarray) -> np.ndarray:
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


def full_fraction(vis: np.ndarray) -> float:
    return float(vis.all(-1).mean())


def apart_fraction(uv1: np.ndarray, uv2: np.ndarray, torso: np.ndarray) -> float:
    """Fraction of frames whose two views' torsos (shoulders and hips) do not
    overlap horizontally in the image."""
    x1, x2 = uv1[:, torso, 0], uv2[:, torso, 0]
    return float(((x1.max(1) < x2.min(1)) | (x2.max(1) < x1.min(1))).mean())


def gap_ok(X: np.ndarray, mirrors: dict[str, _Mirror]) -> bool:
    """Every joint at least ``_MIRROR_GAP`` in front of every mirror."""
    return all(float((X @ m.n - m.d).max()) <= -_MIRROR_GAP for m in mirrors.values())


def place_person(local: np.ndarray, H: float, yaw: float, origin: np.ndarray) -> np.ndarray:
    return (local @ rot_y(yaw).T) * H + origin


def _sample_camera(rng, centre: np.ndarray, azimuth: float, dist: float,
                   g: RigRanges = _LEGACY) -> np.ndarray:
    h = rng.uniform(*g.camera_height)
    return np.array([centre[0] + dist * np.sin(azimuth), h, centre[2] + dist * np.cos(azimuth)])


def _roll(rng, g: RigRanges = _LEGACY) -> float:
    return float(np.radians(np.clip(rng.normal(0.0, g.roll_std_deg), -g.roll_max_deg,
                                    g.roll_max_deg)))


def mirror_distances_ok(cams: list[_Camera], mirrors: dict[str, _Mirror], g: RigRanges) -> bool:
    """Every camera within ``g.camera_to_mirror`` of every mirror it sees (or no range)."""
    if g.camera_to_mirror is None:
        return True
    lo, hi = g.camera_to_mirror
    return all(lo <= mirrors[m].d - cam.C @ mirrors[m].n <= hi for cam in cams for m in cam.sees)


def build_4cams(rng, local, H, Ks, size, g: RigRanges = _LEGACY):
    yaw = rng.uniform(-np.pi, np.pi)
    X = place_person(local, H, yaw, np.zeros(3))
    centre = motion_centre(X)
    a0 = rng.uniform(-np.pi, np.pi)
    cams, info = [], dict(azimuth_deg=[], distance_m=[], height_m=[], camera_attempts=[])
    for k in range(4):
        for attempt in range(MAX_ATTEMPTS):
            az = a0 + k * np.pi / 2 + np.radians(rng.uniform(-10.0, 10.0))
            dist = rng.uniform(*g.camera_distance)
            C = _sample_camera(rng, centre, az, dist, g)
            target = centre + rng.uniform(-0.05, 0.05, 3)
            cam = _Camera(C=C, R=_look_at(C, target, _roll(rng, g)), sees=[])
            _, vis = _project_visible(cam, Ks[k], size, X)
            if full_fraction(vis) >= PERSON_FULL:
                break
        else:
            return None
        cams.append(cam)
        info["azimuth_deg"].append(float(np.degrees(az)))
        info["distance_m"].append(float(dist))
        info["height_m"].append(float(C[1]))
        info["camera_attempts"].append(attempt + 1)
    return X, cams, {}, dict(info, person_yaw_deg=float(np.degrees(yaw)), facing="any")


def build_2cams1mirror(rng, local, H, g: RigRanges = _LEGACY):
    wall = _Mirror("wall", np.array([0.0, 0.0, 1.0]), 0.0)
    mirrors = {"wall": wall}
    dp = rng.uniform(*g.person_to_mirror)
    origin = np.array([rng.uniform(-0.3, 0.3), 0.0, -dp])
    sep = rng.uniform(*g.camera_separation_deg)
    mid = rng.uniform(*g.camera_mid_deg)
    psi = np.radians([mid - sep / 2, mid + sep / 2])
    lo, hi = g.camera_off_normal_deg
    if np.any(np.abs(np.degrees(psi)) < lo) or np.any(np.abs(np.degrees(psi)) > hi):
        return None
    dists = rng.uniform(*g.camera_distance, 2)
    facing = "mirror" if rng.random() < 0.6 else "cameras"
    # room -Z points from the wall into the room; body z forward = room Z at yaw 0
    base = 0.0 if facing == "mirror" else np.pi - float(np.mean(psi))
    yaw = base + np.radians(rng.uniform(-20.0, 20.0))
    X = place_person(local, H, yaw, origin)
    if not gap_ok(X, mirrors):
        return None
    centre = motion_centre(X)
    refl = reflect_points(centre, wall.n, wall.d)
    cams = []
    for k in range(2):
        # azimuth psi around the person, from the normal into the room (-Z)
        C = _sample_camera(rng, centre, np.pi - psi[k], dists[k], g)
        target = _aim_between(C, [centre, refl], centre[1]) + rng.uniform(-0.05, 0.05, 3)
        cams.append(_Camera(C=C, R=_look_at(C, target, _roll(rng, g)), sees=["wall"]))
    info = dict(person_to_mirror_m=float(dp), camera_azimuth_deg=np.degrees(psi).tolist(),
                camera_separation_deg=float(sep), distance_m=dists.tolist(),
                height_m=[float(c.C[1]) for c in cams], person_yaw_deg=float(np.degrees(yaw)),
                facing=facing)
    return X, cams, mirrors, info


def build_1cam2mirrors(rng, local, H, alpha, g: RigRanges = _LEGACY):
    h = alpha / 2.0
    # the corner edge is the room's Y axis; the bisector runs into the room along -Z
    nA = np.array([np.cos(h), 0.0, np.sin(h)])       # the wall toward +X (camera's left)
    nB = np.array([-np.cos(h), 0.0, np.sin(h)])
    A = _Mirror("mirror_left", nA, 0.0, [(nB, 0.0)])
    B = _Mirror("mirror_right", nB, 0.0, [(nA, 0.0)])
    mirrors = {"mirror_left": A, "mirror_right": B}
    rp = rng.uniform(*g.corner_person_to_edge)
    beta = np.radians(rng.uniform(5.0, 12.0)) * rng.choice([-1.0, 1.0])
    origin = np.array([rp * np.sin(beta), 0.0, -rp * np.cos(beta)])
    # the camera off the bisector on the other side: the double reflection (the
    # person turned about the edge) then does not hide behind the person
    gamma = -np.sign(beta) * np.radians(rng.uniform(3.0, 8.0))
    rc = rp + rng.uniform(*g.corner_camera_further)
    facing = "camera" if rng.random() < 0.5 else "corner"
    to_corner = np.arctan2(-origin[0], -origin[2])   # body z forward toward the edge
    base = to_corner if facing == "corner" else to_corner + np.pi
    yaw = base + np.radians(rng.uniform(-25.0, 25.0))
    X = place_person(local, H, yaw, origin)
    if not gap_ok(X, mirrors):
        return None
    centre = motion_centre(X)
    C = np.array([rc * np.sin(gamma), rng.uniform(*g.camera_height), -rc * np.cos(gamma)])
    pts = [centre, reflect_points(centre, nA, 0.0), reflect_points(centre, nB, 0.0)]
    target = _aim_between(C, pts, centre[1]) + rng.uniform(-0.05, 0.05, 3)
    cam = _Camera(C=C, R=_look_at(C, target, _roll(rng, g)),
                  sees=["mirror_left", "mirror_right"])
    info = dict(corner_angle_deg=float(np.degrees(alpha)), person_to_edge_m=float(rp),
                person_off_bisector_deg=float(np.degrees(beta)), camera_to_edge_m=float(rc),
                camera_off_bisector_deg=float(np.degrees(gamma)), height_m=[float(C[1])],
                person_yaw_deg=float(np.degrees(yaw)), facing=facing)
    return X, [cam], mirrors, info
