"""The geometry of one camera and one planar mirror.

Frames and units
----------------
Everything is expressed in the *real camera frame*: origin at the optical
centre, x right, y down, z forward (OpenCV convention). Lengths are in the unit
of the mirror distance ``d`` (metres once a metric prior fixed the scale).
Pixels have their origin at the top-left corner of the image.

The mirror is the plane ``n . X = d`` with ``n`` a unit vector pointing *away
from the camera* and ``d > 0`` the camera-to-plane distance. The reflection
across it is the affine map

    S(X) = H X + 2 d n,    H = I - 2 n n^T   (Householder matrix, det H = -1).

A point X is seen directly at ``pi(K X)`` and in the mirror at
``pi(K S(X))``: the mirror view is a *virtual camera*, the reflection of the
real one, whose frame is left-handed. Following MirrorCalib (Liao, Zheng and
Mitchell, eq. 7) we write its extrinsics as a proper rotation, a translation and
the handedness flip ``D = diag(-1, 1, 1)``:

    X_virtual = D (R X + t) = S(X),   R = D H,   t = 2 d D n.

The reflective essential matrix is ``E = 2 d [n]_x`` and the reflective
fundamental matrix ``F ~ K^-T [n]_x K^-1 = [K n]_x / det K`` is skew-symmetric:
``u'^T F u = 0`` says that the image ``u`` of a joint, the image ``u'`` of its
reflection and the epipole ``e ~ K n`` are collinear (Hartley and Zisserman,
*Multiple View Geometry*, 2nd ed., sec. 9.2 and exercise on planar motion;
Gluckman and Nayar, "Catadioptric stereo using planar mirrors", IJCV 2001).
The epipole is the vanishing point of the mirror normal.
"""

from __future__ import annotations

import numpy as np

from .errors import DegenerateGeometryError

#: The handedness flip between the real and the virtual camera frame.
D_FLIP = np.diag([-1.0, 1.0, 1.0])


# --------------------------------------------------------------------------- basics
def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix ``[v]_x`` of a ``(3,)`` vector, so ``[v]_x w = v x w``."""
    x, y, z = np.asarray(v, dtype=float)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def unskew(M: np.ndarray) -> np.ndarray:
    """The ``(3,)`` vector ``v`` of the skew-symmetric part of ``M``: ``M ~ [v]_x``."""
    A = 0.5 * (np.asarray(M, dtype=float) - np.asarray(M, dtype=float).T)
    return np.array([A[2, 1], A[0, 2], A[1, 0]])


def tangent_basis(v: np.ndarray) -> np.ndarray:
    """``(3, 2)`` orthonormal basis of the plane orthogonal to the unit vector ``v`` ``(3,)``
    (the tangent space of the sphere at ``v``: a normal's or an epipole's two degrees of
    freedom)."""
    v = np.asarray(v, dtype=float).reshape(3)
    a = np.eye(3)[np.argmin(np.abs(v))]
    b1 = np.cross(v, a)
    b1 /= np.linalg.norm(b1)
    return np.stack([b1, np.cross(v, b1)], axis=1)


def to_homogeneous(u: np.ndarray) -> np.ndarray:
    """Append a 1: ``(..., 2)`` pixels -> ``(..., 3)`` homogeneous pixels."""
    u = np.asarray(u, dtype=float)
    return np.concatenate([u, np.ones(u.shape[:-1] + (1,))], axis=-1)


def project(K: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Pinhole projection ``pi(K X)``.

    Args:
        K: ``(3, 3)`` intrinsics.
        X: ``(..., 3)`` points in the camera frame.

    Returns:
        ``(..., 2)`` pixels.
    """
    x = np.asarray(X, dtype=float) @ np.asarray(K, dtype=float).T
    return x[..., :2] / x[..., 2:3]


