"""The camera of the synthetic scenes and rigs: its matrix, projection, lens distortion,
rotations, and the checks of the arguments a scene and a rig share.

Camera matrix: ``fx = fy = (w / 2) / tan(fov / 2)`` (``fov`` horizontal), zero skew,
principal point ``(w / 2 + dx, h / 2 + dy)`` with ``dx, dy`` drawn uniformly in +-4 px
(a real camera's principal point is never exactly central).
"""

from __future__ import annotations

import numpy as np

__all__ = ["D_FLIP", "Z_MIN", "check_camera_args", "distort_pixels", "project",
           "random_camera_matrix", "rot_x", "rot_y", "rot_z", "tilted_normal"]

#: Reflection of the x axis that makes the virtual camera's rotation proper.
D_FLIP = np.diag([-1.0, 1.0, 1.0])

Z_MIN = 0.5           # m: nearest a joint (or its reflection) may be to the camera plane


def tilted_normal(normal: np.ndarray, deg: float, rng: np.random.Generator) -> np.ndarray:
    """A unit vector ``deg`` degrees from the unit ``normal`` ``(3,)``, in a random direction:
    a perturbed initial mirror (the virtual camera then turns by ``2 deg``)."""
    n = np.asarray(normal, dtype=float)
    a = rng.normal(size=3)
    a -= (a @ n) * n
    a /= np.linalg.norm(a)
    m = np.cos(np.radians(deg)) * n + np.sin(np.radians(deg)) * a
    return m / np.linalg.norm(m)


def project(K: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Pinhole projection ``pi(K X)`` of points ``(..., 3)`` -> ``(..., 2)``."""
    x = X[..., :2] / X[..., 2:3]
    return x * np.array([K[0, 0], K[1, 1]]) + x[..., ::-1] * np.array([K[0, 1], 0.0]) \
        + K[:2, 2]


def distort_pixels(K: np.ndarray, dist: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Apply OpenCV's lens distortion (``k1, k2, p1, p2[, k3]``) to pinhole pixels.

    The same mapping as :func:`cv2.projectPoints` with these coefficients, so
    that undistorting the result with ``K, dist`` recovers ``pts``.
    """
    d = np.zeros(5)
    dist = np.asarray(dist, dtype=float).ravel()
    d[:len(dist)] = dist
    k1, k2, p1, p2, k3 = d
    fx, fy, s, cx, cy = K[0, 0], K[1, 1], K[0, 1], K[0, 2], K[1, 2]
    y = (pts[..., 1] - cy) / fy
    x = (pts[..., 0] - cx - s * y) / fx
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return np.stack([fx * xd + s * yd + cx, fy * yd + cy], -1)


def random_camera_matrix(rng: np.random.Generator, image_size: tuple[int, int], fov_deg: float
                   ) -> np.ndarray:
    w, h = image_size
    f = (w / 2.0) / np.tan(np.radians(fov_deg) / 2.0)
    dx, dy = rng.uniform(-4.0, 4.0, 2)
    return np.array([[f, 0.0, w / 2.0 + dx], [0.0, f, h / 2.0 + dy], [0.0, 0.0, 1.0]])


def rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1.0, 0], [-s, 0, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def check_camera_args(frames: int, image_size: tuple[int, int], fov_deg: float, fps: float,
                      noise_std: float) -> tuple[int, int, int]:
    """Check the arguments a synthetic scene and a synthetic rig share.

    Returns:
        ``(T, width, height)`` as ints.

    Raises:
        ValueError: naming the argument out of range.
    """
    T = int(frames)
    if T < 1:
        raise ValueError(f"frames must be >= 1, got {frames}")
    w, h = (int(image_size[0]), int(image_size[1]))
    if w <= 0 or h <= 0:
        raise ValueError(f"image_size must be positive, got {image_size}")
    if not 0.0 < fov_deg < 180.0:
        raise ValueError(f"fov_deg must be in (0, 180), got {fov_deg}")
    if fps <= 0:
        raise ValueError(f"fps must be positive, got {fps}")
    if noise_std < 0:
        raise ValueError(f"noise_std must be >= 0, got {noise_std}")
    return T, w, h
