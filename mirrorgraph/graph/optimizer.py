"""Levenberg-Marquardt driven from Python over GTSAM's linear algebra.

GTSAM's C++ optimisers hand every :class:`gtsam.CustomFactor` callback a copy of the whole
:class:`gtsam.Values` (measured: 97 s an iteration on 12,000 points, as ``docs/dependencies.md`` quotes); with the values owned by Python the callbacks see them by
reference, so the loop lives here. One iteration:

1. ``gfg = graph.linearize(values)``;
2. eliminate every local variable (the 3D points) with GTSAM's sequential Cholesky in a
   COLAMD ordering computed once, keeping ``p(points | globals)`` (a
   :class:`gtsam.GaussianBayesNet`) and the dense information ``(Lambda, eta)`` over the
   globals;
3. solve for the globals in reduced coordinates ``z``, ``delta_globals = T z``
   (:class:`GlobalReduction`, :mod:`.reduction`): the mirror link is an exact constraint;
4. back-substitute the points, retract, and project the values back onto the constraint.

Damping: Levenberg-Marquardt with Marquardt's scaling, ``lambda diag(H_z)`` on ``z`` and
``lambda s I`` on the points (``s`` a typical point information); ``lambda`` adapts to
the gain ratio. The stopping rules are those of :class:`LMParams`. An indeterminate point
block (GTSAM's ``IndeterminantLinearSystemException``) is a failed try: more damping, the
variable reported in :attr:`LMResult.indeterminate`. An optional ``guard`` keeps points
in front of their cameras (:func:`mirrorgraph.graph.problem.cheirality_guard`).

The reduced information ``T^T Lambda T`` of the last undamped solve is the exact Schur
complement of everything but ``z``: the marginal information of the plane and bone
lengths (:func:`reduced_marginals`).

Reference: Nocedal and Wright, *Numerical Optimization* (2006), ch. 10; the loop in
full: ``docs/internals.md``.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field
from typing import Callable

import gtsam
import numpy as np

from ..errors import DegenerateGeometryError

_log = logging.getLogger(__name__)

__all__ = ["LMParams", "LMResult", "GlobalReduction", "LevenbergMarquardt", "local_ordering",
           "reduced_covariance"]


@dataclass(frozen=True)
class LMParams:
    """Settings of :class:`LevenbergMarquardt`.

    Attributes:
        max_iterations: most linear solves.
        relative_tolerance: stop when ``(E_old - E_new) / E_old`` is below this, or
            when the step's actual decrease matches the quadratic model's prediction
            to within this fraction of ``E`` (the step landed on the model's
            minimum, so the next one would gain less than that).
        absolute_tolerance: or when ``E_old - E_new`` is below this.
        global_step_tolerance: or when the undamped step of the reduced global
            coordinates is shorter than this in their own metric,
            ``sqrt(z^T H_z z)`` (``H_z`` the reduced information: the step moved the
            mirror by less than this many of its standard deviations).
        lambda_start: smallest non-zero (relative) damping.
        lambda_factor: growth/shrink factor of ``lambda``.
        lambda_max: give up above this damping.
        local_scale: ``s``, absolute damping of the points per unit ``lambda``.
        backtrack: an undamped step that raises the error is halved up to this many
            times along its direction before the damping grows (0: no line search).
            Marquardt's damping ``lambda diag(H_z)`` shrinks a step most along the
            globals' weakest, most correlated directions: an estimated focal length
            with the plane and the bone lengths, where ``lambda = 1e-3`` cuts a step
            25 % of the focal length long that overshoots to 0.1 %, and the
            iterations crawl.
    """

    max_iterations: int = 20
    relative_tolerance: float = 1e-5
    absolute_tolerance: float = 1e-9
    global_step_tolerance: float = 0.05
    lambda_start: float = 1e-3
    lambda_factor: float = 10.0
    lambda_max: float = 1e8
    local_scale: float = 1.0
    backtrack: int = 0


@dataclass
class GlobalReduction:
    """How the global variables are solved.

    Attributes:
        graph_keys: ``(key, dim)`` of the global variables that appear in the
            graph; eliminated last, in this order.
        extra_keys: ``(key, dim)`` of global variables outside the graph (the
            planes), stacked after ``graph_keys`` in ``delta_globals``.
        z_keys: ``(key, dim)`` of the reduced coordinates (variables of ``z``).
        basis: ``basis(values)`` -> ``T`` of shape ``(sum dims graph+extra, sum dims z)``.
        extra_graph: factors on extra variables only (e.g. the distance gauge).
        project: ``project(values)``: restore the constraints in place after a retraction.
    """

    graph_keys: list[tuple[int, int]]
    extra_keys: list[tuple[int, int]]
    z_keys: list[tuple[int, int]]
    basis: Callable[[gtsam.Values], np.ndarray]
    extra_graph: gtsam.NonlinearFactorGraph = field(default_factory=gtsam.NonlinearFactorGraph)
    project: Callable[[gtsam.Values], None] | None = None


def local_ordering(graph: gtsam.NonlinearFactorGraph, global_keys: list[int]) -> gtsam.Ordering:
    """COLAMD ordering of the graph's keys except ``global_keys`` (computed with those last)."""
    present = set(graph.keyVector())
    last = [int(k) for k in global_keys if int(k) in present]
    colamd = (gtsam.Ordering.ColamdConstrainedLastNonlinearFactorGraph(graph, last) if last
              else gtsam.Ordering.ColamdNonlinearFactorGraph(graph))
    ordering = gtsam.Ordering()
    for i in range(colamd.size() - len(last)):
        ordering.push_back(colamd.at(i))
    return ordering


