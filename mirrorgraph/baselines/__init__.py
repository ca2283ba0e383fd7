"""Other methods, for comparison with mirrorgraph (``bench/compare.py``).

* :mod:`.paper` — MirrorCalib (Liao, Zheng and Mitchell) as the paper writes it:
  6-unknown reflective eight-point, L-BFGS refinement of the 2D joints on the six
  body losses (PyTorch), RANSAC with six pairs. Needs ``torch``.
* :mod:`.anipose` — aniposelib's bundle adjustment (``CameraGroup.bundle_adjust_iter``)
  on the person and the horizontally flipped reflection, the tool a multi-camera
  user already has. Needs ``aniposelib``.

Neither is a dependency of mirrorgraph: both import their library lazily and
say how to install it (``pip install 'mirrorgraph[bench]'``) when it is missing.

Every baseline reports the virtual camera in the package's convention
(:mod:`mirrorgraph.geometry`): ``X_virtual = D (R X + t)``, ``D = diag(-1, 1, 1)``,
``R`` a proper rotation. A general ``(R, t)`` (one that an unconstrained
estimator returns) need not be the reflection of a plane; :func:`triangulate_virtual`
triangulates with any such camera.
"""

from __future__ import annotations

import numpy as np

from ..geometry import project_with_jacobian

__all__ = ["BenchDependencyError", "require", "triangulate_virtual"]

_D = np.diag([-1.0, 1.0, 1.0])


class BenchDependencyError(ImportError):
    """A library needed only by the comparison baselines is not installed."""


def require(module: str, what: str):
    """Import ``module`` or raise :class:`BenchDependencyError` naming the extra to install."""
    import importlib
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise BenchDependencyError(
            f"{what} needs the Python package '{module}', which is not installed: "
            "pip install 'mirrorgraph[bench]'") from exc


def triangulate_virtual(K: np.ndarray, R: np.ndarray, t: np.ndarray, u: np.ndarray,
                        u_mirror: np.ndarray, *, iterations: int = 3) -> np.ndarray:
    """Triangulate with the real camera ``K [I | 0]`` and a virtual camera ``(R, t)``.

    The virtual camera images ``X`` at ``pi(K D (R X + t))``; ``(R, t)`` need not
    come from a mirror. Linear triangulation (DLT, rows normalised), then
    ``iterations`` batched Gauss-Newton steps on the reprojection error of both
    views.

    Args:
        K: ``(3, 3)`` intrinsics.
        R: ``(3, 3)`` rotation; t: ``(3,)`` translation (any scale).
        u, u_mirror: ``(..., 2)`` pixels of the same joints in the two views.

    Returns:
        ``(..., 3)`` points in the real camera frame, unit of ``t``; NaN where
        the input is not finite.
    """
    K = np.asarray(K, float)
    M = _D @ np.asarray(R, float)
    c = _D @ np.asarray(t, float).reshape(3)
    u = np.asarray(u, float)
    um = np.asarray(u_mirror, float)
    shape = u.shape[:-1]
    a, b = u.reshape(-1, 2), um.reshape(-1, 2)
    ok = np.isfinite(a).all(1) & np.isfinite(b).all(1)
    out = np.full((len(a), 3), np.nan)
    if not ok.any():
        return out.reshape(shape + (3,))
    a, b = a[ok], b[ok]
    P1 = np.hstack([K, np.zeros((3, 1))])
    P2 = K @ np.hstack([M, c[:, None]])
    A = np.stack([a[:, :1] * P1[2] - P1[0], a[:, 1:2] * P1[2] - P1[1],
                  b[:, :1] * P2[2] - P2[0], b[:, 1:2] * P2[2] - P2[1]], axis=1)
    A /= np.linalg.norm(A, axis=2, keepdims=True)
    Xh = np.linalg.svd(A)[2][:, -1, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        X = Xh[:, :3] / Xh[:, 3:4]
    for _ in range(iterations):
        X = _gauss_newton(K, M, c, X, a, b)
    out[ok] = X
    return out.reshape(shape + (3,))


def _gauss_newton(K, M, c, X, a, b):
    with np.errstate(divide="ignore", invalid="ignore"):
        p1, J1 = project_with_jacobian(K, X)
        p2, J2 = project_with_jacobian(K @ np.column_stack([M, c]), X)
        r = np.concatenate([p1 - a, p2 - b], 1)
        J = np.concatenate([J1, J2], 1)
        JtJ = np.einsum("nki,nkj->nij", J, J) + 1e-12 * np.eye(3)
        step = np.linalg.solve(JtJ, np.einsum("nki,nk->ni", J, r)[..., None])[..., 0]
    step[~np.isfinite(step).all(1)] = 0.0
    return X - step
