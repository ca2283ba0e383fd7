"""Solve one built graph: Levenberg-Marquardt (:mod:`.optimizer`) set up for a problem.

For a :class:`~.problem.GraphProblem`: the solver's parameters from the options
(:func:`lm_params`), the mirror links exact (:func:`~.reduction.mirror_reduction`), the
cheirality guard on, and the bone lengths set to their optimum between steps
(:func:`optimize`); the reduced information at a
solution (:func:`information_at`) and the joints GTSAM found undetermined
(:func:`undetermined`). Every solve of the driver (:mod:`.stages`), the focal search
and the chunks goes through :func:`optimize`.
"""

from __future__ import annotations

from typing import Callable

import gtsam
import numpy as np

from .lengths import update_lengths
from .optimizer import LevenbergMarquardt, LMParams, LMResult
from .options import RefineOptions
from .problem import GraphProblem, cheirality_guard, point_keys
from .reduction import mirror_reduction

__all__ = ["Progress", "FOCAL_BACKTRACK", "lm_params", "optimize", "information_at",
           "undetermined"]

#: ``progress(iteration, error)``: the user's callback of the solves' iterations.
Progress = Callable[[int, float], None]


#: Halvings of an undamped step that overshoots where intrinsics are estimated
#: (:attr:`~.optimizer.LMParams.backtrack`).
FOCAL_BACKTRACK = 4


def lm_params(opts: RefineOptions, problem: GraphProblem,
              max_iterations: int | None = None) -> LMParams:
    """:class:`~.optimizer.LMParams` from the options; the points' damping scale is the typical
    information of a point seen in two views, ``2 (f / Z)^2 / sigma^2`` (graph units)."""
    K = problem.rig.cameras[0].K
    depth = problem.median_depth
    scale = 2.0 * (K[0, 0] / max(depth, 1e-9)) ** 2 / opts.pixel_sigma ** 2
    return LMParams(max_iterations=opts.max_iterations if max_iterations is None
                    else max_iterations, relative_tolerance=opts.relative_tolerance,
                    global_step_tolerance=opts.global_step_tolerance, local_scale=scale,
                    backtrack=FOCAL_BACKTRACK if problem.calibration_keys else 0)


def optimize(problem: GraphProblem, graph: gtsam.NonlinearFactorGraph, opts: RefineOptions,
             *, distance_gauge: float | None, max_iterations=None,
             hold_globals: bool = False, progress: Progress | None = None,
             values: gtsam.Values | None = None, sensitivity: bool = False
             ) -> tuple[LMResult, list[tuple[int, int]]]:
    """Levenberg-Marquardt on ``graph`` from ``values`` (default: the problem's initial
    values) with the links exact, the cheirality guard on. Where the problem has bone
    factors and the globals move, the bone lengths are set to their optimum after
    every accepted step (:func:`~.lengths.update_lengths`; ``problem`` holds the last
    ones, and ``graph`` must be its :meth:`~.problem.GraphProblem.full` graph). With
    ``sensitivity`` the result holds the points' change per unit of the reduced globals
    (:attr:`~.optimizer.LMResult.sensitivity`, reshaped ``(N, 3, nz)`` in
    ``problem.flat_index`` order)."""
    red = mirror_reduction(problem, distance_gauge=distance_gauge)
    refresh = None
    if problem.lengths is not None and not hold_globals and problem.length_key is None:
        current = [graph]

        def refresh(v: gtsam.Values) -> gtsam.NonlinearFactorGraph:
            # the bone factors are made again only when a length moved by more than
            # the tolerance of the globals' steps, in its own standard deviations
            L, std = update_lengths(problem, v)
            if np.any(np.abs(L - problem.lengths) > opts.global_step_tolerance * std):
                problem.set_lengths(L)
                current[0] = problem.full()
            return current[0]
    lm = LevenbergMarquardt(graph, red, lm_params(opts, problem, max_iterations),
                            ordering=problem.point_ordering(), hold_globals=hold_globals,
                            guard=cheirality_guard(problem), refresh=refresh,
                            sensitivity_keys=point_keys(problem.flat_index) if sensitivity
                            else None)
    res = lm.optimize(problem.values if values is None else values, progress)
    if res.sensitivity is not None:
        res.sensitivity = res.sensitivity.reshape(len(problem.flat_index), 3, -1)
    if problem.length_key is not None:       # the lengths are a variable: read them back
        problem.lengths = np.asarray(res.values.atVector(problem.length_key), dtype=float)
    return res, red.z_keys


def information_at(problem: GraphProblem, values: gtsam.Values, opts: RefineOptions
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The reduced information and gradient of ``problem``'s full graph at ``values``
    (:meth:`~.optimizer.LevenbergMarquardt.reduced_system`)."""
    red = mirror_reduction(problem, distance_gauge=problem.distance_gauge)
    lm = LevenbergMarquardt(problem.full(), red, lm_params(opts, problem),
                            ordering=problem.point_ordering())
    return lm.reduced_system(values)


def undetermined(problem: GraphProblem, res: LMResult) -> np.ndarray:
    """``(T, J)`` bool: the points GTSAM found (nearly) undetermined during ``res``
    (:attr:`~.optimizer.LMResult.indeterminate`); they are dropped with their pairs."""
    T, J = problem.used.shape
    out = np.zeros(T * J, dtype=bool)
    flat = np.array(sorted(res.indeterminate), dtype=np.uint64) - np.uint64(point_keys([0])[0])
    flat = flat[flat < T * J].astype(np.int64)
    out[flat] = True
    return out.reshape(T, J) & problem.used
