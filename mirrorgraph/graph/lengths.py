"""The bone lengths of the graph: held during a linearisation, set between linearisations.

The bone factors (:class:`mirrorgraph.factors.BoneLengthFactor`) are GTSAM's
range factors with the bone's length as their measurement, so the lengths ``L``
are not variables of the linear systems. After every accepted step they are set
to their optimum given the joints:

    min_L  sum_{t,k} (|X_a^t - X_b^t| - L_k)^2 / sigma^2  +  length-only priors  +  gauge,

the first term being ``sum_k n_k (m_k - L_k)^2 / sigma^2`` up to a constant (``m_k``
the mean length of bone ``k`` over its ``n_k`` frames). The length-only priors
(symmetry, anthropometry) and the gauge (the lengths' sum) are the problem's
:attr:`~.problem.GraphProblem.length_priors` and :attr:`~.problem.GraphProblem.gauge`
on the vector :data:`~.problem.LENGTH_KEY`; a few Gauss-Newton steps on that
``B``-dimensional problem solve it (the anthropometric ratios are mildly
nonlinear). The alternation of a Gauss-Newton step on the joints and planes with
this exact step on the lengths has the joint optimum as its fixed point.
"""

from __future__ import annotations

import gtsam
import numpy as np

from .problem import GraphProblem, LENGTH_KEY, points_array

__all__ = ["update_lengths", "LENGTH_STEPS"]

#: Gauss-Newton steps of the length problem per update (started at the held lengths,
#: which are already close: the anthropometric ratios are the only nonlinearity).
LENGTH_STEPS = 2


def update_lengths(problem: GraphProblem, values: gtsam.Values
                   ) -> tuple[np.ndarray, np.ndarray]:
    """``(B,)`` the bone lengths that minimise the objective given the joints of ``values``.

    Args:
        problem: a graph with bone factors (``problem.lengths`` not ``None``).
        values: the current joints.

    Returns:
        The new lengths, ``problem.bone_names`` order (graph units), and each one's
        standard deviation from its frames alone, ``sigma / sqrt(n_k)``.
    """
    X = points_array(problem, values)
    a, b, k = problem.bone_rows.T
    ell = np.linalg.norm(X[a] - X[b], axis=1)
    B = len(problem.bone_names)
    n = np.bincount(k, minlength=B).astype(float)
    mean = np.bincount(k, weights=ell, minlength=B) / np.maximum(n, 1.0)
    w = n / problem.bone_sigma ** 2                        # information of each mean
    L = np.asarray(problem.lengths, dtype=float).copy()
    graph = gtsam.NonlinearFactorGraph(problem.length_priors)
    graph.push_back(problem.gauge)
    ordering = gtsam.Ordering()
    ordering.push_back(LENGTH_KEY)
    for _ in range(LENGTH_STEPS):
        H, eta = np.diag(w), w * (mean - L)
        if graph.size():
            v = gtsam.Values()
            v.insert(LENGTH_KEY, L)
            Hg, eg = graph.linearize(v).hessian(ordering)
            H, eta = H + Hg, eta + np.ravel(eg)
        try:
            L = L + np.linalg.solve(H, eta)
        except np.linalg.LinAlgError:         # a bone in no frame and no prior: keep it
            L = L + np.linalg.lstsq(H, eta, rcond=None)[0]
    return L, problem.bone_sigma / np.sqrt(np.maximum(n, 1.0))
