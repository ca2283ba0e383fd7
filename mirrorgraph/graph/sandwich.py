"""An uncertainty that follows the data's real error structure: a cluster-robust sandwich.

The marginals of the graph (:func:`~.optimizer.reduced_covariance`) are right for
independent Gaussian pixel noise. A real detector's error is neither: a joint's
error in one frame predicts the next (frame-to-frame correlated noise), and a
detector places some joints consistently off the anatomical joint (a per-joint
bias). Both leave the estimate's spread far above what the marginals say.

With each joint's Schur complement ``S_p`` and reduced score ``s_p`` on the globals
(:mod:`.scores`), the sandwich (Huber 1967; White 1980) ``Cov = H^-1 Omega H^-1`` with
``H = sum_p S_p`` and ``Omega`` the covariance of ``sum_p s_p`` holds whatever the
errors are, if ``Omega`` sees how the scores are correlated. Two correlations are modelled, as
two-way clustering does (Cameron, Gelbach and Miller, *J. Bus. Econ. Stat.* 2011):

* **over time**: the frames' scores ``s_t = sum_{p in t} s_p`` form a time series,
  whose long-run covariance is the heteroscedasticity- and autocorrelation-
  consistent estimate of Newey and West (1987) with the Bartlett kernel and
  Andrews' (1991) AR(1) plug-in bandwidth (``Omega_time``);
* **over joints**: all the frames of one left/right pair of joints are one cluster,
  ``G_c = sum_{t, j in c} s_tj`` (a per-joint bias is the same in every frame, and the
  detector's label ``left wrist`` is the person's left wrist in the direct view and
  the *right* one in the reflection: a label's bias reaches both joints of a pair),
  ``Omega_joint = C / (C - 1) sum_c G_c G_c^T``;

and ``Omega = Omega_time + Omega_joint - Omega_both``, ``Omega_both`` the time-series
estimate within each joint summed over joints (counted in both), its negative
eigenvalues clipped. Under independent noise all three are the same matrix and the
sandwich is the marginal covariance again (up to its own sampling noise).

What it cannot see: a bias shared by every joint of a view (all keypoints offset
the same way) looks like a change of the geometry; and with a dozen joints the
joint clusters' estimate has a dozen degrees of freedom (±30 % on a std).

The same scores give the sensitivity report: how the estimate moves when one
joint, or one segment of frames, is left out (the linearised jackknife,
``dtheta_c = -(H - H_c)^-1 G_c``), and the information each segment carries
(:mod:`.sensitivity`).
"""

from __future__ import annotations

import gtsam
import numpy as np

from .scores import JointScores

__all__ = ["sandwich", "two_way_meat", "long_run_covariance", "andrews_bandwidth",
           "jackknife_cov", "leave_one_out", "gauge_inverse", "held_intrinsics_cov",
           "covariance_max", "sandwich_candidates", "SEGMENT_BANDWIDTHS", "SEGMENTS_RANGE"]


def andrews_bandwidth(series: np.ndarray) -> float:
    """Andrews' (1991) AR(1) plug-in bandwidth of the Bartlett kernel for ``(T, n)`` series.

    Each component's AR(1) coefficient ``rho`` and innovation variance ``v`` give
    ``alpha = sum 4 rho^2 v^2 / ((1 - rho)^6 (1 + rho)^2) / sum v^2 / (1 - rho)^4``
    and the bandwidth ``1.1447 (alpha T)^(1/3)`` (lags).
    """
    x = np.asarray(series, dtype=float)
    T = len(x)
    if T < 3:
        return 0.0
    num = den = 0.0
    for c in x.T:
        c = c - c.mean()
        d = float(np.dot(c[:-1], c[:-1]))
        if d <= 0:
            continue
        rho = float(np.clip(np.dot(c[1:], c[:-1]) / d, -0.97, 0.97))
        v = float(np.mean((c[1:] - rho * c[:-1]) ** 2))
        num += 4 * rho ** 2 * v ** 2 / ((1 - rho) ** 6 * (1 + rho) ** 2)
        den += v ** 2 / (1 - rho) ** 4
    if den <= 0:
        return 0.0
    return float(min(1.1447 * (num / den * T) ** (1.0 / 3.0), T - 1))


