"""Scene geometries of the synthetic generator, and how to measure a scene's geometry.

Frames and units are those of :mod:`.scene`: the real camera at the origin (``x`` right,
``y`` down, ``z`` forward), metres; the mirror ``n . X = d`` with ``n`` pointing away from
the camera; a level camera's world frame has ``y`` up.

Presets (:data:`PRESETS`, chosen with ``make_scene(geometry=...)``; every range is
sampled uniformly and redrawn with the rest of the placement when no position fits):

* ``"favourable"`` (the default, :data:`DEFAULT_GEOMETRY`): mirror 2.5-4.5 m, normal
  10-60 deg off the optical axis, 60 deg field of view; person ~2000 px from the epipole,
  rays meeting at ~70 deg;
* ``"gym"``: a camera on a tripod before a wall mirror 3.5-8 m away, the person
  0.8-2.5 m in front of it, focal 800-1600 px; the regime of the independent fixtures
  (~400 px from the epipole, rays ~30 deg apart);
* ``"wide"``: everything a user may film (mirror 2.5-10 m, focal 700-2200 px, normal
  5-70 deg off the axis);
* ``"low_parallax"``: the ``"wide"`` ranges with the person near the camera-mirror line
  (rays 2-12 deg apart).

The non-favourable presets place a vertical mirror (up to ``mirror_lean_deg``) in a world
whose floor the tilted camera sees, keep every joint between the camera and the mirror,
and require a reflection at least ``min_reflection_px`` tall. Every range in full:
:data:`PRESETS` and ``docs/internals.md``.

Geometry measurements (:func:`geometry_stats`): for pairs of a joint ``u`` and its
reflection ``u'`` (undistorted pixels), the epipole ``e ~ K n``, the distance ``|u - e|``
and the angle between the joint's two viewing rays, ``K^-1 u`` from the real camera and
``H K^-1 u'`` from the virtual one (``H = I - 2 n n^T``): the angle of the two lines in
``[0, 90]`` deg, 0 on the camera-mirror line (no triangulation), 90 at best.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np

from .. import geometry as geo
from ..keypoints import DEFAULT_MIN_CONFIDENCE

__all__ = ["DEFAULT_GEOMETRY", "GeometryPreset", "PRESETS", "resolve_geometry",
           "vertical_mirror_normal", "parallax_deg", "ray_angles_deg", "geometry_stats",
           "scene_geometry_stats", "pair_by_epipole"]

#: The preset ``make_scene`` uses when ``geometry`` is not given. Flip to ``"gym"``
#: once the solver holds in that regime (the one line to change).
DEFAULT_GEOMETRY = "favourable"


@dataclass(frozen=True)
class GeometryPreset:
    """Ranges of a scene geometry (see the module docstring).

    Ranges are ``(low, high)`` sampled uniformly; ``None`` where the preset does
    not constrain the quantity.

    Attributes:
        name: the preset's name.
        mirror_distance: camera-to-mirror distance ``d``, m.
        mirror_angle_deg: angle between the mirror normal and the optical axis, deg.
        focal_px: focal length ``fx = fy``, px; ``None``: from ``fov_deg`` (60 deg).
        person_to_mirror: distance of the centre of the person's motion from the
            mirror plane, m; ``None``: anywhere that fits.
        camera_height: height of the camera above the floor, m (``"box"``
            sampler: the range of the floor point's ``y`` in the camera frame).
        pitch_std_deg, pitch_max_deg: camera pitch ``N(0, std)`` clipped at +-max.
        roll_std_deg, roll_max_deg: camera roll, the same way.
        vertical_mirror: a vertical mirror in the world (leaning by up to
            ``mirror_lean_deg``) whose normal makes the drawn angle with the
            optical axis; ``False``: the normal drawn in the camera frame, turned
            left or right with ``mirror_azimuth_deg`` of azimuth (favourable).
        mirror_azimuth_deg: see ``vertical_mirror``.
        mirror_lean_deg: see ``vertical_mirror``.
        facing_mirror: probability that the person faces the mirror (else the camera).
        facing_jitter_deg: the facing direction varies by +- this.
        sampler: how candidate positions are drawn: ``"box"`` (uniform in a box
            of the camera frame: favourable), ``"slab"`` (lateral position, camera
            height and distance to the mirror), ``"axis"`` (near the line from
            the camera along the normal).
        column_frac: the ``"slab"`` sampler puts the motion's centre in the middle
            ``column_frac`` of the image's horizontal field of view (1: anywhere).
        prefer_apart: candidates are kept whose person-reflection separation in
            the image is at least this quantile of the feasible ones (0: any).
        parallax_deg: angle between the two rays of the person's centre, deg.
        margin_frac: image margin, fraction of the shorter image side.
        min_reflection_px: least height of the reflection, px (``f H / depth``).
        between: every joint at ``n . X >= 0`` (between the camera and the mirror).
    """

    name: str
    mirror_distance: tuple[float, float] = (2.5, 4.5)
    mirror_angle_deg: tuple[float, float] = (10.0, 60.0)
    focal_px: tuple[float, float] | None = None
    person_to_mirror: tuple[float, float] | None = None
    camera_height: tuple[float, float] = (-0.2, 2.2)
    pitch_std_deg: float = 4.0
    pitch_max_deg: float = 10.0
    roll_std_deg: float = 1.5
    roll_max_deg: float = 3.0
    vertical_mirror: bool = False
    mirror_azimuth_deg: float = 20.0
    mirror_lean_deg: float = 0.0
    facing_mirror: float = 0.5
    facing_jitter_deg: float = 15.0
    sampler: str = "box"
    column_frac: float = 1.0
    prefer_apart: float = 0.5
    parallax_deg: tuple[float, float] | None = None
    margin_frac: float = 0.04
    min_reflection_px: float | None = None
    between: bool = False

    @property
    def favourable(self) -> bool:
        """The generator's original model (box sampler, normal in the camera frame)."""
        return self.sampler == "box" and not self.vertical_mirror

    def replace(self, **changes) -> "GeometryPreset":
        """A copy with some ranges changed, e.g. ``PRESETS["gym"].replace(focal_px=(900, 900))``."""
        return replace(self, **changes)


_WIDE = dict(mirror_distance=(2.5, 10.0), mirror_angle_deg=(5.0, 70.0), focal_px=(700.0, 2200.0),
             person_to_mirror=(0.5, 3.5), camera_height=(0.3, 2.5), pitch_std_deg=8.0,
             pitch_max_deg=20.0, roll_std_deg=2.5, roll_max_deg=6.0, vertical_mirror=True,
             mirror_lean_deg=5.0, facing_mirror=0.5, facing_jitter_deg=20.0, sampler="slab",
             prefer_apart=0.0, margin_frac=0.02, min_reflection_px=120.0, between=True)

#: The geometries ``make_scene(geometry=NAME)`` knows (see the module docstring).
PRESETS: dict[str, GeometryPreset] = {
    "favourable": GeometryPreset("favourable"),
    "gym": GeometryPreset("gym", **dict(
        _WIDE, mirror_distance=(3.5, 8.0), mirror_angle_deg=(8.0, 30.0),
        focal_px=(800.0, 1600.0), person_to_mirror=(0.8, 2.5), camera_height=(0.6, 1.6),
        column_frac=0.4,
        pitch_std_deg=5.0, pitch_max_deg=12.0, roll_std_deg=1.5, roll_max_deg=4.0,
        mirror_lean_deg=2.0, facing_mirror=0.6, facing_jitter_deg=15.0,
        min_reflection_px=150.0)),
    "wide": GeometryPreset("wide", **_WIDE),
    "low_parallax": GeometryPreset("low_parallax", **dict(
        _WIDE, mirror_angle_deg=(5.0, 40.0), sampler="axis", parallax_deg=(2.0, 12.0))),
}


def resolve_geometry(geometry: "str | GeometryPreset | None") -> GeometryPreset:
    """The :class:`GeometryPreset` of a name (``None``: :data:`DEFAULT_GEOMETRY`) or a preset.

    Raises:
        ValueError: an unknown name or an inconsistent preset.
    """
    if geometry is None:
        geometry = DEFAULT_GEOMETRY
    if isinstance(geometry, str):
        if geometry not in PRESETS:
            raise ValueError(f"unknown geometry {geometry!r}; known: {', '.join(PRESETS)}")
        return PRESETS[geometry]
    if not isinstance(geometry, GeometryPreset):
        raise ValueError(f"geometry must be a preset name or a GeometryPreset, got {geometry!r}")
    g = geometry
    if g.sampler not in ("box", "slab", "axis"):
        raise ValueError(f"unknown sampler {g.sampler!r}; known: box, slab, axis")
    if g.sampler != "box" and g.person_to_mirror is None:
        raise ValueError(f"the {g.sampler!r} sampler needs a person_to_mirror range")
    for name in ("mirror_distance", "mirror_angle_deg", "focal_px", "person_to_mirror",
                 "camera_height", "parallax_deg"):
        r = getattr(g, name)
        if r is not None and not (len(r) == 2 and r[0] <= r[1]):
            raise ValueError(f"{name} must be a (low, high) range, got {r!r}")
    if not (0 < g.mirror_angle_deg[0] or g.favourable) or g.mirror_angle_deg[1] >= 90.0:
        raise ValueError(f"mirror_angle_deg must lie in (0, 90), got {g.mirror_angle_deg}")
    return g


def vertical_mirror_normal(R_cw: np.ndarray, angle: float, lean: float, side: float
                           ) -> np.ndarray | None:
    """Normal ``(3,)`` (camera frame) of a vertical mirror at ``angle`` from the optical axis.

    The mirror stands on the floor of the world frame (``y`` up) and leans by
    ``lean``; its normal ``n_w = (cos(lean) sin(psi), sin(lean), cos(lean) cos(psi))``
    turns about the vertical by the ``psi`` that makes ``n . z_camera = cos(angle)``,
    to the left or the right of the optical axis by the sign of ``side``.

    Args:
        R_cw: ``(3, 3)`` world (``y`` up) to camera rotation (the camera's tilt included).
        angle: angle between the normal and the optical axis, radians.
        lean: the mirror's lean (rotation of the normal out of the floor plane), radians.
        side: ``+1`` or ``-1``.

    Returns:
        The unit normal in the camera frame, or ``None`` when no vertical mirror
        of that lean makes that angle with this camera's axis (a steep pitch).
    """
    o = R_cw[2]                                   # the optical axis in the world frame
    rho, phi = np.hypot(o[0], o[2]), np.arctan2(o[0], o[2])
    c = (np.cos(angle) - np.sin(lean) * o[1]) / (np.cos(lean) * rho)
    if not -1.0 <= c <= 1.0:
        return None
    psi = phi + np.sign(side) * np.arccos(c)
    n_w = np.array([np.cos(lean) * np.sin(psi), np.sin(lean), np.cos(lean) * np.cos(psi)])
    return R_cw @ n_w


# ------------------------------------------------------------------ measurements
def parallax_deg(X: np.ndarray, n: np.ndarray, d: float) -> np.ndarray:
    """Angle between the rays of 3D points from the camera and from the virtual camera.

    Args:
        X: ``(N, 3)`` points, real camera frame, metres.
        n: ``(3,)`` unit mirror normal; d: mirror distance (m).

    Returns:
        ``(N,)`` degrees in ``[0, 90]``: the angle between the lines through ``X``
        from the camera centre and from the virtual camera's centre ``2 d n``
        (the 3D form of :func:`ray_angles_deg`;
        :func:`mirrorgraph.geometry.mirror_ray_angles_deg`).
    """
    return geo.mirror_ray_angles_deg(X, n, d)


def ray_angles_deg(K: np.ndarray, n: np.ndarray, u: np.ndarray, u_mirror: np.ndarray
                   ) -> np.ndarray:
    """Angle between each joint's two viewing rays, degrees in ``[0, 90]``.

    Args:
        K: ``(3, 3)`` camera matrix.
        n: ``(3,)`` unit mirror normal, camera frame.
        u: ``(N, 2)`` pixels of the joints (undistorted).
        u_mirror: ``(N, 2)`` pixels of their reflections.

    Returns:
        ``(N,)`` the angle between the lines ``K^-1 u`` (real camera) and
        ``H K^-1 u'`` (virtual camera) at the joint.
    """
    Kinv = np.linalg.inv(np.asarray(K, float))
    r1 = geo.to_homogeneous(u) @ Kinv.T
    r2 = geo.to_homogeneous(u_mirror) @ (geo.householder(n) @ Kinv).T
    c = np.abs(np.einsum("ij,ij->i", r1, r2)) / (np.linalg.norm(r1, axis=1)
                                                  * np.linalg.norm(r2, axis=1))
    return np.degrees(np.arccos(np.clip(c, 0.0, 1.0)))


def geometry_stats(K: np.ndarray, n: np.ndarray, u: np.ndarray, u_mirror: np.ndarray) -> dict:
    """How favourable a mirror scene is, from joint/reflection pairs.

    Args:
        K: ``(3, 3)``; n: ``(3,)`` unit normal (camera frame).
        u, u_mirror: ``(N, 2)`` pixels of the joints and of their reflections
            (undistorted; rows with NaN are ignored).

    Returns:
        ``epipole_px`` (median distance of the joints from the epipole, px),
        ``ray_deg_median``, ``ray_deg_p5``, ``ray_deg_p95`` (the angle of
        :func:`ray_angles_deg`), ``separation_px`` (median ``|u - u'|``) and ``pairs``.
    """
    u = np.asarray(u, float).reshape(-1, 2)
    v = np.asarray(u_mirror, float).reshape(-1, 2)
    ok = np.isfinite(u).all(1) & np.isfinite(v).all(1)
    u, v = u[ok], v[ok]
    if len(u) == 0:
        nan = float("nan")
        return dict(epipole_px=nan, ray_deg_median=nan, ray_deg_p5=nan, ray_deg_p95=nan,
                    separation_px=nan, pairs=0)
    ang = ray_angles_deg(K, n, u, v)
    p5, p50, p95 = np.percentile(ang, [5, 50, 95])
    e = geo.epipole_pixels(geo.epipole_from_normal(K, n))
    return dict(epipole_px=float(np.median(np.linalg.norm(u - e, axis=1))) if e is not None
                else float("inf"),
                ray_deg_median=float(p50), ray_deg_p5=float(p5), ray_deg_p95=float(p95),
                separation_px=float(np.median(np.linalg.norm(u - v, axis=1))), pairs=int(len(u)))


def scene_geometry_stats(scene, joints: np.ndarray | None = None) -> dict:
    """:func:`geometry_stats` of a :class:`~.scene.SyntheticScene` (noise-free pinhole pixels).

    Args:
        scene: the scene.
        joints: joint indices (default: the skeleton's calibration joints).
    """
    j = scene.skeleton.calibration_joints if joints is None else np.asarray(joints, int)
    return geometry_stats(scene.K, scene.normal, scene.real_clean[:, j], scene.mirror_clean[:, j])


def pair_by_epipole(people: list[np.ndarray], K: np.ndarray, n: np.ndarray, flip: np.ndarray,
                    joints: np.ndarray, max_line_px: float = 12.0,
                    min_confidence: float = DEFAULT_MIN_CONFIDENCE) -> tuple[np.ndarray, np.ndarray]:
    """Joint/reflection pairs of detections, paired with the *true* mirror (to measure a scene).

    In every frame with exactly two people, the reflection is the one nearer the
    epipole (it lies between the person and the epipole); its labels are flipped
    (:attr:`~mirrorgraph.skeletons.Skeleton.flip`) or not, whichever gives the
    smaller median epipolar distance (a detector's left/right swap). Pairs whose
    epipolar distance (:func:`mirrorgraph.geometry.epipolar_distances`) exceeds
    ``max_line_px`` (outliers) or below ``min_confidence`` are dropped.

    Args:
        people: per frame ``(P, J, 3)`` detections (x, y, confidence), undistorted.
        K: ``(3, 3)``; n: ``(3,)`` the true unit normal.
        flip: ``(J,)`` the skeleton's left/right map.
        joints: ``(k,)`` joint indices to pair.

    Returns:
        ``(u, u_mirror)``, each ``(N, 2)`` px, ``u_mirror`` in real-joint labels.

    Raises:
        ValueError: the epipole lies at infinity (a mirror parallel to the optical axis).
    """
    e_h = geo.epipole_from_normal(K, n)
    e = geo.epipole_pixels(e_h)
    if e is None:
        raise ValueError("pair_by_epipole needs an epipole in the image plane (n_z != 0)")
    two = [p for p in people if len(p) == 2]
    if not two:
        return np.zeros((0, 2)), np.zeros((0, 2))
    P = np.stack(two)                                            # (F, 2, J, 3)
    P = np.where((P[..., 2:3] >= min_confidence), P, np.nan)
    sel = P[:, :, joints]                                        # (F, 2, k, 3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)          # all-NaN rows
        far = np.nanmedian(np.linalg.norm(sel[..., :2] - e, axis=-1), axis=-1)   # (F, 2)
    F = len(P)
    person = np.argmax(np.nan_to_num(far, nan=-1.0), axis=1)
    real = P[np.arange(F), person][:, joints, :2]
    refl = P[np.arange(F), 1 - person]
    cand = np.stack([refl[:, flip][:, joints, :2], refl[:, joints, :2]])     # (2, F, k, 2)

    dist = geo.epipolar_distances(e_h, real[None], cand)         # (2, F, k)
    dist = np.where(np.isfinite(real[None]).all(-1) & np.isfinite(cand).all(-1), dist, np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        score = np.nanmedian(dist, axis=-1)                      # (2, F)
    pick = (np.nan_to_num(score[1], nan=np.inf) < np.nan_to_num(score[0], nan=np.inf))
    mirror = np.where(pick[:, None, None], cand[1], cand[0])
    d = np.where(pick[:, None], dist[1], dist[0])
    ok = np.isfinite(real).all(-1) & np.isfinite(mirror).all(-1) & (d < max_line_px)
    return real[ok], mirror[ok]

