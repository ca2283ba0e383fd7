"""The initial search of an unknown focal length: the one that makes the body most rigid.

For one held camera whose focal length is estimated (:attr:`~.rig.Camera.estimate_focal`)
and its mirrors, candidates log-spaced over a range of fields of view
(:func:`focal_candidates`) each get the normals their epipoles give and a short solve
of the full graph on spread frames; the profile of the graph's error over ``log f`` is
the criterion (:func:`focal_search`). The driver (:mod:`.stages`) starts the graph's
own estimate of the focal length there; the rig front end uses it for one camera
(:mod:`mirrorgraph.initial.rig`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import DegenerateGeometryError
from ..keypoints import MIN_PAIRS
from .bones import gauge_scale
from .builder import build_problem
from .options import RefineOptions
from .outliers import clean_views
from .problem import snap_virtual_poses
from .rig import Rig, seen_twice, spread_rows, triangulate_rig, with_intrinsics, with_views
from .solve_graph import optimize
from .stage_config import SolveConfig

__all__ = ["focal_searchable", "focal_candidates", "focal_search", "FOCAL_SEARCH_ITERATIONS",
           "FOCAL_SEARCH_MIN_KEPT"]


def focal_searchable(rig: Rig) -> bool:
    """A rig whose focal length the search (:func:`focal_search`) can start: one held camera
    whose focal length is estimated, seen through its mirrors."""
    return (len(rig.cameras) == 1 and rig.cameras[0].estimate_focal
            and not rig.cameras[0].estimate_pose and len(rig.mirrors) > 0)


def focal_candidates(K: np.ndarray, opts: RefineOptions) -> np.ndarray:
    """``(S,)`` candidate focal lengths, px: log-spaced over the horizontal fields of view of
    ``opts.focal.search_fov_deg`` for an image ``2 cx`` wide."""
    lo, hi = opts.focal.search_fov_deg
    width = 2.0 * float(K[0, 2])
    fov = np.radians(np.geomspace(float(hi), float(lo), int(opts.focal.search_steps)))
    return 0.5 * width / np.tan(0.5 * fov)


def focal_search(rig: Rig, masks: list[np.ndarray], poses: list[np.ndarray],
                 planes: list[tuple[np.ndarray, float]], opts: RefineOptions,
                 config: SolveConfig, height: float | None
                 ) -> tuple[Rig, list[tuple[np.ndarray, float]], dict]:
    """The focal length that makes the body most rigid, among candidates: the start of
    the graph's own estimate.

    For a camera at the origin the epipole ``e ~ K n`` of each mirror is what the
    images fix; a candidate focal length ``f`` gives the normal ``n ~ K_f^-1 e`` (the
    distance is a gauge). Each candidate's graph (every joint of
    ``opts.focal.search_frames`` frames spread over the video, every bone in every
    frame: one set of factors for all, so that their errors compare; the focal length
    held) is solved for a few iterations, and the errors are the profile of the
    objective over ``f``. The errors compare only on the same observations: each
    candidate's cleaning (triangulation, rays meeting under the warm start's angle,
    outliers) keeps its own, and a longer focal length narrows the rays, so its
    cleaning drops the noisiest joints and its error sums fewer, quieter terms (on the
    independent generator's scene_901, 3 % outliers and left/right swaps: the minimum
    at +23 % with each candidate's own observations, at -0.2 % with common ones). So
    every compared candidate (those whose cleaning kept at least
    :data:`FOCAL_SEARCH_MIN_KEPT` of what the best-kept one kept) is solved on the
    observations they all keep. The geometric midpoints on either side of the best
    candidate are solved too, and a parabola in ``log f`` through the best of these and
    its neighbours gives the start. The graph's estimate that follows keeps the bones
    of ``opts.focal.bone_bias_limit``.

    Args:
        rig: one camera (held) with ``estimate_focal``, its mirrors, views; its ``K`` is
            the initial guess (the principal point stays).
        masks: per view the observations to use; poses, planes: the current rig.
        opts, config: the solve's options and configuration.
        height: the subject's height (the gauge), or ``None``.

    Returns:
        The rig with the chosen ``K``, the planes turned to it, and the stage's record
        (``{"name", "candidates_px", "errors", "kept", "refined_px", "refined_errors",
        "compared_observations", "focal_px", ...}``: ``kept`` each candidate's own
        cleaning's count, ``compared_observations`` the count all were solved on,
        ``None`` where too few joints are common and each is solved on its own).
    """
    K0 = np.asarray(rig.cameras[0].K, dtype=float)
    epipoles = [K0 @ np.asarray(n, float) for n, _ in planes]
    rows = spread_rows(rig.num_frames, opts.focal.search_frames)
    sub = rig.subset(rows)
    sub_masks = [np.asarray(m, bool)[rows] for m in masks]
    sopts = replace(opts, bone_bias_limit=None, focal=replace(opts.focal, bone_bias_limit=None),
                    use_bone_length=True)

    def candidate(f: float) -> tuple[Rig, list[tuple[np.ndarray, float]]]:
        K = K0.copy()
        K[0, 0] = K[1, 1] = f
        return (with_intrinsics(sub, [K]),
                [(_normal_from_epipole(K, e, n), d) for e, (n, d) in zip(epipoles, planes)])

    def cleaned(f: float) -> list[np.ndarray]:
        frig, fplanes = candidate(f)
        _, fm, _, _ = clean_views(frig, sub_masks, poses, fplanes, sopts, config,
                                  opts.warm_start_min_parallax_deg)
        return [np.asarray(m, bool) for m in fm]

    def profile(f: float, fm: list[np.ndarray]) -> float:
        frig, fplanes = candidate(f)
        pts, ok = triangulate_rig(frig, fm, poses, fplanes)
        used = seen_twice(fm) & ok & np.isfinite(pts).all(-1)
        if np.count_nonzero(used) < MIN_PAIRS:
            return np.inf
        fm = [m & used for m in fm]
        fposes = [np.asarray(p, float).copy() for p in poses]
        if height is not None:
            scale = gauge_scale(frig, pts, used, float(height))
            pts, fplanes = pts * scale, [(n, d * scale) for n, d in fplanes]
            for p in fposes:
                p[:3, 3] *= scale
        problem = build_problem(with_views(frig, fm, fposes, fplanes), pts, used, fplanes,
                                sopts, body_height=height, hold_intrinsics=True,
                                final_kernel=None)
        snap_virtual_poses(problem, problem.values)
        try:
            res, _ = optimize(problem, problem.full(), sopts,
                              distance_gauge=problem.distance_gauge,
                              max_iterations=FOCAL_SEARCH_ITERATIONS)
        except DegenerateGeometryError:
            return np.inf
        return float(res.final_error)

    fs = focal_candidates(K0, opts)
    own = [cleaned(f) for f in fs]
    kept = np.array([sum(int(np.count_nonzero(m & seen_twice(fm))) for m in fm) for fm in own],
                    dtype=float)
    # the errors compare only on the same data: each candidate's cleaning keeps its own
    # observations (a longer focal length narrows the rays' angles, and the joints whose
    # rays meet at the smallest angles, the noisiest bones, leave: its error sums fewer,
    # quieter terms). So every candidate is solved on the observations all the compared
    # candidates keep, and a candidate whose cleaning kept fewer than
    # FOCAL_SEARCH_MIN_KEPT of the best-kept one's is not compared (a wrong focal length
    # that rejects two thirds of the pairs leaves too little in common)
    compared = kept >= FOCAL_SEARCH_MIN_KEPT * kept.max()
    common = [np.logical_and.reduce([own[i][v] for i in np.flatnonzero(compared)])
              for v in range(len(sub_masks))]
    if np.count_nonzero(seen_twice(common)) < MIN_PAIRS:      # each its own, as a last resort
        common = None
    errors = np.array([profile(f, own[i] if common is None else common) if compared[i]
                       else np.inf for i, f in enumerate(fs)])
    best = int(np.argmin(errors))
    # the candidates are a factor ~1.3 apart: the geometric midpoints on either side of
    # the best, then a parabola in log f through the best of these and its neighbours
    near = [float(np.sqrt(fs[j] * fs[best])) for j in (best - 1, best + 1)
            if 0 <= j < len(fs) and np.isfinite(errors[j])]
    near_errors = [profile(f, cleaned(f) if common is None else common) for f in near]
    grid, errs = np.concatenate([fs, near]), np.concatenate([errors, near_errors])
    order = np.argsort(grid)
    grid, errs = grid[order], errs[order]
    at = int(np.argmin(errs))
    f = float(grid[at])
    if 0 < at < len(grid) - 1 and np.all(np.isfinite(errs[at - 1:at + 2])):
        x = np.log(grid[at - 1:at + 2])
        a, b, _ = np.polyfit(x, errs[at - 1:at + 2], 2)
        if a > 0:
            f = float(np.exp(np.clip(-b / (2 * a), x[0], x[2])))
    K = K0.copy()
    K[0, 0] = K[1, 1] = f
    new_planes = [(_normal_from_epipole(K, e, n), d) for e, (n, d) in zip(epipoles, planes)]
    record = {"name": "focal search (%d candidates, %d frames, focal held)"
              % (len(fs), int(np.count_nonzero(rows))),
              "iterations": 0, "initial_error": float("nan"),
              "final_error": float(errs[at]), "converged": True, "rejected": 0,
              "failed_steps": 0, "guarded": 0, "undetermined": 0,
              "candidates_px": [float(x) for x in fs],
              "errors": [float(x) for x in errors], "kept": [int(k) for k in kept],
              "refined_px": [float(x) for x in near],
              "refined_errors": [float(x) for x in near_errors],
              "compared_observations": (None if common is None
                                        else int(sum(np.count_nonzero(m & seen_twice(common))
                                                      for m in common))),
              "focal_px": f, "frames": int(np.count_nonzero(rows)),
              "initial_focal_px": float(K0[0, 0])}
    return with_intrinsics(rig, [K]), new_planes, record


#: Iterations (at most) of each candidate's solve in :func:`focal_search`. Its error is
#: the profile only where the solve has nearly converged: on a real clip (Pose2Sim's
#: demo, OpenPose, cam02 with cam04 as its mirror) 3 iterations left the errors of
#: neighbouring candidates 70 % apart and the search at -37 %; 10 smooth the profile
#: about the minimum (-10 %).
FOCAL_SEARCH_ITERATIONS = 10


#: A candidate of :func:`focal_search` whose cleaning kept fewer than this fraction of the
#: observations the best-kept candidate kept is not compared.
FOCAL_SEARCH_MIN_KEPT = 0.9


def _normal_from_epipole(K: np.ndarray, e: np.ndarray, like: np.ndarray) -> np.ndarray:
    """Unit ``K^-1 e`` (3,), the sign of ``like`` (the normal it replaces)."""
    n = np.linalg.solve(K, np.asarray(e, float))
    n /= np.linalg.norm(n)
    return n if n @ np.asarray(like, float) >= 0 else -n