def long_run_covariance(series: np.ndarray, bandwidth: float | None = None) -> np.ndarray:
    """Newey-West (1987) long-run covariance of the sum of a ``(T, n)`` series of scores.

    ``sum_k w_k (Gamma_k + Gamma_k^T)`` over lags ``|k| <= m`` with Bartlett weights
    ``w_k = 1 - k / (m + 1)`` and ``Gamma_k = sum_t x_t x_{t-k}^T`` (the scores are
    taken to have mean zero: at the solution they sum to zero); ``m``: the given
    bandwidth or :func:`andrews_bandwidth`.

    Returns:
        ``(n, n)`` covariance of ``sum_t x_t``.
    """
    x = np.asarray(series, dtype=float)
    m = andrews_bandwidth(x) if bandwidth is None else float(bandwidth)
    out = x.T @ x
    for k in range(1, int(np.floor(m)) + 1):
        w = 1.0 - k / (m + 1.0)
        G = x[k:].T @ x[:-k]
        out += w * (G + G.T)
    return out


def two_way_meat(scores: JointScores) -> dict[str, np.ndarray]:
    """``Omega`` of the module docstring and its parts (``(n, n)`` each).

    Returns:
        ``{"time", "joint", "both", "total"}``; ``total`` has no negative eigenvalue.
    """
    T, n = scores.frame_info.shape[0], scores.scores.shape[1]
    per_frame = np.zeros((T, n))
    np.add.at(per_frame, scores.frames, scores.scores)
    m = andrews_bandwidth(per_frame)
    time_part = long_run_covariance(per_frame, m)
    if not scores.joint_clusters:          # the bones couple a frame's joints: time alone
        nan = np.full((n, n), np.nan)
        return {"time": time_part, "joint": nan, "both": nan, "total": time_part,
                "bandwidth": np.array(m)}
    clusters = np.unique(scores.clusters)
    G = np.array([scores.scores[scores.clusters == c].sum(0) for c in clusters])
    C = len(clusters)
    joint_part = (C / max(C - 1, 1)) * (G.T @ G)
    both = np.zeros((n, n))
    for c in clusters:
        series = np.zeros((T, n))
        sel = scores.clusters == c
        np.add.at(series, scores.frames[sel], scores.scores[sel])
        both += long_run_covariance(series, m)
    total = time_part + joint_part - both
    w, V = np.linalg.eigh(0.5 * (total + total.T))
    total = (V * np.maximum(w, 0.0)) @ V.T
    return {"time": time_part, "joint": joint_part, "both": both, "total": total,
            "bandwidth": np.array(m)}


def gauge_inverse(H: np.ndarray, gauge: np.ndarray | None) -> np.ndarray:
    """Inverse of a symmetric ``H`` on the complement of its gauge directions.

    ``Q (Q^T H Q)^-1 Q^T`` with ``Q`` an orthonormal basis of the directions orthogonal
    to ``gauge`` (``(n,)`` or ``(n, k)``; ``None``: no gauge): the covariance in which
    the gauge does not move. Quantities the gauge leaves unchanged (a normal, a
    rotation) get their covariance whatever gauge is chosen. Where ``Q^T H Q`` is
    singular (a direction nothing observes) its pseudo-inverse.
    """
    n = H.shape[0]
    if gauge is None or np.size(gauge) == 0 or not np.any(gauge):
        Q = np.eye(n)
    else:
        G = np.asarray(gauge, dtype=float).reshape(n, -1)
        U, _, _ = np.linalg.svd(G, full_matrices=True)
        Q = U[:, G.shape[1]:]
    M = Q.T @ H @ Q
    M = 0.5 * (M + M.T)
    try:
        return Q @ np.linalg.inv(M) @ Q.T
    except np.linalg.LinAlgError:
        # a direction no observation holds (a leave-one-out that removed every frame of
        # a bone): the least-norm inverse, which does not move it and moves the rest as
        # the remaining observations determine them
        return Q @ np.linalg.pinv(M, hermitian=True) @ Q.T