def project_with_jacobian(P: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pinhole projection ``pi(P [X; 1])`` and its Jacobian in ``X``.

    ``d pi / d X = (1 / z) [P_1 - u P_3; P_2 - v P_3]`` over the first three columns,
    ``z`` the point's third homogeneous coordinate (Hartley and Zisserman, *Multiple View
    Geometry*, 2nd ed., sec. 5.2.1): the ``2 x 3`` block of a reprojection error's
    linearisation, of a triangulated point's information ``J^T J / sigma^2``.

    Args:
        P: ``(3, 4)`` world-to-pixel matrix, or ``(3, 3)`` (no translation: ``K`` for
            camera-frame points, ``K H`` for a reflection through a plane at the origin).
        X: ``(N, 3)`` points in ``P``'s world frame.

    Returns:
        ``(u, J)``: ``(N, 2)`` pixels and ``(N, 2, 3)`` Jacobians, px per unit of ``X``;
        NaN or inf where ``z`` is 0.
    """
    P = np.asarray(P, dtype=float)
    y = np.asarray(X, dtype=float) @ P[:, :3].T
    if P.shape[1] == 4:
        y = y + P[:, 3]
    z = y[:, 2:3]
    u = y[:, :2] / z
    J = (P[None, :2, :3] - u[:, :, None] * P[None, 2:3, :3]) / z[:, :, None]
    return u, J


# --------------------------------------------------------------------------- mirror
def normalize_plane(normal: np.ndarray, distance: float) -> tuple[np.ndarray, float]:
    """Scale ``n . X = d`` to a unit normal and orient it so that ``d > 0``.

    Raises:
        DegenerateGeometryError: zero normal, or a plane through the camera centre.
    """
    n = np.asarray(normal, dtype=float).reshape(3)
    norm = np.linalg.norm(n)
    if not np.isfinite(norm) or norm < 1e-12:
        raise DegenerateGeometryError("mirror normal is zero or not finite")
    n, d = n / norm, float(distance) / norm
    if abs(d) < 1e-12:
        raise DegenerateGeometryError("mirror plane passes through the camera centre")
    return (n, d) if d > 0 else (-n, -d)


def householder(normal: np.ndarray) -> np.ndarray:
    """``(3, 3)`` reflection ``H = I - 2 n n^T`` about the plane through 0 with unit normal."""
    n = np.asarray(normal, dtype=float).reshape(3)
    return np.eye(3) - 2.0 * np.outer(n, n)


def reflect_points(X: np.ndarray, normal: np.ndarray, distance: float) -> np.ndarray:
    """Mirror image ``S(X) = X - 2 (n . X - d) n`` of ``(..., 3)`` points."""
    X = np.asarray(X, dtype=float)
    n = np.asarray(normal, dtype=float).reshape(3)
    return X - 2.0 * ((X @ n) - distance)[..., None] * n


def mirror_ray_angles_deg(X: np.ndarray, normal: np.ndarray, distance: float) -> np.ndarray:
    """``(...)`` angle between the *lines* of a point's two rays, degrees in ``[0, 90]``.

    The rays from the camera centre (origin) and from the virtual camera's centre
    ``2 d n`` to ``(..., 3)`` points ``X`` (camera frame, the unit of ``distance``).
    Rays pointing opposite ways (a point between the camera and the mirror) are as
    ill-conditioned as rays pointing the same way: a point's depth std grows as ``1 /
    sin`` of this angle (Hartley and Zisserman, *Multiple View Geometry*, 2nd ed., 12.6).
    """
    X = np.asarray(X, dtype=float)
    v = X - 2.0 * float(distance) * np.asarray(normal, dtype=float).reshape(3)
    c = np.abs(np.sum(X * v, axis=-1)) / (np.linalg.norm(X, axis=-1) * np.linalg.norm(v, axis=-1))
    return np.degrees(np.arccos(np.clip(c, 0.0, 1.0)))


def virtual_camera_from_mirror(normal: np.ndarray, distance: float
                               ) -> tuple[np.ndarray, np.ndarray]:
    """Extrinsics of the virtual camera, ``X_virtual = D (R X + t)``.

    Args:
        normal: ``(3,)`` unit mirror normal, real camera frame, away from the camera.
        distance: ``d > 0``, camera-to-mirror distance.

    Returns:
        ``R`` ``(3, 3)`` proper rotation ``D (I - 2 n n^T)`` and ``t`` ``(3,)``
        ``2 d D n`` (same unit as ``d``).
    """
    n, d = normalize_plane(normal, distance)
    return D_FLIP @ householder(n), 2.0 * d * (D_FLIP @ n)


def mirror_from_virtual_camera(R: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, float]:
    """Inverse of :func:`virtual_camera_from_mirror`: ``(n, d)`` from ``(R, t)``.

    The normal is read from ``t`` (``D t = 2 d n``); ``R`` is used only to check
    consistency. With a unit-length ``t`` (unknown scale) ``d = 1/2``.
    """
    Dt = D_FLIP @ np.asarray(t, dtype=float).reshape(3)      # = 2 d n
    norm = float(np.linalg.norm(Dt))
    if norm < 1e-12:
        raise DegenerateGeometryError("virtual camera translation is zero")
    return Dt / norm, 0.5 * norm


def essential_from_mirror(normal: np.ndarray, distance: float) -> np.ndarray:
    """Reflective essential matrix ``E = 2 d [n]_x`` (3, 3), skew-symmetric."""
    n, d = normalize_plane(normal, distance)
    return 2.0 * d * skew(n)


def epipole_from_normal(K: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Homogeneous epipole ``e = K n`` (3,), scaled to unit norm, sign of ``K n`` kept."""
    e = np.asarray(K, dtype=float) @ np.asarray(normal, dtype=float).reshape(3)
    return e / np.linalg.norm(e)


