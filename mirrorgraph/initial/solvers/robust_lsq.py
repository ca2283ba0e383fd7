"""A small robust nonlinear least-squares solver in NumPy: the trust-region method of
SciPy's ``least_squares(method="trf", loss="cauchy", x_scale="jac")`` without bounds,
step for step, for the few parameters of :func:`.reflective.refine_epipole`.

Importing ``scipy.optimize`` costs a fresh ``mirrorgraph calibrate`` ~0.4 s of its
start (#25), for one 2-parameter fit. The refined epipole seeds the factor graph, and a
minimiser that stopped elsewhere (SciPy stops at a 1e-8 relative decrease of the cost,
not at the minimum) moves the calibration by ~1e-7: this solver therefore takes SciPy's
very steps, not merely its minimum, so that the results stay SciPy's to the last digits
(``tests/solvers/test_robust_lsq.py`` compares the two on random problems):

* the residuals ``f`` and forward-difference Jacobian ``J`` (step ``sqrt(eps) max(1,
  |x_i|)``) are rescaled for the Cauchy loss ``rho(s) = C^2 log(1 + s / C^2)`` as by
  Triggs et al. ("Bundle adjustment: a modern synthesis", 2000, sec. 4.3): the scaled
  problem's Gauss-Newton model has the loss's first and second derivatives;
* the variables are scaled by the Jacobian's column norms (never decreasing);
* each step solves the trust-region subproblem exactly from one SVD of the scaled
  Jacobian (Moré 1977: Newton's method on the Levenberg-Marquardt parameter, to 1 %
  of the radius, at most 10 iterations, warm-started from the last step's);
* the radius shrinks to a quarter of the step where the cost decreased by less than a
  quarter of the model's prediction, doubles where it decreased by more than three
  quarters with the step on the boundary; a step is taken where the cost decreased;
* it stops where the gradient's largest component is below ``gtol``, the cost decreased
  by less than ``ftol`` of itself (with a good model), the step is below
  ``xtol (xtol + |x|)``, or after ``max_nfev`` evaluations of the residuals.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.linalg import norm

__all__ = ["RobustFit", "robust_least_squares"]

EPS = np.finfo(float).eps

#: The SVD of the scaled Jacobian (NumPy's LAPACK; SciPy's differs in the last bits, and
#: so then the steps: the tests put SciPy's here and get SciPy's steps bit for bit).
_svd = np.linalg.svd


@dataclass(frozen=True)
class RobustFit:
    """What :func:`robust_least_squares` found.

    Attributes:
        x: the parameters; cost: ``sum_i rho(f_i^2) / 2`` there; nfev: evaluations of
        the residuals counted as SciPy counts them (not those of the Jacobian);
        status: SciPy's (0: ``max_nfev`` reached, 1: ``gtol``, 2: ``ftol``, 3:
        ``xtol``, 4: ``ftol`` and ``xtol``).
    """

    x: np.ndarray
    cost: float
    nfev: int
    status: int


def _cauchy(f: np.ndarray, c: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Cauchy loss of the residuals ``f`` at scale ``c``: ``rho`` and its first and
    second derivatives in ``s = f^2``."""
    z = (f / c) ** 2
    t = 1 + z
    return np.log1p(z) * c ** 2, 1 / t, -1 / t ** 2 / c ** 2


def _cauchy_cost(f: np.ndarray, c: float) -> float:
    return 0.5 * c ** 2 * np.sum(np.log1p((f / c) ** 2))


def _scale_for_loss(J: np.ndarray, f: np.ndarray, c: float):
    """The Jacobian and residuals of the scaled problem, and the cost."""
    rho0, rho1, rho2 = _cauchy(f, c)
    w = rho1 + 2 * rho2 * f ** 2
    w[w < EPS] = EPS
    w **= 0.5
    return J * w[:, None], f * (rho1 / w), 0.5 * np.sum(rho0)


def _jacobian(fun: Callable[[np.ndarray], np.ndarray], x: np.ndarray,
              f0: np.ndarray) -> np.ndarray:
    """Forward differences, SciPy's steps (``approx_derivative``, ``"2-point"``)."""
    sign = (x >= 0).astype(float) * 2 - 1
    h = EPS ** 0.5 * sign * np.maximum(1.0, np.abs(x))
    cols = []
    for i in range(x.size):
        x1 = np.copy(x)
        x1[i] = x[i] + h[i]
        cols.append((fun(x1) - f0) / ((x[i] + h[i]) - x[i]))
    return np.array(cols).T