def leave_one_out(scores: JointScores, kind: str, segments: int | None = None
                  ) -> tuple[list, np.ndarray, np.ndarray]:
    """How the estimate moves when one cluster of observations is left out, linearised.

    Without cluster ``c`` the Gauss-Newton step from the solution is ``delta_c =
    -(H - H_c)^-1 G_c`` (``G_c``, ``H_c``: the cluster's summed reduced scores and
    Schur complements; at the solution the scores sum to zero, so the other clusters'
    pull is ``-G_c``).

    Args:
        scores: :func:`~.scores.joint_scores`.
        kind: ``"joint"``: the left/right pairs of joints; ``"time"``: ``segments``
            contiguous runs of frame rows of equal length.
        segments: number of time segments (``kind="time"``).

    Returns:
        the clusters (a pair's joint indices, or a segment's ``(start, stop)`` rows),
        ``(C, n)`` the moves (reduced coordinates, gauge-fixed as
        :func:`gauge_inverse`) and ``(C, n, n)`` each cluster's information ``H_c``.
    """
    H = scores.information
    n = H.shape[1]
    if kind == "joint":
        labels = scores.clusters
        ids = np.unique(labels)
        members = [sorted(set(scores.joints[labels == c].tolist())) for c in ids]
        Hc = [sum(scores.joint_info[j] for j in m) for m in members]
    else:
        T = scores.frame_info.shape[0]
        edges = np.linspace(0, T, int(segments) + 1).round().astype(int)
        labels = np.searchsorted(edges, scores.frames, side="right") - 1
        ids = np.arange(len(edges) - 1)
        members = [(int(edges[c]), int(edges[c + 1])) for c in ids]
        Hc = [scores.frame_info[edges[c]:edges[c + 1]].sum(0) for c in ids]
    deltas = np.array([-gauge_inverse(H - Hcc, scores.gauge) @ scores.scores[labels == c].sum(0)
                       for c, Hcc in zip(ids, Hc)]).reshape(len(ids), n)
    return members, deltas, np.array(Hc).reshape(len(ids), n, n)


def jackknife_cov(scores: JointScores, kind: str, segments: int | None = None) -> np.ndarray:
    """Delete-one-cluster jackknife covariance of the reduced coordinates, linearised.

    ``Cov = (C - 1) / C sum_c (delta_c - mean)(delta_c - mean)^T`` over the moves of
    :func:`leave_one_out` (Efron and Stein 1981; the CR3 estimator of the clustered
    regression literature, MacKinnon and White 1985). Unlike ``H^-1 (sum_c G_c
    G_c^T) H^-1`` it does not shrink where a cluster pulled the estimate towards
    itself (each ``G_c`` is a residual score at an estimate the cluster helped make),
    which with a handful of clusters is most of the difference.

    Returns:
        ``(n, n)`` covariance (whitened units, gauge-fixed as :func:`gauge_inverse`).
    """
    _, D, _ = leave_one_out(scores, kind, segments)
    C, n = D.shape
    if C < 2:
        return np.full((n, n), np.nan)
    D = D - D.mean(0)
    return (C - 1) / C * (D.T @ D)


#: Time segments of the jackknife: about this many bandwidths of the score series
#: long (so that neighbouring segments are nearly independent), within
#: :data:`SEGMENTS_RANGE`.
SEGMENT_BANDWIDTHS = 3.0


SEGMENTS_RANGE = (5, 20)