def fundamental_from_epipole(e: np.ndarray) -> np.ndarray:
    """Reflective fundamental matrix ``F = [e]_x`` (3, 3), unit Frobenius norm.

    ``u'^T F u = 0`` for a joint ``u`` and its reflection ``u'`` (homogeneous pixels).
    """
    F = skew(np.asarray(e, dtype=float).reshape(3))
    return F / np.linalg.norm(F)


def fundamental_from_mirror(K: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """``F ~ K^-T [n]_x K^-1 = [K n]_x / det K``, unit Frobenius norm (3, 3)."""
    return fundamental_from_epipole(epipole_from_normal(K, normal))


def epipole_from_fundamental(F: np.ndarray) -> np.ndarray:
    """Homogeneous epipole (3,) of a reflective (skew-symmetric) ``F = [e]_x``."""
    e = unskew(F)
    return e / np.linalg.norm(e)


def epipole_pixels(e: np.ndarray) -> np.ndarray | None:
    """Epipole in pixels ``(2,)``, or ``None`` when it lies at infinity."""
    e = np.asarray(e, dtype=float).reshape(3)
    if abs(e[2]) < 1e-12 * np.linalg.norm(e):
        return None
    return e[:2] / e[2]


def normal_from_epipole(K: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Unit mirror normal ``n ~ K^-1 e`` (3,), oriented away from the camera (``n_z >= 0``).

    The sign of ``n`` is not observable from ``e`` alone; a mirror that the
    camera faces has ``n_z > 0``. :func:`orient_normal` settles it from data.
    """
    n = np.linalg.solve(np.asarray(K, dtype=float), np.asarray(e, dtype=float).reshape(3))
    n /= np.linalg.norm(n)
    return n if n[2] >= 0 else -n


# --------------------------------------------------------------------------- residuals
def epipolar_distances(e: np.ndarray, u: np.ndarray, u_mirror: np.ndarray) -> np.ndarray:
    """Reflective epipolar distance in pixels (Sampson distance of collinearity).

    A pair is consistent with the epipole when ``u``, ``u'`` and ``e`` are
    collinear: ``c = det[e, u, u'] = 0``. The Sampson distance
    ``|c| / |grad_{u,u'} c|`` is the smallest total displacement of the two
    points (to first order) that makes them collinear with ``e`` (Hartley and
    Zisserman sec. 4.2.6). Unlike the point-to-epipolar-line distances it is
    symmetric in ``u`` and ``u'``, stays well behaved when one point is close to
    the epipole, and works for an epipole at infinity. With independent
    Gaussian noise of standard deviation sigma per coordinate and per view it
    is distributed as ``|N(0, sigma^2)|`` (to first order).

    Args:
        e: ``(3,)`` homogeneous epipole in pixels.
        u: ``(..., 2)`` direct-view pixels.
        u_mirror: ``(..., 2)`` mirror-view pixels of the same joints.

    Returns:
        ``(...)`` distances in pixels (``inf`` where undefined).
    """
    return np.abs(signed_epipolar_distances(e, u, u_mirror))


def signed_epipolar_distances(e: np.ndarray, u: np.ndarray, u_mirror: np.ndarray
                              ) -> np.ndarray:
    """Signed version of :func:`epipolar_distances` (``(...)`` pixels): the Sampson
    distance of :func:`sampson_distances` with ``F = [e]_x`` (``u'^T [e]_x u = det(u', e, u)``),
    written out (``F u = e x u``, ``F^T u' = u' x e``): RANSAC scores every pair with it."""
    e0, e1, e2 = (float(v) for v in np.asarray(e, dtype=float).reshape(3))
    u = np.asarray(u, dtype=float)
    v = np.asarray(u_mirror, dtype=float)
    x, y, xm, ym = u[..., 0], u[..., 1], v[..., 0], v[..., 1]
    l0, l1, l2 = e1 - e2 * y, e2 * x - e0, e0 * y - e1 * x      # e x (x, y, 1)
    m0, m1 = ym * e2 - e1, e0 - xm * e2                         # (xm, ym, 1) x e
    c = xm * l0 + ym * l1 + l2
    with np.errstate(divide="ignore", invalid="ignore"):
        out = c / np.sqrt(l0 * l0 + l1 * l1 + m0 * m0 + m1 * m1)
    return np.where(np.isfinite(out), out, np.inf)


def sampson_distances(F: np.ndarray, u: np.ndarray, u_other: np.ndarray) -> np.ndarray:
    """Signed Sampson distance of correspondences under an epipolar matrix, ``(...)``.

    ``c = u'^T F u`` over the norm of its gradient in the four image coordinates,
    ``sqrt((F u)_1^2 + (F u)_2^2 + (F^T u')_1^2 + (F^T u')_2^2)``: the first-order
    smallest displacement of the two points onto the epipolar constraint (Hartley and
    Zisserman, *Multiple View Geometry*, 2nd ed., sec. 11.4.3). With ``F`` in pixels
    the distance is in pixels; with an essential matrix on normalised coordinates,
    in those (times the focal length for pixels).

    Args:
        F: ``(3, 3)`` fundamental (or essential) matrix, ``u'^T F u = 0``.
        u, u_other: ``(..., 2)`` points of the first and the second view.

    Returns:
        ``(...)`` signed distances (``inf`` where undefined).
    """
    F = np.asarray(F, dtype=float)
    x1 = to_homogeneous(np.asarray(u, dtype=float))
    x2 = to_homogeneous(np.asarray(u_other, dtype=float))
    Fx1 = x1 @ F.T                          # F u: line in the second view
    Ftx2 = x2 @ F                           # F^T u': line in the first view
    c = np.einsum("...i,...i->...", x2, Fx1)
    g = np.sqrt(Fx1[..., 0] ** 2 + Fx1[..., 1] ** 2 + Ftx2[..., 0] ** 2 + Ftx2[..., 1] ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = c / g
    return np.where(np.isfinite(out), out, np.inf)


def epipolar_distances_fundamental(F: np.ndarray, u: np.ndarray, u_mirror: np.ndarray
                                   ) -> np.ndarray:
    """Symmetric epipolar distance in pixels for a general ``F`` (``u'^T F u = 0``).

    Mean of the distance of ``u'`` to the line ``F u`` and of ``u`` to the line
    ``F^T u'``; equal to :func:`epipolar_distances` when ``F = [e]_x``.

    Args:
        F: ``(3, 3)`` fundamental matrix in pixels.
        u, u_mirror: ``(..., 2)`` pixel pairs.

    Returns:
        ``(...)`` distances in pixels.
    """
    x1 = to_homogeneous(u)
    x2 = to_homogeneous(u_mirror)
    l2 = x1 @ np.asarray(F, dtype=float).T          # F u: line in the mirror view
    l1 = x2 @ np.asarray(F, dtype=float)            # F^T u': line in the direct view
    alg = np.abs(np.einsum("...i,...i->...", l2, x2))
    with np.errstate(divide="ignore", invalid="ignore"):
        out = 0.5 * (alg / np.hypot(l2[..., 0], l2[..., 1]) + alg / np.hypot(l1[..., 0], l1[..., 1]))
    return np.where(np.isfinite(out), out, np.inf)


# --------------------------------------------------------------------------- triangulation
def camera_projection(K: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """``(3, 4)`` world-to-pixel matrix ``K [R^T | -R^T c]`` of a camera with ``(4, 4)``
    camera-to-world ``pose`` (rotation ``R``, centre ``c``)."""
    pose = np.asarray(pose, dtype=float)
    R, c = pose[:3, :3], pose[:3, 3]
    return np.asarray(K, dtype=float) @ np.hstack([R.T, (-R.T @ c)[:, None]])


def mirror_projection(K: np.ndarray, pose: np.ndarray, normal: np.ndarray, distance: float
                      ) -> np.ndarray:
    """``(3, 4)``: the camera of ``pose`` looking through the mirror ``n . X = d`` (world
    frame): it sees ``X`` where it would see ``S(X)``, so the matrix is the camera's
    times ``S = [[H, 2 d n], [0, 1]]``, ``H = I - 2 n n^T``."""
    n = np.asarray(normal, dtype=float).reshape(3)
    S = np.eye(4)
    S[:3, :3] = householder(n)
    S[:3, 3] = 2.0 * float(distance) * n
    return camera_projection(K, pose) @ S


def triangulate(projections: np.ndarray | list[np.ndarray], pixels: np.ndarray | list,
                masks: np.ndarray | list | None = None, *, iterations: int = 3,
                min_views: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Triangulate points seen by any number of real and virtual cameras.

    Linear triangulation (DLT, Hartley and Zisserman, *Multiple View Geometry*, 2nd
    ed., sec. 12.2: two rows a view, ``u P_3 - P_1`` and ``v P_3 - P_2``, each scaled
    to unit norm, solved in least squares for a finite point ``(X, 1)``), then
    ``iterations`` Gauss-Newton steps on the reprojection error of the views that
    see the point (the maximum-likelihood point under iid pixel noise, sec. 12.3).
    Batched over points: one ``3 x 3`` solve per point per step.

    Args:
        projections: ``V`` world-to-pixel matrices ``(3, 4)``
            (:func:`camera_projection`, :func:`mirror_projection`).
        pixels: ``V`` arrays ``(..., 2)`` of one leading shape ``S``, undistorted pixels.
        masks: ``V`` bool arrays of shape ``S``: the view observes the point
            (default: wherever its pixels are finite).
        iterations: Gauss-Newton steps after the linear solution.
        min_views: fewest views a point needs.

    Returns:
        ``(S + (3,))`` world points (NaN where not triangulated) and the ``S`` bool
        mask of the triangulated ones.
    """
    P = np.stack([np.asarray(p, dtype=float) for p in projections])                 # (V, 3, 4)
    shape = np.asarray(pixels[0]).shape[:-1]
    uv = np.stack([np.asarray(p, dtype=float).reshape(-1, 2) for p in pixels])      # (V, N, 2)
    m = np.isfinite(uv).all(-1)
    if masks is not None:
        m &= np.stack([np.asarray(k, dtype=bool).reshape(-1) for k in masks])
    ok = m.sum(0) >= min_views
    out = np.full((uv.shape[1], 3), np.nan)
    if ok.any():
        u = np.nan_to_num(uv[:, ok])                                                  # (V, M, 2)
        w = m[:, ok]
        # two rows a view, (2V, 4, M), each scaled to unit norm, zero where not seen
        A = np.concatenate([u[..., 0][:, None, :] * P[:, 2, :, None] - P[:, 0, :, None],
                            u[..., 1][:, None, :] * P[:, 2, :, None] - P[:, 1, :, None]])
        A *= np.concatenate([w, w])[:, None, :] / np.maximum(np.sqrt(np.einsum(
            "rim,rim->rm", A, A)), 1e-300)[:, None, :]
        # the rows' least squares with X_h = (X, 1): the normal equations of the
        # inhomogeneous system (a finite point is the case here; six times faster than
        # the homogeneous SVD, and the Gauss-Newton steps below refine it anyway)
        M = np.stack([np.einsum("rm,rm->m", A[:, a], A[:, b]) for a, b in SYM3])   # (6, M)
        b = -np.einsum("rim,rm->im", A[:, :3], A[:, 3])                               # (3, M)
        adj, det = sym3_adjugate(M)
        solvable = np.abs(det) > 1e-12 * (M[0] + M[1] + M[2]) ** 3
        with np.errstate(divide="ignore", invalid="ignore"):
            X = np.where(solvable, sym3_product(adj, b) / det, np.nan).T
        for _ in range(iterations):
            X = _gauss_newton_views(P, u, w, X)
        good = np.isfinite(X).all(1) & solvable
        idx = np.flatnonzero(ok)
        out[idx[good]] = X[good]
        ok[idx[~good]] = False
    return out.reshape(shape + (3,)), ok.reshape(shape)


def _gauss_newton_views(P: np.ndarray, u: np.ndarray, w: np.ndarray, X: np.ndarray
                        ) -> np.ndarray:
    """One batched Gauss-Newton step of the reprojection error over the views ``w``.

    The normal equations' six distinct entries and the gradient are summed as ``(M,)``
    columns and solved in closed form (:func:`solve_sym3`): no ``(M, 3, 3)`` temporaries.

    Args:
        P: ``(V, 3, 4)``; u: ``(V, M, 2)`` pixels; w: ``(V, M)`` bool; X: ``(M, 3)``.
    """
    H = np.zeros((6, len(X)))                   # xx, yy, zz, xy, xz, yz
    g = np.zeros((3, len(X)))
    Xt = X.T
    with np.errstate(divide="ignore", invalid="ignore"):
        for Pv, uv, wv in zip(P, u, w):
            y = Pv[:, :3] @ Xt + Pv[:, 3:4]                                     # (3, M)
            inv = np.where(wv, 1.0 / y[2], 0.0)
            px, py = y[0] * inv, y[1] * inv
            # d pi / dX = (1 / z) [P_1 - u P_3 ; P_2 - v P_3] (first three columns)
            jx = (Pv[0, :3, None] - Pv[2, :3, None] * px) * inv                 # (3, M)
            jy = (Pv[1, :3, None] - Pv[2, :3, None] * py) * inv
            rx, ry = px - uv[:, 0], py - uv[:, 1]
            for k, (a, b) in enumerate(SYM3):
                H[k] += jx[a] * jx[b] + jy[a] * jy[b]
            g += jx * rx + jy * ry
        H[:3] += 1e-9
        step = solve_sym3(H, g).T
    step[~np.isfinite(step).all(1)] = 0.0
    return X - step


def similarity_align(src: np.ndarray, dst: np.ndarray, weights: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The similarity ``dst ~ s R src + t`` of least weighted squares, batched
    (Umeyama, "Least-squares estimation of transformation parameters between two point
    patterns", PAMI 1991; SciPy's :meth:`~scipy.spatial.transform.Rotation.align_vectors`
    does one set at a time and no scale).

    Args:
        src, dst: ``(..., N, 3)`` corresponding points (broadcast against each other).
        weights: ``(..., N)`` non-negative weights (default 1); a point of weight 0 takes
            no part (its coordinates may be NaN).

    Returns:
        ``R`` ``(..., 3, 3)`` a proper rotation, ``s`` ``(...)`` the scale, ``t``
        ``(..., 3)``; NaN where a weighted point is not finite, fewer than 3 points
        carry weight or ``src`` does not spread.
    """
    src, dst = np.broadcast_arrays(np.asarray(src, float), np.asarray(dst, float))
    w = np.ones(src.shape[:-1]) if weights is None else np.broadcast_to(
        np.asarray(weights, float), src.shape[:-1])
    broken = ((w > 0) & ~(np.isfinite(src).all(-1) & np.isfinite(dst).all(-1))).any(-1)
    w = np.where(np.isfinite(src).all(-1) & np.isfinite(dst).all(-1), w, 0.0)
    wk = w[..., None]
    total = wk.sum(-2)                                                   # (..., 1)
    src, dst = np.where(wk > 0, src, 0.0), np.where(wk > 0, dst, 0.0)   # weight 0: left out
    with np.errstate(invalid="ignore", divide="ignore"):
        ms, md = (wk * src).sum(-2) / total, (wk * dst).sum(-2) / total
    sc = np.where(wk > 0, src - ms[..., None, :], 0.0)
    dc = np.where(wk > 0, dst - md[..., None, :], 0.0)
    cov = np.einsum("...n,...ni,...nj->...ij", w, dc, sc)              # sum w d s^T
    U, S, Vt = np.linalg.svd(cov)
    sign = np.sign(np.linalg.det(U @ Vt))
    sign = np.where(sign == 0, 1.0, sign)
    diag = np.stack([np.ones_like(sign), np.ones_like(sign), sign], axis=-1)
    R = U @ (diag[..., :, None] * Vt)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = (S * diag).sum(-1) / np.einsum("...n,...ni,...ni->...", w, sc, sc)
    t = md - s[..., None] * np.einsum("...ij,...j->...i", R, ms)
    few = broken | (np.count_nonzero(w > 0, axis=-1) < 3) | ~np.isfinite(s) | (s <= 0)
    R = np.where(few[..., None, None], np.nan, R)
    return R, np.where(few, np.nan, s), np.where(few[..., None], np.nan, t)


#: The six distinct entries of a symmetric ``3 x 3`` matrix, in the order of
#: :func:`solve_sym3`'s rows: xx, yy, zz, xy, xz, yz.
SYM3 = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


def solve_sym3(H: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve symmetric ``3 x 3`` systems in closed form (the adjugate over the determinant).

    Args:
        H: ``(6, ...)`` each matrix's entries xx, yy, zz, xy, xz, yz.
        b: ``(3, ...)`` the right-hand sides.

    Returns:
        ``(3, ...)`` the solutions (inf or NaN where a matrix is singular).
    """
    adj, det = sym3_adjugate(H)
    with np.errstate(divide="ignore", invalid="ignore"):
        return sym3_product(adj, b) / det


def sym3_adjugate(H: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The adjugates ``(6, ...)`` (the same order) and determinants ``(...)`` of symmetric
    ``3 x 3`` matrices given as their six distinct entries ``(6, ...)``."""
    a, d, f, b, c, e = H
    adj = np.stack([d * f - e * e, a * f - c * c, a * d - b * b,
                    c * e - b * f, b * e - c * d, b * c - a * e])
    return adj, a * adj[0] + b * adj[3] + c * adj[4]


def sym3_product(S: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``(3, ...)`` symmetric matrices ``S`` ``(6, ...)`` times vectors ``v`` ``(3, ...)``."""
    return np.stack([S[0] * v[0] + S[3] * v[1] + S[4] * v[2],
                     S[3] * v[0] + S[1] * v[1] + S[5] * v[2],
                     S[4] * v[0] + S[5] * v[1] + S[2] * v[2]])


def triangulation_covariance(projections: np.ndarray | list[np.ndarray], points: np.ndarray,
                             masks: np.ndarray | list, pixel_sigma: float) -> np.ndarray:
    """First-order covariance of triangulated points under iid pixel noise.

    ``Sigma = sigma^2 (sum_v J_v^T J_v)^-1`` over the views that see the point, ``J_v``
    the ``2 x 3`` Jacobian of the view's projection at the point (Hartley and
    Zisserman, *Multiple View Geometry*, 2nd ed., sec. 5.2.1, the inverse of the
    maximum-likelihood point's information). Large along the rays where they meet at
    a small angle: a joint between the camera and the mirror has a depth standard
    deviation that grows as ``1 / sin(angle)``.

    Args:
        projections: ``V`` world-to-pixel matrices ``(3, 4)``.
        points: ``S + (3,)`` world points (NaN where absent).
        masks: ``V`` bool arrays of shape ``S``: the view observes the point.
        pixel_sigma: standard deviation of a pixel coordinate, px.

    Returns:
        ``S + (3, 3)`` covariances in the points' length unit squared; NaN where under
        two views see the point or its information is singular.
    """
    P = np.stack([np.asarray(p, dtype=float) for p in projections])                 # (V, 3, 4)
    X = np.asarray(points, dtype=float)
    shape = X.shape[:-1]
    Xt = np.nan_to_num(X.reshape(-1, 3)).T
    w = np.stack([np.asarray(k, dtype=bool).reshape(-1) for k in masks])             # (V, N)
    info = np.zeros((6, Xt.shape[1]))                        # xx, yy, zz, xy, xz, yz
    with np.errstate(divide="ignore", invalid="ignore"):
        for P_v, m in zip(P, w):
            y = P_v[:, :3] @ Xt + P_v[:, 3:4]                                      # (3, N)
            inv = np.where(m, 1.0 / y[2], 0.0)
            jx = (P_v[0, :3, None] - P_v[2, :3, None] * (y[0] * inv)) * inv        # (3, N)
            jy = (P_v[1, :3, None] - P_v[2, :3, None] * (y[1] * inv)) * inv
            for k, (a, b) in enumerate(SYM3):
                info[k] += jx[a] * jx[b] + jy[a] * jy[b]
    adj, det = sym3_adjugate(info)
    ok = (w.sum(0) >= 2) & np.isfinite(info).all(0)
    ok[ok] = det[ok] > 0
    cov = np.full((Xt.shape[1], 3, 3), np.nan)
    c = float(pixel_sigma) ** 2 * adj[:, ok] / det[ok]
    cov[ok] = c[[0, 3, 4, 3, 1, 5, 4, 5, 2]].T.reshape(-1, 3, 3)
    return cov.reshape(shape + (3, 3))


def triangulate_mirror(K: np.ndarray, normal: np.ndarray, distance: float,
                       u: np.ndarray, u_mirror: np.ndarray, *, iterations: int = 3
                       ) -> np.ndarray:
    """Triangulate joints from their direct and mirrored images.

    :func:`triangulate` with the real camera ``K [I | 0]`` and the virtual camera
    ``K [H | 2 d n]``.

    Args:
        K: ``(3, 3)`` intrinsics.
        normal: ``(3,)`` unit mirror normal (real camera frame).
        distance: mirror distance ``d``.
        u: ``(..., 2)`` direct-view pixels (undistorted).
        u_mirror: ``(..., 2)`` mirror-view pixels, same joints.
        iterations: Gauss-Newton steps after the linear solution.

    Returns:
        ``(..., 3)`` points in the real camera frame, unit of ``d``.
        Rows whose input is not finite are NaN.
    """
    eye = np.eye(4)
    X, _ = triangulate([camera_projection(K, eye), mirror_projection(K, eye, normal, distance)],
                       [np.asarray(u, dtype=float), np.asarray(u_mirror, dtype=float)],
                       iterations=iterations)
    return X


def orient_normal(K: np.ndarray, normal: np.ndarray, u: np.ndarray, u_mirror: np.ndarray
                  ) -> np.ndarray:
    """Choose the sign of ``n`` for which the triangulated joints lie in front of
    the camera and in front of the mirror (cheirality), with ``d = 1``.

    Args:
        K: ``(3, 3)`` intrinsics; normal: ``(3,)`` unit normal (either sign).
        u, u_mirror: ``(N, 2)`` paired pixels.

    Returns:
        ``(3,)`` unit normal with the better-supported sign.
    """
    n = np.asarray(normal, dtype=float).reshape(3)
    scores = []
    for cand in (n, -n):
        X = triangulate_mirror(K, cand, 1.0, u, u_mirror, iterations=0)
        good = (X[:, 2] > 0) & (X @ cand < 1.0)
        scores.append(np.count_nonzero(good))
    return n if scores[0] >= scores[1] else -n


# --------------------------------------------------------------------------- decomposition
def decompose_reflective_essential(E: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Virtual-camera pose from a (possibly not exactly skew) essential matrix.

    MirrorCalib, sec. "Reflective essential matrix decomposition":
    ``E = [t']_x D R`` with ``t' = D t``. The ordinary SVD decomposition of
    ``E`` (Hartley and Zisserman, result 9.19) gives proper rotations ``Q`` with
    ``E ~ [t']_x Q``; a reflection has ``D R = H = -Q`` for the twisted-pair
    candidate, so ``R = -D Q``. Of the two candidates we keep the one closest
    to a half-turn (``trace Q = -1``: the rotation by pi about the normal); the
    other is close to the identity.

    Returns:
        ``R`` (3, 3) rotation, ``t`` (3,) unit translation, ``n`` (3,) the
        unit normal implied by ``t`` (sign: ``n_z >= 0``).
    """
    U, _, Vt = np.linalg.svd(np.asarray(E, dtype=float))
    if np.linalg.det(U) < 0:
        U = -U
    if np.linalg.det(Vt) < 0:
        Vt = -Vt
    W = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    cands = [U @ W @ Vt, U @ W.T @ Vt]
    Q = min(cands, key=lambda q: abs(np.trace(q) + 1.0))   # the half-turn: trace -1
    t_prime = U[:, 2]
    n = t_prime if t_prime[2] >= 0 else -t_prime
    R = -D_FLIP @ Q
    t = D_FLIP @ n                                   # t = 2 d D n with 2d = 1
    return R, t, n