def _ordering(keys: list[tuple[int, int]]) -> gtsam.Ordering:
    o = gtsam.Ordering()
    for k, _ in keys:
        o.push_back(int(k))
    return o


def _split(vec: np.ndarray, keys: list[tuple[int, int]], out: gtsam.VectorValues) -> None:
    off = 0
    for k, dim in keys:
        out.insert(int(k), np.asarray(vec[off:off + dim], dtype=float))
        off += dim


def dense_system(gfg: gtsam.GaussianFactorGraph, keys: list[tuple[int, int]]
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Dense ``(Lambda, eta)`` of a linear graph over ``keys`` (``(key, dim)``), with zero
    blocks for keys the graph does not touch."""
    present = set(gfg.keyVector())
    n = sum(d for _, d in keys)
    H, g = np.zeros((n, n)), np.zeros(n)
    sub = [(k, d) for k, d in keys if k in present]
    if not sub:
        return H, g
    Hs, gs = gfg.hessian(_ordering(sub))
    offs = np.cumsum([0] + [d for _, d in keys])
    idx = np.concatenate([np.arange(offs[i], offs[i + 1])
                          for i, (k, _) in enumerate(keys) if k in present])
    H[np.ix_(idx, idx)] = Hs
    g[idx] = np.ravel(gs)
    return H, g


def reduced_covariance(information: np.ndarray, z_keys: list[tuple[int, int]]
                       ) -> dict[int, np.ndarray]:
    """Marginal covariance of every variable of a reduced Gaussian over ``z_keys``.

    The reduced information is the Schur complement of the points on the globals
    (what GTSAM's elimination leaves, :meth:`LevenbergMarquardt.linear_system`), so
    its inverse is the globals' joint marginal covariance. It is small (a plane and
    the bone lengths: 3 + B; a rig: 6 per camera, 3 per plane) and mixes a gauge of
    weight ~1e12 with directions a few frames determine, a condition number GTSAM's
    Cholesky calls indeterminate: it is inverted here with Jacobi scaling
    (``D^-1/2 H D^-1/2``, exact in exact arithmetic) and a symmetric eigensolver.

    Args:
        information: ``(n, n)`` symmetric reduced information.
        z_keys: ``(key, dim)`` of its blocks, in order (dims sum to ``n``).

    Returns:
        key -> ``(dim, dim)`` covariance block; all NaN when the information is not
        positive definite (a direction no observation fixes).
    """
    cov = reduced_covariance_matrix(information)
    out, off = {}, 0
    for key, dim in z_keys:
        out[int(key)] = cov[off:off + dim, off:off + dim].copy()
        off += dim
    return out


def reduced_covariance_matrix(information: np.ndarray) -> np.ndarray:
    """The ``(n, n)`` joint covariance of a reduced Gaussian, every cross term kept: the
    inverse of ``information`` with Jacobi scaling and a symmetric eigensolver
    (:func:`reduced_covariance`, which cuts it into blocks); all NaN when the
    information is not positive definite."""
    H = 0.5 * (np.asarray(information, dtype=float) + np.asarray(information, dtype=float).T)
    n = H.shape[0]
    diag = np.diag(H)
    cov = np.full((n, n), np.nan)
    if n and np.all(np.isfinite(H)) and np.all(diag > 0):
        s = 1.0 / np.sqrt(diag)
        w, V = np.linalg.eigh(H * s[:, None] * s[None, :])
        if w[0] > 1e-14 * w[-1]:
            cov = (V / w) @ V.T * s[:, None] * s[None, :]
    return cov


@dataclass
class LMResult:
    """What :meth:`LevenbergMarquardt.optimize` returns.

    Attributes:
        values: the solution.
        iterations: linear solves performed.
        initial_error, final_error: nonlinear error (0.5 sum of squared whitened,
            robustified residuals) before and after.
        converged: stopped on a tolerance (not on ``max_iterations`` / ``lambda_max``).
        reduced_information: ``T^T Lambda T`` of the last undamped solve (at its
            linearisation point), over :attr:`GlobalReduction.z_keys`; ``None`` if
            every solve was damped.
        reduced_gradient: ``T^T eta`` of that solve (``H_z z = g_z`` is the reduced
            Gauss-Newton step): what a chunk contributes to a shared global step.
        history: error after each accepted step.
        rejected_steps: tries that raised the error or met a singular block.
        indeterminate: local variables GTSAM found (nearly) undetermined at some
            linearisation (only damping made their block definite): the caller
            drops them and their observations.
        guarded: local variables held at their value by the guard (e.g. a point
            that a step would have taken behind a camera).
        sensitivity: ``(n_local, nz)`` the change of the last accepted step of the
            local variables of :attr:`LevenbergMarquardt.sensitivity_keys` (their
            tangent coordinates stacked in that order) per unit of the reduced globals
            ``z``: ``-H_xx^-1 H_xz T`` of that step's (damped) linearisation, so that
            with the globals held the solution at globals moved by ``z`` is, to first
            order, the solution plus ``sensitivity @ z``; ``None`` unless asked.
    """

    values: gtsam.Values
    iterations: int
    initial_error: float
    final_error: float
    converged: bool
    reduced_information: np.ndarray | None = None
    reduced_gradient: np.ndarray | None = None
    history: list[float] = field(default_factory=list)
    rejected_steps: int = 0
    indeterminate: set[int] = field(default_factory=set)
    guarded: int = 0
    sensitivity: np.ndarray | None = None


class LevenbergMarquardt:
    """Levenberg-Marquardt with local variables eliminated by GTSAM and reduced globals.

    Args:
        graph: the nonlinear factor graph (constraints not included).
        reduction: the global variables and their reduced coordinates.
        params: :class:`LMParams`.
        ordering: elimination ordering of the local variables; default
            :func:`local_ordering` (COLAMD, computed once).
        hold_globals: solve the local variables only (``z`` is not stepped, but its
            reduced system is still computed and returned).
        guard: ``guard(previous, candidate, delta) -> int | None``: after every
            retraction, restore in ``candidate`` the local variables that left their
            feasible set (e.g. a point behind a camera) to their ``previous`` value;
            returns how many, or ``None`` where no such repair makes the step feasible
            (a camera moved past a point): the step is then rejected as one whose
            error is not finite.
        refresh: ``refresh(values) -> graph``: after every accepted step, the graph to
            continue with, given the new values (e.g. with quantities the graph holds
            set to their optimum given ``values``, as the bone lengths are): its
            error at ``values`` must not exceed the old graph's.
        sensitivity_keys: local variables whose :attr:`LMResult.sensitivity` to the
            reduced globals is returned (``None``: not computed).
    """

    def __init__(self, graph: gtsam.NonlinearFactorGraph, reduction: GlobalReduction,
                 params: LMParams | None = None, ordering: gtsam.Ordering | None = None,
                 hold_globals: bool = False,
                 guard: Callable[[gtsam.Values, gtsam.Values], int] | None = None,
                 refresh: Callable[[gtsam.Values], gtsam.NonlinearFactorGraph] | None = None,
                 sensitivity_keys: list[int] | None = None) -> None:
        self.hold_globals = hold_globals
        self.sensitivity_keys = sensitivity_keys
        self._sensitivity: np.ndarray | None = None     # of the last step solved
        self.guard = guard
        self.refresh = refresh
        self.graph = graph
        self.reduction = reduction
        self.params = params or LMParams()
        self.ordering = ordering if ordering is not None else local_ordering(
            graph, [k for k, _ in reduction.graph_keys])
        self._global_ordering = _ordering(reduction.graph_keys)
        self._extra_ordering = _ordering(reduction.extra_keys)
        self._damping: dict[float, gtsam.GaussianFactorGraph] = {}
        self._dims: list[tuple[int, int]] | None = None

    # ----------------------------------------------------------------- pieces
    def error(self, values: gtsam.Values) -> float:
        """Nonlinear error of the graph and the extra factors."""
        e = float(self.graph.error(values))
        if self.reduction.extra_graph.size():
            e += float(self.reduction.extra_graph.error(values))
        return e

    def _damping_graph(self, values: gtsam.Values, lam: float) -> gtsam.GaussianFactorGraph:
        """``sqrt(lam s) I`` on every local variable (cached for the last ``lam``)."""
        if lam in self._damping:
            return self._damping[lam]
        if self._dims is None:
            zero = values.zeroVectors()
            self._dims = [(self.ordering.at(i), len(zero.at(self.ordering.at(i))))
                          for i in range(self.ordering.size())]
        g = gtsam.GaussianFactorGraph()
        s = float(np.sqrt(lam * self.params.local_scale))
        models: dict[int, gtsam.noiseModel.Base] = {}
        for k, dim in self._dims:
            if dim not in models:
                models[dim] = gtsam.noiseModel.Unit.Create(dim)
            g.push_back(gtsam.JacobianFactor(k, s * np.eye(dim), np.zeros(dim), models[dim]))
        self._damping = {lam: g}
        return g

    def linear_system(self, gfg: gtsam.GaussianFactorGraph, values: gtsam.Values, lam: float
                      ) -> tuple[gtsam.GaussianBayesNet, np.ndarray, np.ndarray, np.ndarray]:
        """Eliminate the locals of a linearised graph (damped by ``lam``); return the
        conditionals and the dense global system.

        Returns:
            ``bayes_net`` (points given globals), ``T``, ``Lambda`` and ``eta`` over
            ``graph_keys + extra_keys`` (``Lambda x = eta`` is the Gauss-Newton step).
        """
        red = self.reduction
        if lam > 0.0:
            damped = gtsam.GaussianFactorGraph()
            damped.push_back(gfg)
            damped.push_back(self._damping_graph(values, lam))
            gfg = damped
        bayes_net, remaining = gfg.eliminatePartialSequential(self.ordering)
        Lg, eg = remaining.hessian(self._global_ordering)
        if red.extra_keys:
            ne = sum(d for _, d in red.extra_keys)
            Le, ee = np.zeros((ne, ne)), np.zeros(ne)
            if red.extra_graph.size():
                Le, ee = dense_system(red.extra_graph.linearize(values), red.extra_keys)
            ng = Lg.shape[0]
            L = np.zeros((ng + ne, ng + ne))
            L[:ng, :ng], L[ng:, ng:] = Lg, Le
            eta = np.concatenate([np.ravel(eg), np.ravel(ee)])
        else:
            L, eta = Lg, np.ravel(eg)
        return bayes_net, red.basis(values), L, eta

    def step(self, gfg: gtsam.GaussianFactorGraph, values: gtsam.Values, lam: float
             ) -> tuple[gtsam.VectorValues, np.ndarray, np.ndarray, float]:
        """One (damped) Gauss-Newton step from a linearisation.

        Returns:
            the step, the reduced information ``T^T Lambda T`` (the points damped when
            ``lam > 0``) and gradient ``T^T eta``, and the step's length ``sqrt(z^T H_z z)``.
        """
        red = self.reduction
        bayes_net, T, L, eta = self.linear_system(gfg, values, lam)
        Hz = T.T @ L @ T
        gz = T.T @ eta
        if self.hold_globals or len(gz) == 0:
            z = np.zeros(len(gz))
        else:
            try:
                z = np.linalg.solve(Hz + lam * np.diag(np.diag(Hz)), gz)
            except np.linalg.LinAlgError:
                raise DegenerateGeometryError(
                    "the graph cannot be solved: " + _unconstrained(Hz, red.z_keys)) from None
        dg = T @ z
        given = gtsam.VectorValues()
        ng = sum(d for _, d in red.graph_keys)
        _split(dg[:ng], red.graph_keys, given)
        delta = bayes_net.optimize(given)
        if self.sensitivity_keys is not None:      # while the step's conditionals exist
            self._sensitivity = self.local_sensitivity(
                bayes_net, T, dg[:ng], np.asarray(delta.vector(self.sensitivity_keys), float),
                self.sensitivity_keys)
        for k, _ in red.graph_keys:
            if not delta.exists(int(k)):
                delta.insert(int(k), given.at(int(k)))
        if red.extra_keys:
            _split(dg[ng:], red.extra_keys, delta)
        return delta, Hz, gz, float(np.sqrt(max(z @ Hz @ z, 0.0)))

    def local_sensitivity(self, bayes_net: gtsam.GaussianBayesNet, T: np.ndarray,
                          given: np.ndarray, base: np.ndarray, keys: list[int]) -> np.ndarray:
        """``(n_local, nz)`` the change of the back-substituted local variables ``keys``
        per unit of ``z`` (:attr:`LMResult.sensitivity`): the conditionals
        ``p(locals | globals)`` of a step solved with the graph's globals at
        ``given + T e_i``, less ``base`` (the step's own, at ``given``): the
        back-substitution is affine in them."""
        red = self.reduction
        ng = len(given)
        out = np.zeros((len(base), T.shape[1]))
        for i in range(T.shape[1]):
            moved = gtsam.VectorValues()
            _split(given + T[:ng, i], red.graph_keys, moved)
            out[:, i] = np.asarray(bayes_net.optimize(moved).vector(keys), dtype=float) - base
        return out

    def reduced_system(self, values: gtsam.Values) -> tuple[np.ndarray, np.ndarray]:
        """The reduced information ``T^T Lambda T`` and gradient at ``values``.

        Undamped where GTSAM can; where a point's block is singular there (a point the
        last solve left nearly undetermined) the points alone are damped by the smallest
        ``lambda`` of ``1e-9, 1e-7, ...`` that lets the elimination through, which
        changes the globals' information by that relative amount. A point that no
        damping up to ``1e-3`` makes definite (its block nearly singular against its
        own scale, e.g. two rays nearly along one line) is held where it is by a
        strong prior of its own, so that it adds nothing but its factors' pull on the
        globals as a known point would (one point among thousands: what it over-counts
        is negligible), up to :data:`MAX_PINNED` points.

        Raises:
            DegenerateGeometryError: the globals' system itself is singular, or more than
                :data:`MAX_PINNED` points stay singular.
        """
        gfg = self.graph.linearize(values)
        lam = 0.0
        pinned: list[int] = []
        while True:
            try:
                _, Hz, gz, _ = self.step(gfg, values, lam)
                return Hz, gz
            except RuntimeError as exc:
                key = indeterminate_key(exc)
                if key is None:
                    raise
                lam = 1e-9 if lam == 0.0 else lam * 100.0
                if lam <= 1e-3:
                    continue
                if key in pinned or len(pinned) >= MAX_PINNED or not self._is_local(key):
                    raise DegenerateGeometryError(
                        "the solution's information could not be computed: "
                        + str(exc).splitlines()[1 if len(str(exc).splitlines()) > 1 else 0]
                        ) from None
                pinned.append(key)
                dim = len(values.zeroVectors().at(key))
                held = gtsam.GaussianFactorGraph()
                held.push_back(gfg)
                held.push_back(gtsam.JacobianFactor(key, 1e6 * np.eye(dim), np.zeros(dim),
                                                    gtsam.noiseModel.Unit.Create(dim)))
                gfg, lam = held, 0.0

    def _is_local(self, key: int) -> bool:
        """Whether ``key`` is one of the eliminated (local) variables."""
        return any(self.ordering.at(i) == key for i in range(self.ordering.size()))

    def predicted_decrease(self, gfg: gtsam.GaussianFactorGraph, delta: gtsam.VectorValues,
                           values: gtsam.Values) -> float:
        """Decrease of the (undamped) linearised model along ``delta``."""
        zero = gtsam.VectorValues.Zero(delta)
        pred = float(gfg.error(zero) - gfg.error(delta))
        extra = self.reduction.extra_graph
        if extra.size():
            lin = extra.linearize(values)
            pred += float(lin.error(zero) - lin.error(delta))
        return pred

    def _try(self, values: gtsam.Values, delta: gtsam.VectorValues
             ) -> tuple[gtsam.Values, float, int]:
        """The values a step leads to (constraints restored, guarded) and their error."""
        candidate = values.retract(delta)
        if self.reduction.project is not None:
            self.reduction.project(candidate)
        guarded = self.guard(values, candidate, delta) if self.guard is not None else 0
        if guarded is None:                       # infeasible: rejected unevaluated
            return candidate, float("inf"), 0
        return candidate, self.error(candidate), int(guarded)

    # ----------------------------------------------------------------- loop
    def optimize(self, values: gtsam.Values,
                 progress: Callable[[int, float], None] | None = None) -> LMResult:
        """Iterate from ``values`` (not modified).

        Args:
            values: initial values of every variable (graph and extra).
            progress: called as ``progress(iteration, error)`` after each accepted step
                (the error never rises from one call to the next).
        """
        p = self.params
        error = self.error(values)
        result = LMResult(values=values, iterations=0, initial_error=error, final_error=error,
                          converged=False)
        lam = 0.0
        gfg = self.graph.linearize(values)
        for it in range(1, p.max_iterations + 1):
            result.iterations = it
            try:
                delta, Hz, gz, zlen = self.step(gfg, values, lam)
            except RuntimeError as exc:
                # GTSAM's Cholesky met a (nearly) singular block: a point that one
                # view alone sees (the other downweighted by the kernel), or seen
                # along one line. As GTSAM's own LM does: a failed try, more damping
                # (which makes every point block definite). The variable is named.
                key = indeterminate_key(exc)
                if key is None:
                    raise
                result.indeterminate.add(key)
                result.rejected_steps += 1
                lam = max(lam * p.lambda_factor, p.lambda_start)
                if lam > p.lambda_max:
                    break
                continue
            if lam == 0.0:
                result.reduced_information, result.reduced_gradient = Hz, gz
            candidate, new_error, guarded = self._try(values, delta)
            decrease = error - new_error
            # an undamped step that overshoots: halve it along its own direction first
            # (``backtrack``). Damping shrinks a step most along the weakest directions
            # of the globals, where an estimated focal length lies, so that damped
            # steps there crawl; the Gauss-Newton direction is right, its length not.
            halvings = p.backtrack if lam == 0.0 else 0
            while not (np.isfinite(new_error) and decrease >= 0.0) and halvings > 0:
                halvings -= 1
                result.rejected_steps += 1
                delta, zlen = delta.scale(0.5), 0.5 * zlen
                candidate, new_error, guarded = self._try(values, delta)
                decrease = error - new_error
            if not (np.isfinite(new_error) and decrease >= 0.0):
                result.rejected_steps += 1
                lam = max(lam * p.lambda_factor, p.lambda_start)
                if lam > p.lambda_max:
                    break
                continue
            result.guarded += guarded
            accepted = self._sensitivity
            last = it == p.max_iterations
            # the last solve allowed: nothing is decided by the model's prediction any more
            predicted = None if last else self.predicted_decrease(gfg, delta, values)
            rho = 1.0 if predicted is None else (decrease / predicted if predicted > 0 else 0.0)
            _log.debug("solve %d: lambda %.3g, decrease %.4g (predicted %s, rho %.3f), "
                       "global step %.3g sigma", it, lam, decrease, predicted, rho, zlen)
            values, error = candidate, new_error
            if self.refresh is not None:
                self.graph = self.refresh(values)
                error = self.error(values)
            result.history.append(error)
            if progress is not None:
                progress(it, error)
            tol = p.relative_tolerance * (error + decrease)
            trusted = lam == 0.0 or rho > 0.75          # a heavily damped step proves nothing
            # the mirror (and any pose) moved by less than the tolerance in standard
            # deviations; a damped step is about 1 / (1 + lambda) of the undamped one
            # (Marquardt's scaling), so its undamped length is judged
            still = (not self.hold_globals and bool(self.reduction.z_keys)
                     and (lam == 0.0 or rho > 0.25)
                     and zlen * (1.0 + lam) <= p.global_step_tolerance)
            if decrease <= p.absolute_tolerance or (trusted and decrease <= tol) or still or (
                    lam == 0.0 and predicted is not None and abs(decrease - predicted) <= tol):
                result.converged = True
                break
            if rho > 0.75:
                lam = lam / p.lambda_factor if lam >= p.lambda_start * p.lambda_factor else 0.0
            elif rho < 0.25:
                lam = max(lam * p.lambda_factor, p.lambda_start)
            if not last:
                gfg = self.graph.linearize(values)
        result.values, result.final_error = values, error
        if self.sensitivity_keys is not None and result.history:
            result.sensitivity = accepted
        self._sensitivity = None
        return result


_KEY_IN_MESSAGE = re.compile(r"near variable\s+(\d+)")


#: Points :meth:`LevenbergMarquardt.reduced_system` may hold by a prior of their own where
#: no damping makes their block definite.
MAX_PINNED = 20


def indeterminate_key(exc: BaseException) -> int | None:
    """The variable named by GTSAM's ``IndeterminantLinearSystemException``, else ``None``.

    The Python bindings raise it as a :class:`RuntimeError` whose message reads
    "Indeterminate linear system detected while working near variable <key>".
    """
    m = _KEY_IN_MESSAGE.search(str(exc))
    if m is None or "ndetermin" not in str(exc):
        return None
    return int(m.group(1))


def _unconstrained(H: np.ndarray, z_keys: list[tuple[int, int]]) -> str:
    """Which global variables of a singular reduced system ``H`` no observation holds."""
    names, i = [], 0
    scale = max(float(np.max(np.abs(np.diag(H)))), 1e-300)
    for key, dim in z_keys:
        if np.all(np.abs(np.diag(H)[i:i + dim]) <= 1e-12 * scale):
            names.append(gtsam.DefaultKeyFormatter(int(key)))
        i += dim
    if names:
        return ("no observation constrains " + ", ".join(names)
                + " (a camera, mirror or bone length whose keypoints were all rejected)")
    return "its system is singular (the views do not fix the cameras and mirrors)"

