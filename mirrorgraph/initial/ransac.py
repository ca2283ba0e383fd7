"""A generic RANSAC that takes any minimal solver.

The estimator knows nothing of mirrors: it draws minimal samples, asks a
solver for candidate models, scores them with a residual function and keeps the
best; a refit on the inliers and a final inlier pass close it. Scoring is MSAC
(Torr and Zisserman, "MLESAC", CVIU 2000): ``sum_i min(r_i^2, tau^2)``, which
ranks models better than a plain inlier count. The number of iterations adapts
to the inlier ratio (Fischler and Bolles 1981; Hartley and Zisserman sec. 4.7.1).
On many data the hypotheses are drawn and scored on a fixed random subset of
``max_scored`` of them (the inlier ratio, all that the score estimates, is known
to a fraction of a percent from tens of thousands: Chum and Matas's randomized
RANSAC pushes the same idea further); the final inlier pass and the refits use
every datum.

Deterministic: the same seed gives the same samples and the same answer.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Generic, Sequence, TypeVar

import numpy as np

Model = TypeVar("Model")


@dataclass(frozen=True)
class RansacOptions:
    """Options of :func:`ransac`.

    Attributes:
        threshold: inlier threshold on the residual (same unit as the residuals).
        confidence: probability of drawing at least one all-inlier sample.
        min_iterations: iterations always run (guards against a lucky early stop).
        max_iterations: hard cap on iterations.
        seed: seed of the ``numpy`` generator that draws the samples.
        max_scored: most data a hypothesis is drawn from and scored on (a random
            subset, the same for every hypothesis, when there are more).
    """

    threshold: float
    confidence: float = 0.9999
    min_iterations: int = 50
    max_iterations: int = 2000
    seed: int = 0
    max_scored: int = 20000


@dataclass
class RansacResult(Generic[Model]):
    """Outcome of :func:`ransac`.

    Attributes:
        model: the refitted best model.
        inliers: ``(N,)`` bool, residual below threshold under ``model``.
        iterations: samples drawn.
        residuals: ``(N,)`` residuals under ``model``.
    """

    model: Model
    inliers: np.ndarray
    iterations: int
    residuals: np.ndarray

    @property
    def inlier_ratio(self) -> float:
        """Fraction of data that are inliers."""
        return float(np.mean(self.inliers)) if self.inliers.size else 0.0


def required_iterations(inlier_ratio: float, sample_size: int, confidence: float) -> float:
    """Samples needed to draw one all-inlier sample with probability ``confidence``."""
    p_good = inlier_ratio ** sample_size
    if p_good <= 0.0:
        return np.inf
    if p_good >= 1.0:
        return 0.0
    return np.log(1.0 - confidence) / np.log(1.0 - p_good)


def ransac(num_data: int, sample_size: int,
           minimal_solver: Callable[[np.ndarray], Sequence[Model]],
           residuals: Callable[[Model, np.ndarray | None], np.ndarray],
           options: RansacOptions,
           refit: Callable[[np.ndarray, Model], Model] | None = None,
           progress: Callable[[int, int], None] | None = None) -> RansacResult[Model] | None:
    """Robustly fit a model.

    Args:
        num_data: number of data points ``N``.
        sample_size: points in a minimal sample.
        minimal_solver: ``(sample_size,)`` int indices -> candidate models
            (possibly none for a degenerate sample).
        residuals: ``(model, idx)`` -> non-negative residuals of the data ``idx``
            (``(len(idx),)``), or of every datum when ``idx`` is ``None`` (``(N,)``).
        options: threshold, confidence, iteration bounds and seed.
        refit: ``(inlier mask, best model) -> model``, e.g. least squares on the
            inliers; called twice (after sampling, after the inlier pass).
        progress: ``progress(iteration, planned)`` after every sample, where
            ``planned`` is the current adaptive estimate of the samples needed.

    Returns:
        The result, or ``None`` when no sample gave a model (degenerate data).
    """
    if num_data < sample_size:
        return None
    rng = np.random.default_rng(options.seed)
    scored = None
    if num_data > options.max_scored:
        scored = np.sort(rng.choice(num_data, size=options.max_scored, replace=False))
    pool = num_data if scored is None else len(scored)
    tau2 = options.threshold ** 2
    best_model, best_cost = None, np.inf
    needed = float(options.max_iterations)
    it = 0
    while it < options.max_iterations and (it < options.min_iterations or it < needed):
        it += 1
        sample = rng.choice(pool, size=sample_size, replace=False)
        if scored is not None:
            sample = scored[sample]
        for model in minimal_solver(sample):
            r = residuals(model, scored)
            cost = float(np.sum(np.minimum(r * r, tau2)))
            if cost < best_cost:
                best_model, best_cost = model, cost
                ratio = np.count_nonzero(r < options.threshold) / pool
                needed = required_iterations(ratio, sample_size, options.confidence)
        if progress is not None:
            progress(it, int(min(options.max_iterations, max(options.min_iterations, needed))))
    if best_model is None:
        return None
    model = best_model
    r = residuals(model, None)
    inliers = r < options.threshold
    if refit is not None:
        for _ in range(2):
            if np.count_nonzero(inliers) < sample_size:
                break
            model = refit(inliers, model)
            r = residuals(model, None)
            inliers = r < options.threshold
    return RansacResult(model=model, inliers=inliers, iterations=it, residuals=r)
