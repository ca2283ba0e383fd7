"""Two-view initialisation: the relative pose of two cameras, and of a camera and a mirror.

Camera to camera. The same joints seen by two calibrated cameras fix their
essential matrix ``E = [t]x R`` (``x_b^T E x_a = 0`` in normalised
coordinates, ``X_b = R X_a + t``); OpenCV's five-point solver (Nister, "An
efficient solution to the five-point relative pose problem", PAMI 2004) inside
MAGSAC++ (Barath et al., CVPR 2020) estimates it and the cheirality test picks
``(R, t)`` among its four decompositions (Hartley and Zisserman, *Multiple View
Geometry*, 2nd ed., sec. 9.6). A person seen from a few metres covers a small
part of the image, where rotation and translation trade off (the bas-relief
ambiguity): a minimal sample's ``E`` is then degrees off although most joints
fit it, so ``(R, t)`` is refined on all inliers by minimising a robust (Cauchy)
Sampson distance (:func:`refine_relative_pose`). Measured on the synthetic
two-camera rig: plain RANSAC 4-19 deg, MAGSAC++ 0.03-0.09 deg, refined 0.02 deg.
The reflection seen by both cameras adds correspondences of the same kind: the
mirror image is a rigid (reflected) copy of the person.

Camera to mirror. The reflective RANSAC of :func:`mirrorgraph.initial.estimators.estimate_mirror`.

A camera without intrinsics (:func:`focal_from_fundamental`). The fundamental matrix
of two cameras is ``F = K_b^-T E K_a^-1`` whatever their intrinsics, and an essential
matrix has two equal singular values (Hartley and Zisserman, *Multiple View Geometry*,
2nd ed., result 9.17). With square pixels and the principal point at the image centre
the one unknown focal length of ``K_b`` is where ``K_b^T F K_a`` comes closest to that
(Mendonca and Cipolla's criterion, CVPR 1999: the relative gap of the two largest
singular values); with both cameras unknown the two focal lengths together
(Bougnoux's setting, ECCV 1998, unstable where the optical axes meet, as they often
do on a person: the graph then decides, the bones and every other view with it).

Scale. Two views fix the geometry up to scale; the subject fixes it: the joints
triangulated with a unit baseline (or ``d = 1``) give the subject's height in
that unit from the median bone lengths and Winter's segment proportions
(:func:`mirrorgraph.graph.bones.body_height_from_points`), so one edge's
length is ``H / h``. With every edge scaled by the same subject the chain of
edges is consistent.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from ..errors import DegenerateGeometryError
from .estimators import estimate_mirror
from ..geometry import camera_projection, sampson_distances, skew, triangulate, triangulate_mirror
from ..graph.bones import body_height_from_points
from ..graph.rig import Rig
from ..skeletons import Skeleton

__all__ = ["RelativePose", "MirrorSighting", "relative_pose", "refine_relative_pose",
           "sampson_px", "mirror_sighting", "focal_from_fundamental", "essential_defect",
           "MIN_CORRESPONDENCES"]

#: Fewest joint correspondences for a camera-to-camera edge.
MIN_CORRESPONDENCES = 30


@dataclass
class RelativePose:
    """Camera ``b`` relative to camera ``a``: ``X_b = R X_a + t``.

    Attributes:
        R: ``(3, 3)`` rotation.
        t: ``(3,)`` translation, length = the baseline in the subject's scale
            (:func:`relative_pose`'s ``height``).
        inliers: number of inlier correspondences (the edge's weight).
        correspondences: number of correspondences tried.
        residual_px: median Sampson distance of the inliers, pixels.
    """

    R: np.ndarray
    t: np.ndarray
    inliers: int
    correspondences: int
    residual_px: float

    @property
    def pose_b_in_a(self) -> np.ndarray:
        """``(4, 4)`` camera-to-world pose of ``b`` when ``a`` is the world frame."""
        T = np.eye(4)
        T[:3, :3] = self.R.T
        T[:3, 3] = -self.R.T @ self.t
        return T


@dataclass
class MirrorSighting:
    """A mirror seen by one camera: the plane in that camera's frame.

    Attributes:
        normal: ``(3,)`` unit normal, away from the camera.
        distance: ``d`` in the subject's scale.
        inliers: number of inlier pairs.
    """

    normal: np.ndarray
    distance: float
    inliers: int


def _skeleton_rig(skeleton: Skeleton, T: int, joints: np.ndarray) -> Rig:
    return Rig(cameras=(), mirrors=(), views=(), skeleton=skeleton,
               frame_ids=np.arange(T), joints=np.asarray(joints, dtype=int))


def normalised_coordinates(K: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Normalised image coordinates ``(..., 2)`` ``pi(K^-1 [u; 1])`` of pixels ``(..., 2)``."""
    uh = np.concatenate([u, np.ones(u.shape[:-1] + (1,))], axis=-1)
    x = uh @ np.linalg.inv(K).T
    return x[..., :2] / x[..., 2:3]


def sampson_px(E: np.ndarray, xa: np.ndarray, xb: np.ndarray, f: float) -> np.ndarray:
    """``(N,)`` signed Sampson distances in pixels (``f`` times the normalised one,
    :func:`mirrorgraph.geometry.sampson_distances`) of correspondences ``xa``, ``xb``
    ``(N, 2)`` (normalised coordinates) under the essential matrix ``E``."""
    return f * sampson_distances(E, xa, xb)


def refine_relative_pose(xa: np.ndarray, xb: np.ndarray, R: np.ndarray, t: np.ndarray,
                         f: float, scale_px: float) -> tuple[np.ndarray, np.ndarray]:
    """Refine ``(R, t)`` (``|t| = 1``) on correspondences by a robust Sampson distance.

    Parametrisation: ``R <- R Exp(w)``, ``t <- normalise(t + B v)`` with ``B`` a
    ``(3, 2)`` basis orthogonal to ``t`` (5 unknowns). Cauchy loss of scale
    ``scale_px`` (scipy's ``least_squares``, trust-region reflective).

    Args:
        xa, xb: ``(N, 2)`` normalised coordinates; f: focal length (px) for the units.
    """
    R0, t0 = np.asarray(R, float), np.asarray(t, float).ravel() / np.linalg.norm(t)
    B = np.linalg.svd(t0[None, :])[2][1:].T                          # (3, 2)

    def unpack(p):
        Rm = R0 @ Rotation.from_rotvec(p[:3]).as_matrix()
        tv = t0 + B @ p[3:]
        return Rm, tv / np.linalg.norm(tv)

    def residual(p):
        Rm, tv = unpack(p)
        return sampson_px(skew(tv) @ Rm, xa, xb, f)

    sol = least_squares(residual, np.zeros(5), loss="cauchy", f_scale=float(scale_px),
                        x_scale="jac", max_nfev=200)
    return unpack(sol.x)


def relative_pose(K_a: np.ndarray, K_b: np.ndarray, u_a: np.ndarray, u_b: np.ndarray,
                  mask: np.ndarray, skeleton: Skeleton, joints: np.ndarray, height: float,
                  *, threshold_px: float = 8.0, seed: int = 0) -> RelativePose | None:
    """Relative pose of two cameras from joints both see, scaled by the subject.

    Args:
        K_a, K_b: ``(3, 3)`` intrinsics.
        u_a, u_b: ``(S, T, J, 2)`` undistorted pixels of the same 3D points in
            ``a`` and ``b`` (``S`` sets: the person, and each reflection both see).
        mask: ``(S, T, J)`` bool, both cameras observe the point.
        skeleton, joints: layout and the joints used (for the scale).
        height: the subject's height in the output unit.
        threshold_px: RANSAC inlier threshold (Sampson distance), pixels.
        seed: seed of OpenCV's RANSAC sampling.

    Returns:
        The pose, or ``None`` with fewer than :data:`MIN_CORRESPONDENCES`
        correspondences or when the geometry is degenerate.
    """
    mask = np.asarray(mask, dtype=bool)
    n = int(np.count_nonzero(mask))
    if n < MIN_CORRESPONDENCES:
        return None
    xa = normalised_coordinates(np.asarray(K_a, float), np.asarray(u_a, float)[mask])
    xb = normalised_coordinates(np.asarray(K_b, float), np.asarray(u_b, float)[mask])
    f = 0.5 * (np.mean(np.diag(K_a)[:2]) + np.mean(np.diag(K_b)[:2]))
    cv2.setRNGSeed(int(seed))
    E, inl = cv2.findEssentialMat(xa, xb, np.eye(3), method=cv2.USAC_MAGSAC, prob=0.9999,
                                  threshold=threshold_px / f, maxIters=5000)
    if E is None or E.shape[1:] != (3,) or E.shape[0] < 3 or inl is None:
        return None
    E = E[:3]
    count, R, t, _ = cv2.recoverPose(E, xa, xb, np.eye(3), mask=inl.copy())
    if count < MIN_CORRESPONDENCES // 2:
        return None
    R, t = refine_relative_pose(xa, xb, R, np.asarray(t, float).ravel(), f, 0.5 * threshold_px)
    E = skew(t) @ R
    sampson = np.abs(sampson_px(E, xa, xb, f))
    inliers = sampson < threshold_px
    # cheirality of the refined pose: most inliers in front of both cameras
    Pa0 = np.hstack([np.eye(3), np.zeros((3, 1))])
    Pb0 = np.hstack([R, t[:, None]])
    X, ok = triangulate([Pa0, Pb0], [xa, xb], [inliers, inliers])
    front = ok & (X[:, 2] > 0) & ((X @ R.T + t)[:, 2] > 0)
    if np.count_nonzero(front) < 0.5 * np.count_nonzero(inliers):
        return None
    # scale: triangulate the inliers with a unit baseline, measure the subject
    full = np.zeros(mask.shape, dtype=bool)
    full[mask] = inliers
    Pa = camera_projection(K_a, np.eye(4))
    Pb = np.asarray(K_b, float) @ np.hstack([R, t[:, None]])
    h = np.nan
    for s in range(mask.shape[0]):
        X, ok = triangulate([Pa, Pb], [u_a[s], u_b[s]], [full[s], full[s]])
        hs = body_height_from_points(_skeleton_rig(skeleton, X.shape[0], joints), X, ok)
        if np.isfinite(hs) and hs > 0:
            h = hs
            break
    if not np.isfinite(h) or h <= 0:
        return None
    return RelativePose(R=np.asarray(R, float), t=t * (float(height) / h),
                        inliers=int(np.count_nonzero(inliers)), correspondences=n,
                        residual_px=float(np.median(sampson[inliers])) if inliers.any()
                        else float("nan"))


def essential_defect(F: np.ndarray, K_a: np.ndarray, K_b: np.ndarray) -> float:
    """``(s1 - s2) / (s1 + s2)`` of the two largest singular values of ``K_b^T F K_a``: 0 for
    an essential matrix (Mendonca and Cipolla's criterion)."""
    s = np.linalg.svd(np.asarray(K_b, float).T @ np.asarray(F, float) @ np.asarray(K_a, float),
                      compute_uv=False)
    return float((s[0] - s[1]) / max(s[0] + s[1], 1e-300))


def _with_focal(K: np.ndarray, f: float) -> np.ndarray:
    K = np.array(K, dtype=float, copy=True)
    K[0, 0] = K[1, 1] = float(f)
    return K


def focal_from_fundamental(K_a: np.ndarray, K_b: np.ndarray, u_a: np.ndarray,
                           u_b: np.ndarray, *, unknown: str = "b",
                           fov_deg: tuple[float, float] = (20.0, 120.0),
                           threshold_px: float = 4.0, seed: int = 0
                           ) -> tuple[float, float] | None:
    """The focal length(s) of cameras without intrinsics from their fundamental matrix.

    Args:
        K_a, K_b: ``(3, 3)`` intrinsics: the known camera's, and the unknown's guess
            (its principal point is kept; square pixels, no skew).
        u_a, u_b: ``(N, 2)`` corresponding pixels (undistorted).
        unknown: ``"b"`` (``K_a`` known) or ``"both"`` (one focal length each).
        fov_deg: the horizontal fields of view searched, degrees (of an image ``2 cx``
            wide).
        threshold_px: RANSAC threshold of the fundamental matrix (Sampson), pixels.
        seed: seed of OpenCV's sampling.

    Returns:
        ``(f_a, f_b)`` px (``f_a`` the given one when ``unknown="b"``), or ``None`` with
        under :data:`MIN_CORRESPONDENCES` correspondences or no fundamental matrix.
    """
    u_a, u_b = np.asarray(u_a, float), np.asarray(u_b, float)
    if len(u_a) < MIN_CORRESPONDENCES:
        return None
    cv2.setRNGSeed(int(seed))
    F, inl = cv2.findFundamentalMat(u_a, u_b, cv2.USAC_MAGSAC, threshold_px, 0.9999, 10000)
    if F is None or F.shape != (3, 3) or inl is None or int(inl.sum()) < MIN_CORRESPONDENCES:
        return None

    def grid(K: np.ndarray, n: int) -> np.ndarray:
        fov = np.radians(np.geomspace(fov_deg[1], fov_deg[0], n))
        return float(K[0, 2]) / np.tan(0.5 * fov)

    K_a, K_b = np.asarray(K_a, float), np.asarray(K_b, float)
    if unknown == "b":
        fs = grid(K_b, 61)
        cost = [essential_defect(F, K_a, _with_focal(K_b, f)) for f in fs]
        i = int(np.argmin(cost))
        lo, hi = fs[max(i - 1, 0)], fs[min(i + 1, len(fs) - 1)]
        fb = golden_section_min(lambda f: essential_defect(F, K_a, _with_focal(K_b, f)), lo, hi)
        return float(K_a[0, 0]), fb
    fa_grid, fb_grid = grid(K_a, 31), grid(K_b, 31)
    cost = np.array([[essential_defect(F, _with_focal(K_a, fa), _with_focal(K_b, fb))
                      for fb in fb_grid] for fa in fa_grid])
    i, j = np.unravel_index(int(np.argmin(cost)), cost.shape)
    return float(fa_grid[i]), float(fb_grid[j])


def golden_section_min(fn, lo: float, hi: float, iterations: int = 40) -> float:
    """Minimum of a unimodal ``fn`` on ``[lo, hi]`` (golden-section search)."""
    g = 0.5 * (np.sqrt(5.0) - 1.0)
    a, b = float(min(lo, hi)), float(max(lo, hi))
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = fn(c), fn(d)
    for _ in range(iterations):
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = fn(c)
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = fn(d)
    return 0.5 * (a + b)


def mirror_sighting(K: np.ndarray, real: np.ndarray, reflection: np.ndarray, mask: np.ndarray,
                    skeleton: Skeleton, joints: np.ndarray, height: float, *,
                    seed: int = 0, name: str = "") -> MirrorSighting:
    """The mirror plane in one camera's frame, scaled by the subject.

    Args:
        K: ``(3, 3)`` intrinsics.
        real, reflection: ``(T, J, 2)`` undistorted pixels (reflection labels flipped).
        mask: ``(T, J)`` bool, both observed (calibration joints).
        skeleton, joints: layout and joints (for the scale).
        height: the subject's height in the output unit.
        name: ``"camera/mirror"`` for messages.

    Raises:
        DegenerateGeometryError: the pairs do not determine the mirror.
    """
    mask = np.asarray(mask, dtype=bool)
    try:
        est = estimate_mirror(real[mask], reflection[mask], K, seed=seed)
    except DegenerateGeometryError as exc:
        raise DegenerateGeometryError(f"mirror {name}: {exc}") from None
    inl = np.zeros(mask.shape, dtype=bool)
    inl[mask] = est.inliers
    X = np.full(mask.shape + (3,), np.nan)
    X[inl] = triangulate_mirror(K, est.normal, 1.0, real[inl], reflection[inl])
    h = body_height_from_points(_skeleton_rig(skeleton, mask.shape[0], joints), X, inl)
    if not np.isfinite(h) or h <= 0:
        raise DegenerateGeometryError(f"mirror {name}: cannot measure the subject through "
                                      "the mirror (no bone seen in both views)")
    return MirrorSighting(normal=np.asarray(est.normal, float), distance=float(height) / h,
                          inliers=int(np.count_nonzero(inl)))