def sandwich(scores: JointScores) -> dict[str, np.ndarray]:
    """The cluster-robust covariance of the reduced coordinates and its parts.

    Args:
        scores: :func:`~.scores.joint_scores` (with its scale gauge).

    Returns:
        ``{"cov", "cov_time", "cov_joint", "marginal", "bread", "meat", ...}``:
        ``(n, n)`` covariances in whitened units (the scores carry the data's own
        noise level: no variance factor is needed); ``marginal`` is ``H^-1``, the
        iid figure of the same rows for comparison.
    """
    H = scores.information
    bread = gauge_inverse(H, scores.gauge)
    meat = two_way_meat(scores)
    out = {"bread": bread, "marginal": bread, "meat": meat["total"],
           "bandwidth": float(meat["bandwidth"])}
    for name in ("total", "time", "joint"):
        out["cov" if name == "total" else f"cov_{name}"] = bread @ meat[name] @ bread
    T = scores.frame_info.shape[0]
    K = int(np.clip(T / max(SEGMENT_BANDWIDTHS * max(out["bandwidth"], 1.0), 1.0),
                    *SEGMENTS_RANGE))
    out["segments"] = K
    out["cov_jack_time"] = jackknife_cov(scores, "time", K)
    out["cov_jack_joint"] = (jackknife_cov(scores, "joint") if scores.joint_clusters
                             else np.full_like(out["cov_jack_time"], np.nan))
    if scores.prior_spread is not None:
        _with_unknown_intrinsics(out, scores, H, meat)
    if scores.bias_score is not None:
        # the bones' curvature bias (rays meeting at small angles): the mean square error
        delta = bread @ np.asarray(scores.bias_score, dtype=float)
        out["bias"] = delta
        for name in ("cov", "cov_time", "cov_joint", "cov_jack_time", "cov_jack_joint"):
            out[name] = out[name] + np.outer(delta, delta)
    if scores.added_cov is not None:
        for name in ("cov", "cov_time", "cov_joint", "cov_jack_time", "cov_jack_joint"):
            out[name] = out[name] + np.asarray(scores.added_cov, dtype=float)
    return out


def _with_unknown_intrinsics(out: dict, scores: JointScores, H: np.ndarray, meat: dict) -> None:
    """The sandwich's figures where intrinsics with a prior about a guess are estimated
    (:attr:`~.scores.JointScores.prior_spread`), in place.

    With ``k`` the intrinsics' coordinates and ``a`` the rest, the estimate moves as
    ``delta a = H_aa^-1 s_a + G delta k``, ``G = -H_aa^-1 H_ak``: the first term is the
    sandwich with the intrinsics held (``H_aa^-1 Omega_aa H_aa^-1``, the figure of a
    known camera), the second carries the intrinsics' own error (Gaussian conditioning;
    the two are uncorrelated where the scores' covariance is their information). The
    intrinsics' covariance ``C_k`` is each figure's own ``k`` block, at least the
    marginal (``H^-1``, which holds the prior) and at most the prior's spread in each
    coordinate: where the data hardly hold them (no bones, rays meeting at a few
    degrees) the scores' ``k`` part is numerically meaningless (it gave a focal std of
    5e7 px), and the truth's spread about the guess is the prior's (about the estimate:
    the prior's plus the estimate's squared distance from the guess,
    :attr:`~.scores.JointScores.prior_cap`). So the reported
    figures hold the unknown intrinsics whether or not the data determine them.
    """
    P = np.asarray(scores.prior_spread, dtype=float)
    d = np.diag(P)
    k = np.flatnonzero(d > 0)
    a = np.flatnonzero(d <= 0)
    if not len(k):
        return
    gauge = None if scores.gauge is None else np.asarray(scores.gauge, float)[a]
    bread = out["bread"]
    bread_a = gauge_inverse(H[np.ix_(a, a)], gauge)
    G = -bread_a @ H[np.ix_(a, k)]
    prior_sd = 1.0 / np.sqrt(d[k])
    if scores.prior_cap is not None:       # the prior's spread about the estimate, not the guess
        prior_sd = np.sqrt(np.maximum(prior_sd ** 2, np.asarray(scores.prior_cap, float)[k]))
    marg_k = bread[np.ix_(k, k)]
    if scores.prior_floor is not None:
        # an intrinsic the data do not determine: its variance at least the floor
        # (the prior's, or the disagreement of two estimates), at most the cap
        floor = np.minimum(np.asarray(scores.prior_floor, float)[k], prior_sd ** 2)
        sd = np.sqrt(np.maximum(np.diag(marg_k), 1e-300))
        up = np.maximum(np.sqrt(floor) / sd, 1.0)
        marg_k = marg_k * np.outer(up, up)

    def assemble(C_a: np.ndarray, C_k: np.ndarray) -> np.ndarray:
        n = H.shape[0]
        if not (np.all(np.isfinite(C_a)) and np.all(np.isfinite(C_k))):
            return np.full((n, n), np.nan)             # a figure that does not apply
        C_k = 0.5 * (C_k + C_k.T)
        sd = np.sqrt(np.maximum(np.diag(C_k), 0.0))
        shrink = np.where(sd > prior_sd, prior_sd / np.maximum(sd, 1e-300), 1.0)
        C_k = covariance_max(marg_k, C_k * np.outer(shrink, shrink))
        C = np.zeros((n, n))
        C[np.ix_(a, a)] = C_a + G @ C_k @ G.T
        C[np.ix_(a, k)] = G @ C_k
        C[np.ix_(k, a)] = (G @ C_k).T
        C[np.ix_(k, k)] = C_k
        return C

    for name, part in (("cov", "total"), ("cov_time", "time"), ("cov_joint", "joint")):
        M = meat[part]
        out[name] = assemble(bread_a @ M[np.ix_(a, a)] @ bread_a, out[name][np.ix_(k, k)])
    for name in ("cov_jack_time", "cov_jack_joint"):
        C = out[name]
        if not np.all(np.isfinite(C)):
            continue
        Ckk = C[np.ix_(k, k)]
        Cak = C[np.ix_(a, k)]
        cond = C[np.ix_(a, a)] - Cak @ np.linalg.pinv(Ckk) @ Cak.T
        out[name] = assemble(cond, Ckk)


