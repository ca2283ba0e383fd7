"""Isotropic point normalisation (Hartley, "In defense of the eight-point
algorithm", PAMI 1997; Hartley and Zisserman sec. 4.4.4).

For the reflective fundamental matrix both views live in the same image, so
*one* similarity is fitted to the points of both views together. With the same
``T`` on both sides ``T^T [e]_x T = det(T) [T^-1 e]_x`` stays skew-symmetric,
which two separate normalisations (as in the paper's eight-point variant) break.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SimilarityNormalizer:
    """Similarity ``x_n = s (x - c)`` taking points to mean distance sqrt(2) from 0.

    Attributes:
        center: ``(2,)`` pixel centroid ``c``.
        scale: ``s`` (1 / pixels).
    """

    center: np.ndarray
    scale: float

    @classmethod
    def fit(cls, *point_sets: np.ndarray) -> "SimilarityNormalizer":
        """Fit to the union of ``(N_i, 2)`` pixel arrays (finite rows only)."""
        pts = np.concatenate([np.asarray(p, dtype=float).reshape(-1, 2) for p in point_sets])
        pts = pts[np.isfinite(pts).all(1)]
        if len(pts) == 0:
            return cls(np.zeros(2), 1.0)
        c = pts.mean(0)
        mean_dist = np.mean(np.linalg.norm(pts - c, axis=1))
        return cls(c, float(np.sqrt(2.0) / mean_dist) if mean_dist > 0 else 1.0)

    @property
    def matrix(self) -> np.ndarray:
        """``(3, 3)`` homogeneous matrix ``T`` of the similarity."""
        s, (cx, cy) = self.scale, self.center
        return np.array([[s, 0.0, -s * cx], [0.0, s, -s * cy], [0.0, 0.0, 1.0]])

    def apply(self, u: np.ndarray) -> np.ndarray:
        """``(..., 2)`` pixels -> ``(..., 2)`` normalised coordinates."""
        return (np.asarray(u, dtype=float) - self.center) * self.scale

    def epipole_to_pixels(self, e_normalized: np.ndarray) -> np.ndarray:
        """Homogeneous epipole ``(3,)`` in normalised coordinates -> pixels (unit norm)."""
        e = np.linalg.solve(self.matrix, np.asarray(e_normalized, dtype=float))
        return e / np.linalg.norm(e)

    def epipole_to_normalized(self, e_pixels: np.ndarray) -> np.ndarray:
        """Homogeneous epipole ``(3,)`` in pixels -> normalised coordinates (unit norm)."""
        e = self.matrix @ np.asarray(e_pixels, dtype=float)
        return e / np.linalg.norm(e)