def _trust_region_step(n: int, m: int, uf: np.ndarray, s: np.ndarray, V: np.ndarray,
                       radius: float, alpha: float) -> tuple[np.ndarray, float]:
    """``argmin |J p + f|`` with ``|p| <= radius`` from ``J = U diag(s) V^T``, and its
    Levenberg-Marquardt parameter (``(J^T J + alpha I) p = -J^T f``), Moré's way."""
    suf = s * uf

    def phi(a: float) -> tuple[float, float]:
        denom = s ** 2 + a
        p_norm = norm(suf / denom)
        return p_norm - radius, -np.sum(suf ** 2 / denom ** 3) / p_norm

    full_rank = m >= n and s[-1] > EPS * m * s[0]
    if full_rank:
        p = -V.dot(uf / s)
        if norm(p) <= radius:
            return p, 0.0
    upper = norm(suf) / radius
    lower = 0.0
    if full_rank:
        value, slope = phi(0.0)
        lower = -value / slope
    if not full_rank and alpha == 0:
        alpha = max(0.001 * upper, (lower * upper) ** 0.5)
    for _ in range(10):
        if alpha < lower or alpha > upper:
            alpha = max(0.001 * upper, (lower * upper) ** 0.5)
        value, slope = phi(alpha)
        if value < 0:
            upper = alpha
        ratio = value / slope
        lower = max(lower, alpha - ratio)
        alpha -= (value + radius) * ratio / radius
        if np.abs(value) < 0.01 * radius:
            break
    p = -V.dot(suf / (s ** 2 + alpha))
    p *= radius / norm(p)                # on the boundary (Newton stopped within 1 %)
    return p, alpha


def robust_least_squares(fun: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, *,
                         f_scale: float, max_nfev: int, ftol: float = 1e-8,
                         xtol: float = 1e-8, gtol: float = 1e-8) -> RobustFit:
    """Minimise ``sum_i rho(fun(x)_i^2) / 2``, ``rho`` the Cauchy loss of scale
    ``f_scale`` (``C^2 log(1 + s / C^2)``), from ``x0``: SciPy's
    ``least_squares(fun, x0, loss="cauchy", f_scale=f_scale, max_nfev=max_nfev,
    x_scale="jac")`` (see the module's description).

    Raises:
        ValueError: the residuals are not finite at ``x0``.
    """
    x = np.array(x0, dtype=float)
    f_true = np.asarray(fun(x), dtype=float)
    if not np.all(np.isfinite(f_true)):
        raise ValueError("Residuals are not finite in the initial point.")
    m, n = f_true.size, x.size
    nfev = 1
    J, f, cost = _scale_for_loss(_jacobian(fun, x, f_true), f_true, f_scale)
    g = J.T.dot(f)
    scale_inv = np.sum(J ** 2, axis=0) ** 0.5
    scale_inv[scale_inv == 0] = 1
    scale = 1 / scale_inv
    radius = norm(x * scale_inv)
    if radius == 0:
        radius = 1.0
    alpha = 0.0
    status = None
    while True:
        if norm(g, ord=np.inf) < gtol:
            status = 1
        if status is not None or nfev == max_nfev:
            break
        J_h = J * scale
        g_h = scale * g
        U, s, Vt = _svd(J_h, full_matrices=False)
        V = Vt.T
        uf = U.T.dot(f)
        reduction = -1.0
        while reduction <= 0 and nfev < max_nfev:
            step_h, alpha = _trust_region_step(n, m, uf, s, V, radius, alpha)
            Js = J_h.dot(step_h)
            predicted = -(0.5 * np.dot(Js, Js) + np.dot(step_h, g_h))
            step = scale * step_h
            x_new = x + step
            f_new = np.asarray(fun(x_new), dtype=float)
            nfev += 1
            step_h_norm = norm(step_h)
            if not np.all(np.isfinite(f_new)):
                radius = 0.25 * step_h_norm
                continue
            cost_new = _cauchy_cost(f_new, f_scale)
            reduction = cost - cost_new
            if predicted > 0:
                ratio = reduction / predicted
            elif predicted == reduction == 0:
                ratio = 1
            else:
                ratio = 0
            new_radius = radius
            if ratio < 0.25:
                new_radius = 0.25 * step_h_norm
            elif ratio > 0.75 and step_h_norm > 0.95 * radius:
                new_radius = radius * 2.0
            ftol_met = reduction < ftol * cost and ratio > 0.25
            xtol_met = norm(step) < xtol * (xtol + norm(x))
            status = (4 if ftol_met and xtol_met else 2 if ftol_met else 3 if xtol_met
                      else None)
            if status is not None:
                break
            alpha *= radius / new_radius
            radius = new_radius
        if reduction > 0:
            x, f_true, cost = x_new, f_new, cost_new
            J, f, _ = _scale_for_loss(_jacobian(fun, x, f_true), f_true.copy(), f_scale)
            g = J.T.dot(f)
            scale_inv = np.maximum(np.sum(J ** 2, axis=0) ** 0.5, scale_inv)
            scale = 1 / scale_inv
    return RobustFit(x=x, cost=float(cost), nfev=nfev, status=0 if status is None else status)