def held_intrinsics_cov(scores: JointScores, block: slice = slice(0, 3)) -> np.ndarray:
    """``(b, b)`` what the estimated intrinsics of ``scores`` (a subset's solve) bring to
    the covariance of the coordinates ``block`` (a plane's three) once they are held:
    ``C_ak C_kk^+ C_ka`` (Gaussian conditioning) of the figure of :func:`sandwich` with
    the largest trace there (the marginal ``H^-1`` among them); zeros without intrinsics."""
    sw = sandwich(scores)
    k = []
    off = 0
    for key, dim in scores.z_keys:
        if gtsam.Symbol(key).chr() == ord("k"):
            k.extend(range(off, off + dim))
        off += dim
    a = np.arange(off)[block]
    if not k:
        return np.zeros((len(a), len(a)))
    best, best_tr = None, -1.0
    for C in [sw["bread"], *sandwich_candidates(sw).values()]:
        if np.all(np.isfinite(C)) and np.trace(C[np.ix_(a, a)]) > best_tr:
            best, best_tr = C, float(np.trace(C[np.ix_(a, a)]))
    k = np.asarray(k)
    Cak = best[np.ix_(a, k)]
    return Cak @ np.linalg.pinv(best[np.ix_(k, k)]) @ Cak.T


def covariance_max(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """The covariance that is at least ``A`` and at least ``B`` in every direction.

    In the basis where ``A`` is the identity (``A = L L^T``) ``B`` is ``M = L^-1 B L^-T``;
    its eigenvalues below 1 are raised to 1 and the result is mapped back: ``L V
    max(Lambda, 1) V^T L^T``. Singular ``A`` (a unit normal's covariance has rank 2)
    is handled on its range.
    """
    A = 0.5 * (np.asarray(A, float) + np.asarray(A, float).T)
    B = 0.5 * (np.asarray(B, float) + np.asarray(B, float).T)
    w, U = np.linalg.eigh(A)
    keep = w > 1e-12 * max(w.max(), 1e-300)
    L = U[:, keep] * np.sqrt(w[keep])                      # A = L L^T on its range
    Linv = np.linalg.pinv(L)
    M = Linv @ B @ Linv.T
    lam, V = np.linalg.eigh(0.5 * (M + M.T))
    out = L @ (V * np.maximum(lam, 1.0)) @ V.T @ L.T
    return 0.5 * (out + out.T)


def sandwich_candidates(sw: dict) -> dict[str, np.ndarray]:
    """The sandwich's full covariances by name (:data:`~.uncertainty.ROBUST_PARTS` but
    the marginals)."""
    return {"time": sw["cov_time"], "joint": sw["cov_joint"], "two_way": sw["cov"],
            "jack_time": sw["cov_jack_time"], "jack_joint": sw["cov_jack_joint"]}
