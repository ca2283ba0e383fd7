"""Initial estimators of the mirror from paired joints: solvers + RANSAC.

Three estimators, chosen by name (``--estimator``):

``reflective`` (default, ours)
    RANSAC over the 2-point minimal solver of ``F = [e]_x``, scored by the
    Sampson epipolar distance in pixels; weighted linear least squares on
    the inliers in one shared normalisation; a robust nonlinear refinement of
    the epipolar distance; a final inlier pass.
``eightpoint``
    MirrorCalib's Baseline1: OpenCV's normalised eight-point algorithm on all
    pairs, no mirror constraint, no RANSAC; pose from ``E = K^T F K``.
``reflective8``
    MirrorCalib's 6-unknown reflective eight-point algorithm inside the
    paper's RANSAC (samples of six pairs, epipolar-distance threshold), refit
    on the largest inlier set.

Every estimator returns a :class:`MirrorEstimate` whose normal is oriented away
from the camera (``n_z > 0``, then checked by cheirality).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .. import geometry as geo
from ..errors import DegenerateGeometryError, InputError
from .ransac import RansacOptions, ransac
from .solvers.eightpoint import fundamental_eight_point, fundamental_reflective_eight_point
from .solvers.normalization import SimilarityNormalizer
from .solvers.reflective import (epipole_from_two_pairs, epipole_least_squares, pair_lines,
                                 refine_epipole)

ESTIMATORS = ("reflective", "eightpoint", "reflective8")

#: ``progress(iteration, planned)`` of a RANSAC.
RansacProgress = Callable[[int, int], None]

#: Default inlier threshold on the epipolar distance, pixels: 2.5 sigma of the
#: 4 px detector noise that MirrorCalib measured for HRNet.
DEFAULT_THRESHOLD_PX = 10.0

#: Minimum pixel separation of a joint and its reflection for the pair to
#: define a line (closer pairs carry no direction).
MIN_PAIR_SEPARATION_PX = 2.0


@dataclass
class MirrorEstimate:
    """An initial estimate of the mirror (scale unknown).

    Attributes:
        estimator: name of the estimator.
        epipole: ``(3,)`` homogeneous epipole in pixels, unit norm, ``~ K n``.
        normal: ``(3,)`` unit mirror normal, real camera frame, away from the camera.
        fundamental: ``(3, 3)`` fundamental matrix in pixels, unit Frobenius norm
            (exactly skew-symmetric for ``reflective``).
        inliers: ``(N,)`` bool over the pairs given.
        residuals: ``(N,)`` epipolar distances in pixels (Sampson for
            ``reflective``, the paper's symmetric point-to-line distance otherwise).
        iterations: RANSAC samples drawn (0 without RANSAC).
        decomposed_rotation: ``(3, 3)`` rotation of the virtual camera as the
            essential-matrix decomposition gives it (before the mirror
            constraint is imposed; equal to ``D (I - 2nn^T)`` for ``reflective``).
    """

    estimator: str
    epipole: np.ndarray
    normal: np.ndarray
    fundamental: np.ndarray
    inliers: np.ndarray
    residuals: np.ndarray
    iterations: int = 0
    decomposed_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))

    @property
    def inlier_ratio(self) -> float:
        return float(np.mean(self.inliers)) if self.inliers.size else 0.0


#: Most inlier pairs the nonlinear refinement of the epipole sees (a random share of
#: them beyond: 60,000 pairs are 5,000 frames of 12 joints, whose statistical error is
#: far below any detector's bias; the factor graph uses every pair).
REFINE_MAX_PAIRS = 60000


def _usable(u: np.ndarray, um: np.ndarray) -> np.ndarray:
    ok = np.isfinite(u).all(1) & np.isfinite(um).all(1)
    ok[ok] &= np.linalg.norm(u[ok] - um[ok], axis=1) >= MIN_PAIR_SEPARATION_PX
    return ok


def estimate_epipole(u: np.ndarray, u_mirror: np.ndarray, *, threshold_px: float = DEFAULT_THRESHOLD_PX,
                     seed: int = 0, max_iterations: int = 2000, refine: bool = True,
                     progress: RansacProgress | None = None
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Reflective RANSAC for the epipole alone (no intrinsics needed).

    Args:
        u, u_mirror: ``(N, 2)`` undistorted pixel pairs (joint, reflection).
        threshold_px: inlier threshold on the symmetric epipolar distance.
        seed: RANSAC seed.
        max_iterations: RANSAC cap.
        refine: run the robust nonlinear refinement on the inliers.
        progress: ``progress(iteration, planned)`` of the RANSAC (optional).

    Returns:
        ``(e, inliers, residuals, iterations)``: ``(3,)`` unit homogeneous
        epipole in pixels, ``(N,)`` bool, ``(N,)`` pixels, samples drawn.

    Raises:
        DegenerateGeometryError: fewer than two usable pairs, all lines
            (nearly) identical, or too few inliers.
    """
    u = np.asarray(u, dtype=float).reshape(-1, 2)
    um = np.asarray(u_mirror, dtype=float).reshape(-1, 2)
    ok = _usable(u, um)
    idx = np.flatnonzero(ok)
    if idx.size < 2:
        raise DegenerateGeometryError(
            f"only {idx.size} usable joint/reflection pairs; at least 2 (in practice "
            "dozens, over several frames) are needed to find the mirror")
    norm = SimilarityNormalizer.fit(u[idx], um[idx])
    a, b = norm.apply(u[idx]), norm.apply(um[idx])
    lines = pair_lines(a, b)
    thr_n = threshold_px * norm.scale

    def residuals(e: np.ndarray, sel: np.ndarray | None = None) -> np.ndarray:
        return (geo.epipolar_distances(e, a, b) if sel is None
                else geo.epipolar_distances(e, a[sel], b[sel]))

    def refit(mask: np.ndarray, _model: np.ndarray) -> np.ndarray:
        # weight lines by the pair's separation: long lines fix e better
        w = np.linalg.norm(a[mask] - b[mask], axis=1)
        return epipole_least_squares(lines[mask], w)

    result = ransac(len(idx), 2, lambda s: epipole_from_two_pairs(lines[s]), residuals,
                    RansacOptions(threshold=thr_n, seed=seed, max_iterations=max_iterations),
                    refit=refit, progress=progress)
    if result is None:
        raise DegenerateGeometryError(
            "every joint/reflection line is the same line: the person does not move "
            "enough to determine the mirror")
    e_n = result.model
    inl = result.inliers
    if np.count_nonzero(inl) < 2:
        raise DegenerateGeometryError("fewer than two pairs agree on a mirror")
    _check_spread(lines[inl])
    e = norm.epipole_to_pixels(e_n)
    if refine:
        sel = np.flatnonzero(inl)
        if len(sel) > REFINE_MAX_PAIRS:          # a long video: a random share of its inliers
            sel = np.sort(np.random.default_rng(seed).choice(sel, REFINE_MAX_PAIRS, replace=False))
        e = refine_epipole(e, u[idx][sel], um[idx][sel], loss_scale_px=threshold_px / 2)
    r_all = np.full(len(u), np.inf)
    r_all[idx] = geo.epipolar_distances(e, u[idx], um[idx])
    return e, r_all < threshold_px, r_all, result.iterations


def _check_spread(lines: np.ndarray) -> None:
    """Refuse an epipole fixed by lines of (nearly) one direction."""
    M = lines.T @ lines
    w = np.linalg.eigvalsh(M)
    # w[0] ~ 0 at the solution; w[1] / w[2] measures how many line directions there are
    if w[2] <= 0 or w[1] / w[2] < 1e-6:
        raise DegenerateGeometryError(
            "all joint/reflection lines are (nearly) parallel and identical: the epipole "
            "cannot be determined from this data")


def _orient_and_package(name, K, e, F, u, um, inliers, residuals, iterations, R_dec=None):
    n = geo.normal_from_epipole(K, e)
    if np.any(inliers):
        n = geo.orient_normal(K, n, u[inliers], um[inliers])
    e_or = geo.epipole_from_normal(K, n)
    R_dec = geo.virtual_camera_from_mirror(n, 1.0)[0] if R_dec is None else R_dec
    return MirrorEstimate(estimator=name, epipole=e_or, normal=n, fundamental=F,
                          inliers=inliers, residuals=residuals, iterations=iterations,
                          decomposed_rotation=R_dec)


def estimate_mirror(u: np.ndarray, u_mirror: np.ndarray, K: np.ndarray, *,
                    estimator: str = "reflective", threshold_px: float = DEFAULT_THRESHOLD_PX,
                    seed: int = 0, progress: RansacProgress | None = None) -> MirrorEstimate:
    """Estimate the mirror from paired joints with the named estimator.

    Args:
        u, u_mirror: ``(N, 2)`` undistorted pixels of joints and their
            reflections (mirror labels already flipped).
        K: ``(3, 3)`` intrinsics.
        estimator: one of :data:`ESTIMATORS`.
        threshold_px: inlier threshold on the symmetric epipolar distance.
        seed: RANSAC seed.
        progress: ``progress(iteration, planned)`` of the RANSAC of the
            ``reflective`` estimator (optional).

    Raises:
        DegenerateGeometryError: the data cannot determine the mirror.
        InputError: unknown estimator (as :func:`mirrorgraph.calibrate` says it).
    """
    u = np.asarray(u, dtype=float).reshape(-1, 2)
    um = np.asarray(u_mirror, dtype=float).reshape(-1, 2)
    if estimator == "reflective":
        e, inl, r, it = estimate_epipole(u, um, threshold_px=threshold_px, seed=seed,
                                         progress=progress)
        return _orient_and_package(estimator, K, e, geo.fundamental_from_epipole(e), u, um,
                                   inl, r, it)
    if estimator == "eightpoint":
        ok = _usable(u, um)
        F = fundamental_eight_point(u[ok], um[ok])
        return _from_fundamental(estimator, K, F, u, um, threshold_px, 0)
    if estimator == "reflective8":
        return _reflective_eight_point_ransac(u, um, K, threshold_px, seed)
    raise InputError(f"unknown estimator {estimator!r}; choose one of {', '.join(ESTIMATORS)}",
                     field="estimator")


def _from_fundamental(name, K, F, u, um, threshold_px, iterations):
    E = K.T @ F @ K
    R_dec, _t, n = geo.decompose_reflective_essential(E)
    e = geo.epipole_from_normal(K, n)
    r = geo.epipolar_distances_fundamental(F, u, um)
    return _orient_and_package(name, K, e, F, u, um, r < threshold_px, r, iterations, R_dec)


def _reflective_eight_point_ransac(u, um, K, threshold_px, seed):
    ok = _usable(u, um)
    idx = np.flatnonzero(ok)
    if idx.size < 6:
        raise DegenerateGeometryError(
            f"the reflective eight-point algorithm needs 6 pairs, got {idx.size}")
    a, b = u[idx], um[idx]

    def solve(sample):
        try:
            return [fundamental_reflective_eight_point(a[sample], b[sample])]
        except (DegenerateGeometryError, np.linalg.LinAlgError):
            return []

    result = ransac(len(idx), 6, solve,
                    lambda F, sel=None: (geo.epipolar_distances_fundamental(F, a, b) if sel is None
                                         else geo.epipolar_distances_fundamental(F, a[sel], b[sel])),
                    RansacOptions(threshold=threshold_px, seed=seed),
                    refit=lambda m, _F: fundamental_reflective_eight_point(a[m], b[m]))
    if result is None:
        raise DegenerateGeometryError("the reflective eight-point RANSAC found no model")
    return _from_fundamental("reflective8", K, result.model, u, um, threshold_px,
                             result.iterations)
