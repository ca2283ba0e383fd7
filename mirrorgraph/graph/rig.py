"""The rig: cameras, mirrors and the views they form, with their observations.

A *view* is what one camera sees either directly (``mirror=None``) or through
one mirror. MirrorCalib's setting is one camera and one mirror, i.e. two views
of the same person: ``("cam", None)`` and ``("cam", "mirror")``. The graph
builder only iterates over views, so more cameras (fixed, known poses) or more
mirrors need no other code.

Frames and units: every pose and plane is in the *world* frame, which for
:func:`single_mirror_rig` is the real camera frame of :mod:`mirrorgraph.geometry`
(x right, y down, z forward). Camera poses are camera-to-world ``(4, 4)``;
pixels are undistorted, origin top-left.

With the rig, its geometry: every view's projection matrix
(:func:`view_projections`), optical centre (:func:`view_centres`) and reprojection
residuals (:func:`view_residuals`), the joints triangulated from the views
(:func:`triangulate_rig`) and the angle their rays meet at (:func:`parallax_deg`);
and copies of a rig with other intrinsics, masks, poses or planes
(:func:`with_intrinsics`, :func:`with_views`) or frame rows (:func:`spread_rows`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import gtsam
import numpy as np

from ..geometry import camera_projection, mirror_projection, project, reflect_points, triangulate
from ..skeletons import Skeleton

__all__ = ["Camera", "Mirror", "View", "Rig", "single_mirror_rig", "view_projections",
           "view_residuals", "view_centres", "triangulate_rig", "parallax_deg", "seen_twice",
           "with_intrinsics", "with_views", "spread_rows"]


@dataclass(frozen=True)
class Camera:
    """A camera with known or estimated intrinsics and a fixed or estimated pose.

    Attributes:
        name: identifier.
        K: ``(3, 3)`` intrinsics (pixels); the initial value when ``estimate_focal``.
        pose: ``(4, 4)`` camera-to-world transform (identity: the camera defines
            the world frame); the initial value when ``estimate_pose``.
        estimate_pose: the pose is a variable of the graph (``False``: held fixed).
        estimate_focal: the focal length is a variable of the graph: square pixels
            (``fx = fy = f``, one unknown), no skew (:mod:`mirrorgraph.graph.reduction`);
            ``K`` must then have ``fx = fy`` and no skew.
        estimate_principal_point: the principal point ``(cx, cy)`` is a variable too
            (only with ``estimate_focal``).
        focal_prior: ``(f0, sigma)`` px: a weak Gaussian prior on an estimated focal
            length (the front ends centre it on the field-of-view guess), which decides
            it where the data do not; ``None``: none.
        principal_point_prior: ``(cx0, cy0, sigma)`` px: the Gaussian prior of an
            estimated principal point (``estimate_principal_point``), each coordinate
            ``sigma`` about ``(cx0, cy0)`` (the front ends: the image centre, with the
            spread of real cameras, :attr:`~.options.FocalOptions.principal_point_rel_sigma`);
            ``None``: about the initial ``K``'s at
            :data:`~.priors.PRINCIPAL_POINT_PRIOR` of the image width.
    """

    name: str
    K: np.ndarray
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))
    estimate_pose: bool = False
    estimate_focal: bool = False
    estimate_principal_point: bool = False
    focal_prior: tuple[float, float] | None = None
    principal_point_prior: tuple[float, float, float] | None = None

    @property
    def intrinsics_dim(self) -> int:
        """Unknowns of the intrinsics in the graph: 0 (held), 1 (``f``) or 3 (``f, cx, cy``)."""
        if not self.estimate_focal:
            return 0
        return 3 if self.estimate_principal_point else 1

    @property
    def gtsam_pose(self) -> gtsam.Pose3:
        """:attr:`pose` as a :class:`gtsam.Pose3`."""
        return gtsam.Pose3(np.asarray(self.pose, dtype=float))


@dataclass(frozen=True)
class Mirror:
    """A planar mirror ``n . X = d`` (world frame) and its initial estimate.

    Attributes:
        name: identifier.
        normal: ``(3,)`` initial unit normal, pointing away from the camera(s).
        distance: initial ``d > 0`` (length unit of the scene).
    """

    name: str
    normal: np.ndarray
    distance: float = 1.0


@dataclass(frozen=True)
class View:
    """One camera looking directly or through one mirror, with its keypoints.

    Attributes:
        name: identifier.
        camera: name of the :class:`Camera`.
        mirror: name of the :class:`Mirror`, or ``None`` for the direct view.
        pixels: ``(T, J, 2)`` observed keypoints (undistorted pixels), indexed by
            the real joint they image (the reflection's labels already flipped).
        mask: ``(T, J)`` bool, observations to use (seen and an inlier).
        weight: ``(J,)`` each joint column's weight in ``(0, 1]``, a factor of the
            reprojection terms' information (pixel sigma ``pixel_sigma / sqrt(weight)``,
            the robust kernel's scale unchanged in pixels); ``None``: 1 throughout.
    """

    name: str
    camera: str
    mirror: str | None
    pixels: np.ndarray
    mask: np.ndarray
    weight: np.ndarray | None = None


@dataclass
class Rig:
    """Cameras, mirrors and views of one recording.

    Attributes:
        cameras: the cameras, by name order of insertion.
        mirrors: the mirrors.
        views: the views (at least two must see a joint for it to be estimated).
        skeleton: keypoint layout of the ``J`` joints.
        frame_ids: ``(T,)`` increasing frame numbers (gaps allowed).
        joints: ``(k,)`` joint indices to estimate.
    """

    cameras: tuple[Camera, ...]
    mirrors: tuple[Mirror, ...]
    views: tuple[View, ...]
    skeleton: Skeleton
    frame_ids: np.ndarray
    joints: np.ndarray

    def camera(self, name: str) -> Camera:
        """The camera called ``name``."""
        for c in self.cameras:
            if c.name == name:
                return c
        raise KeyError(name)

    def camera_index(self, name: str) -> int:
        """Index of the camera called ``name`` in :attr:`cameras`."""
        for i, c in enumerate(self.cameras):
            if c.name == name:
                return i
        raise KeyError(name)

    def mirror_index(self, name: str) -> int:
        """Index of the mirror called ``name`` in :attr:`mirrors`."""
        for i, m in enumerate(self.mirrors):
            if m.name == name:
                return i
        raise KeyError(name)

    @property
    def num_frames(self) -> int:
        """``T``."""
        return int(len(self.frame_ids))

    def subset(self, rows) -> "Rig":
        """The same rig restricted to frame rows ``rows`` (slice, indices or bool mask)."""
        views = tuple(replace(v, pixels=np.asarray(v.pixels)[rows], mask=np.asarray(v.mask)[rows])
                      for v in self.views)
        return replace(self, views=views, frame_ids=np.asarray(self.frame_ids)[rows])

    def observation_count(self) -> np.ndarray:
        """``(T, J)`` int: number of views using each joint (only :attr:`joints` count)."""
        count = np.zeros((self.num_frames, self.skeleton.num_joints), dtype=int)
        for v in self.views:
            count += np.asarray(v.mask, dtype=bool)
        keep = np.zeros(self.skeleton.num_joints, dtype=bool)
        keep[np.asarray(self.joints, dtype=int)] = True
        return count * keep[None, :]


def single_mirror_rig(skeleton: Skeleton, frame_ids: np.ndarray, K: np.ndarray,
                      real: np.ndarray, mirror: np.ndarray, mask: np.ndarray,
                      normal: np.ndarray, distance: float, joints: np.ndarray) -> Rig:
    """MirrorCalib's rig: one camera at the world origin and one mirror.

    Args:
        skeleton: keypoint layout.
        frame_ids: ``(T,)`` frame numbers.
        K: ``(3, 3)`` intrinsics.
        real, mirror: ``(T, J, 2)`` direct and mirror-view pixels (flipped labels).
        mask: ``(T, J)`` pairs to use in both views.
        normal, distance: initial plane ``n . X = d``.
        joints: ``(k,)`` joint indices.
    """
    cam = Camera("camera", np.asarray(K, dtype=float))
    mir = Mirror("mirror", np.asarray(normal, dtype=float), float(distance))
    mask = np.asarray(mask, dtype=bool)
    views = (View("direct", cam.name, None, np.asarray(real, dtype=float), mask),
             View("mirror", cam.name, mir.name, np.asarray(mirror, dtype=float), mask))
    return Rig(cameras=(cam,), mirrors=(mir,), views=views, skeleton=skeleton,
               frame_ids=np.asarray(frame_ids, dtype=np.int64),
               joints=np.asarray(joints, dtype=int))


# --------------------------------------------------------------------------- geometry
def view_projections(rig: Rig, poses: list[np.ndarray] | None = None,
                     planes: list[tuple[np.ndarray, float]] | None = None) -> list[np.ndarray]:
    """``(3, 4)`` world-to-pixel matrix of every view, real or through a mirror
    (:func:`~mirrorgraph.geometry.camera_projection`,
    :func:`~mirrorgraph.geometry.mirror_projection`); default: the rig's poses and planes."""
    out = []
    for v in rig.views:
        ci = rig.camera_index(v.camera)
        K = rig.cameras[ci].K
        pose = rig.cameras[ci].pose if poses is None else poses[ci]
        if v.mirror is None:
            out.append(camera_projection(K, pose))
        else:
            m = rig.mirror_index(v.mirror)
            n, d = ((rig.mirrors[m].normal, rig.mirrors[m].distance) if planes is None
                    else planes[m])
            out.append(mirror_projection(K, pose, n, d))
    return out


def view_residuals(rig: Rig, points: np.ndarray, used: np.ndarray,
                   planes: list[tuple[np.ndarray, float]],
                   poses: list[np.ndarray] | None = None) -> list[np.ndarray]:
    """Reprojection residual norms of every view.

    Args:
        points: ``(T, J, 3)`` world-frame joints; used: ``(T, J)`` bool.
        planes: ``(n, d)`` per mirror.
        poses: ``(4, 4)`` camera-to-world pose per camera (default: the rig's).

    Returns:
        One ``(T, J)`` array per view, pixels, NaN where the view does not use the pair.
    """
    out = []
    for view in rig.views:
        ci = rig.camera_index(view.camera)
        cam = rig.cameras[ci]
        mask = used & np.asarray(view.mask, dtype=bool)
        X = points[mask]
        if view.mirror is not None:
            n, d = planes[rig.mirror_index(view.mirror)]
            X = reflect_points(X, n, d)
        pose = np.asarray(cam.pose if poses is None else poses[ci], dtype=float)
        Xc = (X - pose[:3, 3]) @ pose[:3, :3]
        r = np.full(mask.shape, np.nan)
        r[mask] = np.linalg.norm(project(cam.K, Xc) - np.asarray(view.pixels)[mask], axis=1)
        out.append(r)
    return out


def view_centres(rig: Rig, poses: list[np.ndarray], planes: list[tuple[np.ndarray, float]]
                 ) -> np.ndarray:
    """``(V, 3)`` optical centre of every view: the camera's, or its reflection."""
    out = []
    for v in rig.views:
        c = np.asarray(poses[rig.camera_index(v.camera)], float)[:3, 3]
        if v.mirror is not None:
            n, d = planes[rig.mirror_index(v.mirror)]
            n = np.asarray(n, float)
            c = c - 2.0 * (n @ c - d) * n
        out.append(c)
    return np.array(out)


def triangulate_rig(rig: Rig, masks: list[np.ndarray], poses: list[np.ndarray],
                    planes: list[tuple[np.ndarray, float]]) -> tuple[np.ndarray, np.ndarray]:
    """``(T, J, 3)`` joints (world frame) and ``(T, J)`` mask: every estimated joint seen
    in two of ``masks`` (per view), triangulated with the rig ``poses`` / ``planes``."""
    jmask = np.zeros(rig.skeleton.num_joints, dtype=bool)
    jmask[rig.joints] = True
    return triangulate(view_projections(rig, poses, planes), [v.pixels for v in rig.views],
                       [np.asarray(m, bool) & jmask[None, :] for m in masks])


def parallax_deg(rig: Rig, points: np.ndarray, masks: list[np.ndarray], poses, planes
                 ) -> np.ndarray:
    """``(T, J)`` largest angle between the *lines* of two rays that see a joint, degrees.

    Rays pointing opposite ways (a joint between the camera and the mirror, seen
    from the camera and from its virtual camera behind the mirror) are as
    ill-conditioned as rays pointing the same way: a joint's depth standard
    deviation grows as ``1 / sin(angle)``. 0 where under two views see it.
    """
    C = view_centres(rig, poses, planes)
    X = np.nan_to_num(points)
    dirs = X[None] - C[:, None, None, :]                                   # (V, T, J, 3)
    dirs /= np.maximum(np.linalg.norm(dirs, axis=-1, keepdims=True), 1e-300)
    m = np.stack([np.asarray(k, bool) for k in masks])
    best = np.zeros(points.shape[:2])
    for a in range(len(C)):
        for b in range(a + 1, len(C)):
            cos = np.abs(np.einsum("tjk,tjk->tj", dirs[a], dirs[b]))
            ang = np.degrees(np.arccos(np.clip(cos, 0.0, 1.0)))
            best = np.where(m[a] & m[b], np.maximum(best, ang), best)
    return best


def seen_twice(masks: list[np.ndarray]) -> np.ndarray:
    """``(T, J)`` bool: observed in at least two views."""
    return np.sum([np.asarray(m, bool) for m in masks], axis=0) >= 2


def with_intrinsics(rig: Rig, intrinsics: list[np.ndarray]) -> Rig:
    """``rig`` with every camera's ``K`` replaced (``(3, 3)`` each, rig order)."""
    return replace(rig, cameras=tuple(replace(c, K=np.asarray(K, float))
                                      for c, K in zip(rig.cameras, intrinsics)))


def with_views(rig: Rig, masks: list[np.ndarray], poses=None, planes=None) -> Rig:
    """``rig`` with other view masks (and initial poses / planes)."""
    out = replace(rig, views=tuple(replace(v, mask=m) for v, m in zip(rig.views, masks)))
    if poses is not None:
        out = replace(out, cameras=tuple(replace(c, pose=np.asarray(p, float))
                                         for c, p in zip(out.cameras, poses)))
    if planes is not None:
        out = replace(out, mirrors=tuple(replace(m, normal=np.asarray(n, float),
                                                 distance=float(d))
                                         for m, (n, d) in zip(out.mirrors, planes)))
    return out


def spread_rows(T: int, count: int) -> np.ndarray:
    """``(T,)`` bool: ``count`` frame rows spread evenly over ``T`` (all if ``T <= count``)."""
    mask = np.zeros(T, dtype=bool)
    if count <= 0 or T <= count:
        mask[:] = count > 0 or T == 0
        return mask
    mask[np.unique(np.linspace(0, T - 1, count).round().astype(int))] = True
    return mask
