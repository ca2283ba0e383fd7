"""One frame's joints refined with the body's bone lengths: the live run's per-frame prior.

The per-frame path of :class:`~mirrorgraph.live.calibrator.LiveCalibrator` triangulates
each joint from its two rays alone (the camera and its reflection). The offline graph
holds every bone at one length over the video (:mod:`mirrorgraph.factors.bone_length`);
the live run has those lengths from its latest window's solve, and refines each frame's
joints with them at a fixed cost: a few Gauss-Newton steps on

    sum_j rho(|pi(K X_j) - u_j|^2 / s^2) + rho(|pi(K S(X_j)) - u'_j|^2 / s^2)
      + sum_b (|X_a - X_b| - L_b)^2 / s_L^2

over the frame's joints ``X`` (``S`` the reflection in the mirror plane, ``s`` the
reprojection noise, ``s_L`` each bone's spread, ``rho`` Huber's loss at 1.345 standard
deviations on the pixels: Huber, *Robust Statistics*, 1981; Hartley and Zisserman,
*Multiple View Geometry*, 2nd ed., sec. A6.8). The bones are Gaussian, as the offline
graph's factor: a joint the detector misplaced along its epipolar line (which the
reprojection threshold cannot see) is held by its bones. A "bone" here is any pair of
joints held at a distance: the offline joints pass's torso distances
(:mod:`mirrorgraph.factors.torso`, the shoulders tied to the hips) are more such pairs.
The normal equations (``3k x 3k``, ``k`` <= 33 joints) are the per-joint ``3 x 3``
blocks of the two views' ``2 x 3`` projection Jacobians plus the bones' ``1 x 3`` length
Jacobians, ``B`` rows in all; they are solved through the ``B x B`` system of the
Woodbury identity where every joint keeps both views (densely otherwise), vectorised; the
joints' covariance is the diagonal blocks of their inverse (the Laplace approximation, at
the final weights).
"""

from __future__ import annotations

import numpy as np

from ..graph.outliers import one_view_outliers

__all__ = ["refine_with_bones", "refine_starts", "triangulate_two_rays", "with_head_prior", "head_layout",
           "view_residuals", "bias_covariance", "bone_branches", "two_starts", "HUBER_K",
           "views_near_track", "VIEW_GATE_CHI2"]

#: Huber's threshold in standard deviations (95 % efficiency under Gaussian noise).
HUBER_K = 1.345

#: A joint's view whose pixel is beyond this squared Mahalanobis distance from its
#: track's predicted projection is one keypoint misplaced: chi-square with 2 degrees of
#: freedom at 0.9999 (the tracks' own gate's level, :data:`.joint_filter.GATE_CHI2`).
VIEW_GATE_CHI2 = 18.4


def triangulate_two_rays(K: np.ndarray, normal: np.ndarray, distance: float, u: np.ndarray,
                         um: np.ndarray) -> np.ndarray:
    """Joints from their direct and mirrored pixels: the midpoint of the two rays.

    The direct ray leaves the camera centre along ``K^-1 [u, 1]``, the mirrored one the
    virtual camera's centre ``2 d n`` along ``H K^-1 [u', 1]`` (``H = I - 2 n n^T``);
    the point is the midpoint of their common perpendicular (Hartley and Zisserman,
    *Multiple View Geometry*, 2nd ed., sec. 12.1), closed form, vectorised. It is the
    starting point of :func:`refine_with_bones`, whose Gauss-Newton steps take it to the
    reprojection optimum.

    Args:
        K: ``(3, 3)`` camera matrix, px; normal, distance: the plane ``n . X = d``.
        u, um: ``(k, 2)`` undistorted pixels in the camera and in the mirror.

    Returns:
        ``(k, 3)`` points, camera frame, the unit of ``d``; NaN where the rays are
        parallel.
    """
    n = np.asarray(normal, float)
    Kinv = np.linalg.inv(K)
    H = np.eye(3) - 2.0 * np.outer(n, n)
    r1 = u @ Kinv[:, :2].T + Kinv[:, 2]                                   # (k, 3)
    HK = H @ Kinv
    r2 = um @ HK[:, :2].T + HK[:, 2]
    c2 = 2.0 * float(distance) * n
    a, b, c = (r1 * r1).sum(1), (r1 * r2).sum(1), (r2 * r2).sum(1)
    e, f = r1 @ c2, r2 @ c2
    den = a * c - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (e * c - b * f) / den                   # along the direct ray
        t = (b * e - a * f) / den                   # along the mirrored one
        X = 0.5 * (s[:, None] * r1 + c2 + t[:, None] * r2)
    X[~(np.abs(den) > 1e-12 * a * c)] = np.nan
    return X


def view_residuals(K: np.ndarray, normal: np.ndarray, distance: float, X: np.ndarray,
                   u: np.ndarray, um: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each joint's reprojection residual and projection Jacobian in both views.

    Args:
        K: ``(3, 3)`` camera matrix, px; normal, distance: the plane ``n . X = d``.
        X: ``(k, 3)`` joints (camera frame); u, um: ``(k, 2)`` their pixels in the
            camera and in the mirror, undistorted.

    Returns:
        ``(r, J)``: ``(k, 2, 2)`` residuals ``pi(P X) - u``, px (view: camera, mirror;
        x, y) and ``(k, 2, 2, 3)`` their Jacobians in ``X``, px per unit of ``X``.
    """
    n = np.asarray(normal, float)
    H = np.eye(3) - 2.0 * np.outer(n, n)
    P = np.stack([K, K @ H])                                              # (2, 3, 3)
    q = np.einsum("vij,kj->kvi", P, X)
    q[:, 1] += K @ (2.0 * float(distance) * n)
    z = q[:, :, 2:3]
    p = q[:, :, :2] / z
    J = (P[None, :, :2, :] - p[..., None] * P[None, :, 2:3, :]) / z[..., None]
    return p - np.stack([u, um], 1), J


def _residuals(K: np.ndarray, normal: np.ndarray, distance: float, X: np.ndarray,
               u: np.ndarray, um: np.ndarray) -> np.ndarray:
    """``(k, 2, 2)`` :func:`view_residuals`' residuals alone (no Jacobians)."""
    n = np.asarray(normal, float)
    KH = K - 2.0 * np.outer(K @ n, n)                                     # K H
    q = np.empty((len(X), 2, 3))
    q[:, 0] = X @ K.T
    q[:, 1] = X @ KH.T + K @ (2.0 * float(distance) * n)
    return q[:, :, :2] / q[:, :, 2:3] - np.stack([u, um], 1)


def views_near_track(K: np.ndarray, normal: np.ndarray, distance: float, Xp: np.ndarray,
                     Pp: np.ndarray, u: np.ndarray, um: np.ndarray, sigma_px: float,
                     chi2: float = VIEW_GATE_CHI2) -> np.ndarray:
    """The views of a frame's joints near where their tracks predict them.

    Each view's pixel is tested against the prediction's projection: its squared
    Mahalanobis distance on ``J P J^T + s^2 I`` (``J`` the view's ``2 x 3`` projection
    Jacobian at the prediction, ``P`` its covariance, ``s`` the reprojection noise;
    the innovation of that view alone, Bar-Shalom, Li and Kirubarajan, 2001, sec. 5.2)
    beyond ``chi2`` leaves the view out. One keypoint misplaced in one view moves the
    two rays' point along the other's ray, where the bones may not see it; the offline
    joints pass finds it by its residual once the smoothness holds the joint
    (:func:`mirrorgraph.graph.stages.joints_pass`), the track does here. A joint far
    off in both views keeps both (the tracks' own gate judges its point: an outlier,
    or the person moved unlike the prior), as does one without a prediction.

    Args:
        K: ``(3, 3)`` camera matrix, px; normal, distance: the plane ``n . X = d``.
        Xp, Pp: ``(k, 3)``, ``(k, 3, 3)`` the joints' predicted points (camera frame)
            and covariances; NaN rows: no prediction.
        u, um: ``(k, 2)`` the pixels in the camera and the mirror, undistorted.
        sigma_px: the reprojection noise, px.
        chi2: the gate.

    Returns:
        ``(k, 2)`` bool the views kept (direct, mirror).
    """
    ok = np.isfinite(Xp).all(1) & np.isfinite(Pp).all((1, 2))
    views = np.ones((len(Xp), 2), bool)
    if not ok.any():
        return views
    r, J = view_residuals(K, normal, distance, Xp[ok], u[ok], um[ok])
    S = J @ Pp[ok][:, None] @ J.swapaxes(-1, -2)                         # (n, 2, 2, 2)
    S[..., [0, 1], [0, 1]] += sigma_px * sigma_px
    with np.errstate(invalid="ignore"):
        m2 = np.einsum("nvi,nvi->nv", r, np.linalg.solve(S, r[..., None])[..., 0])
    near = ~(m2 > chi2)
    near[~near.any(1)] = True
    views[ok] = near
    return views


def bias_covariance(J: np.ndarray, mean_w: np.ndarray, sigma_px: float) -> np.ndarray:
    """The covariance a detector's per-joint bias adds to a joint triangulated from two
    views: ``H^-1 H_b H^-1``, ``H = sum_v J_v^T J_v / s^2`` the joint's information from
    its two rays, ``H_b = sum_v 2 |m_v|^2 J_v^T J_v / s^2`` with ``m_v`` the joint's mean
    whitened residual in view ``v`` over the frames (the offline joints' bias share,
    :func:`mirrorgraph.graph.joints_uncertainty.joints_covariance`'s: the bias shows
    across the epipolar line, each view about half of it, and is taken as large along
    it). A shared bias does not average over frames: it is added after the filter.
    Under iid noise ``|m_v|^2`` is ``~2 / frames``.

    Args:
        J: ``(k, 2, 2, 3)`` each joint's projection Jacobians (:func:`view_residuals`).
        mean_w: ``(k, 2, 2)`` each joint's mean residual in each view over ``s``.
        sigma_px: the reprojection noise ``s``, px.

    Returns:
        ``(k, 3, 3)``; NaN where the two rays do not fix the joint.
    """
    Hv = np.einsum("kvri,kvrj->kvij", J, J) / (sigma_px * sigma_px)          # (k, 2, 3, 3)
    w = 2.0 * np.einsum("kvr,kvr->kv", mean_w, mean_w)
    Hb = np.einsum("kv,kvij->kij", w, Hv)
    try:
        Hinv = np.linalg.inv(Hv.sum(1))
    except np.linalg.LinAlgError:
        return np.full((len(J), 3, 3), np.nan)
    return Hinv @ Hb @ Hinv


_TABLE: list = []


def _frame_bones(joints: np.ndarray, bones: np.ndarray, lengths: np.ndarray,
                 sigma_len: "float | np.ndarray", k: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One frame's bone table: the bones whose two ends the frame has and whose length
    is known, in the frame's local joint indices.

    The last table is kept with its inputs (the per-frame path asks for the same frame's
    table from each of its refinements and folds): equal inputs give it back.

    Args:
        joints: ``(k,)`` the skeleton's indices of the frame's ``k`` joints.
        bones: ``(B, 2)`` the skeleton's bones; lengths: ``(B,)`` (NaN: not used).
        sigma_len: the bones' spread, one for all or ``(B,)`` one a bone.
        k: the frame's joint count.

    Returns:
        ``(a, b, L, sl)``: ``(m,)`` each used bone's two ends (local indices), its length
        and its spread (read-only: shared by the callers of one frame).
    """
    joints = np.asarray(joints)
    key = (np.asarray(bones).tobytes(), np.asarray(lengths, float).tobytes(),
           np.asarray(sigma_len, float).tobytes(), joints.tobytes(), k)
    last = _TABLE[0] if _TABLE else None            # one tuple: safe across threads
    if last is not None and last[0] == key:
        return last[1]
    top = max(int(joints.max()) if joints.size else 0, int(bones.max()) if bones.size else 0)
    local = np.full(top + 1, -1)
    local[joints] = np.arange(k)
    a, b = local[bones[:, 0]], local[bones[:, 1]]
    lengths_f = np.asarray(lengths, float)
    use = (a >= 0) & (b >= 0) & np.isfinite(lengths_f)
    sig = np.asarray(sigma_len, float)
    sl = (np.full(use.shape, float(sig)) if sig.ndim == 0 else sig)[use]
    out = (a[use], b[use], lengths_f[use], sl)
    for v in out:
        v.flags.writeable = False
    _TABLE[:] = [(key, out)]
    return out


def bone_branches(K: np.ndarray, normal: np.ndarray, distance: float, X: np.ndarray,
                  cov: np.ndarray, u: np.ndarray, um: np.ndarray, keep: np.ndarray,
                  joints: np.ndarray, bones: np.ndarray, lengths: np.ndarray,
                  sigma_px: float, sigma_len: "float | np.ndarray", *, matched: bool = True
                  ) -> tuple[np.ndarray, np.ndarray]:
    """One frame's refined joints with each one's other bone branch folded into its
    Gaussian: the two modes' moment-matched mean and covariance.

    A bone of length ``L`` from a joint ``p`` meets the joint's camera ray ``c + s r``
    (``|r| = 1``) twice, at points mirror-symmetric about the foot of ``p`` on the ray:
    the joint ``X`` and ``X' = X - 2 ((X - p) . r) r``. Where the two rays of the joint
    meet at a small angle the views barely tell the two apart, and the refinement's
    Laplace covariance at ``X`` (:func:`refine_with_bones`) covers one of them only.
    Each joint's likeliest other branch (over its bones) is scored by the frame's
    cost at the joint, the others held: both views' squared whitened reprojection
    residuals (the views kept) and the squared whitened length errors of every bone at
    the joint. The modes weigh ``1 - w`` and ``w``, each a Gaussian of covariance ``C``,
    their mixture's density matching the frame's at both points: with ``g = exp(-(c' -
    c) / 2)`` (``c``, ``c'`` the costs at ``X``, ``X'``) and ``a = exp(-q / 2)`` the
    first mode's own density at ``X'`` (``q = D^T C^-1 D``, ``D = X' - X``),
    ``((1 - w) a + w) / ((1 - w) + w a) = g`` gives ``w = (g - a) / ((1 - a)(1 + g))``,
    clipped to ``[0, 1]``: a branch the Gaussian at ``X`` already reaches (``C`` long
    along the ray) weighs only what the cost holds there beyond it (0 where ``g <= a``),
    a branch far outside it ``1 / (1 + exp((c' - c) / 2))``. The joint becomes their
    moment-matched Gaussian ``m = X + w D``, ``C + w (1 - w) D D^T`` (the collapse of a
    two-component mixture: Bar-Shalom, Li and Kirubarajan, *Estimation with
    Applications to Tracking and Navigation*, 2001, sec. 11.6). A joint the views place
    is unchanged (``w`` ~ 0): its other branch reprojects far off. Weighed by the cost
    gap alone, the fold pulls joints the Gaussian already covers towards a branch the
    frames do not hold (``bench/RESULTS_live_gap.md``).

    Args:
        K: ``(3, 3)`` camera matrix, px; normal, distance: the plane ``n . X = d``.
        X: ``(k, 3)`` the refined joints (camera frame); cov: ``(k, 3, 3)`` theirs.
        u, um: ``(k, 2)`` their pixels in the camera and the mirror, undistorted.
        keep: ``(k, 2)`` the views kept (direct, mirror).
        joints: ``(k,)`` the skeleton's indices of the joints; bones: ``(B, 2)`` the
            skeleton's bones; lengths: ``(B,)`` their lengths (NaN: not used).
        sigma_px: the reprojection noise, px; sigma_len: the bones' spread about
            their lengths, one for all or ``(B,)`` one a bone.
        matched: weigh the other branch by the density the joint's Gaussian at ``X``
            does not already give it there (above); ``False``: by the cost gap alone,
            ``w = 1 / (1 + exp((c' - c) / 2))`` (a bench ablation).

    Returns:
        ``(X, cov)``: ``(k, 3)``, ``(k, 3, 3)`` (copies).
    """
    X = np.asarray(X, float)
    k = len(X)
    a, b, L, sl = _frame_bones(joints, bones, lengths, sigma_len, k)
    if not len(L):
        return X.copy(), np.array(cov, float)
    # every bone end moved to its other branch about the bone's other end
    move = np.concatenate([a, b])                                  # (2B,)
    fixed = np.concatenate([b, a])
    r = X[move] / np.linalg.norm(X[move], axis=1, keepdims=True)   # camera rays
    Y = X[move] - 2.0 * ((X[move] - X[fixed]) * r).sum(1, keepdims=True) * r
    ends = np.stack([a, b], 1)                                     # (B, 2)

    m = len(move)
    with np.errstate(invalid="ignore", over="ignore"):
        c = _joint_cost(K, normal, distance, np.concatenate([Y, X[move]]),
                        np.concatenate([move, move]), X, u, um, keep, ends, L, sl, sigma_px)
        gap = c[:m] - c[m:]                                        # c' - c, (2B,)
        gap = np.where(np.isfinite(gap), gap, np.inf)
    # each joint's likeliest other branch
    order = np.lexsort((gap, move))
    first = np.ones(len(order), bool)
    first[1:] = move[order][1:] != move[order][:-1]
    pick = order[first]
    i, D = move[pick], Y[pick] - X[move[pick]]
    w = _mode_weight(gap[pick], D, np.array(cov, float)[i], matched)
    Xo, Co = X.copy(), np.array(cov, float)
    Xo[i] += w[:, None] * D
    Co[i] += (w * (1.0 - w))[:, None, None] * D[:, :, None] * D[:, None, :]
    return Xo, Co


def _mode_weight(gap: np.ndarray, D: np.ndarray, C: np.ndarray, matched: bool
                 ) -> np.ndarray:
    """``(n,)`` the second mode's weight of two Gaussians of covariance ``C`` ``(n, 3,
    3)`` ``D`` ``(n, 3)`` apart whose costs differ by ``gap`` (``c' - c``): the mixture
    matched to the frame's density at both points (:func:`bone_branches`), or with
    ``matched`` off ``1 / (1 + exp(gap / 2))``."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        if not matched:
            return 1.0 / (1.0 + np.exp(np.clip(0.5 * gap, -700.0, 700.0)))
        C = np.where(np.isfinite(C).all((1, 2))[:, None, None], C, np.eye(3))
        D = np.where(np.isfinite(D), D, 0.0)
        try:
            CiD = np.linalg.solve(C, D[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:               # a joint the frame does not hold
            CiD = (np.linalg.pinv(C, hermitian=True) @ D[:, :, None])[:, :, 0]
        q = np.einsum("ni,ni->n", D, CiD)
        a = np.exp(-0.5 * np.maximum(q, 0.0))       # the first mode's density at the other
        g = np.exp(np.clip(-0.5 * gap, -700.0, 700.0))      # the frame's there, relative
        w = np.clip((g - a) / ((1.0 - a) * (1.0 + g)), 0.0, 1.0)
        return np.where(np.isfinite(w) & (q > 1e-9), w, 0.0)


def _joint_cost(K, normal, distance, P, who, X, u, um, keep, ends, L, sl, sigma_px,
                px=None):
    """``(n,)`` the frame's cost at joints ``who`` placed at ``P`` ``(n, 3)``, the
    others at ``X``: both views' squared whitened reprojection residuals (the views
    ``keep``; ``px`` ``(n, 2)``: their norms at ``P`` where known, px), the squared
    whitened length errors of the bones ``ends`` ``(B, 2)`` (local indices; lengths
    ``L``, spreads ``sl``) at the joint."""
    if px is None:
        res = _residuals(K, normal, distance, P, u[who], um[who])
        sq = (res * res).sum(2) / (sigma_px * sigma_px)
    else:
        sq = px / sigma_px
        sq = sq * sq
    rr = np.where(keep[who], sq, 0.0).sum(1)
    at = ends[None] == who[:, None, None]                          # (n, B, 2)
    touch = at.any(2)
    other = np.where(at[:, :, 0], ends[None, :, 1], ends[None, :, 0])   # (n, B)
    length = np.linalg.norm(P[:, None, :] - X[other], axis=2)
    e = np.where(touch, (length - L[None]) / sl[None], 0.0)
    return rr + (e * e).sum(1)


def two_starts(K: np.ndarray, normal: np.ndarray, distance: float, XA: np.ndarray,
               CA: np.ndarray, XB: np.ndarray, CB: np.ndarray, u: np.ndarray,
               um: np.ndarray, keepA: np.ndarray, keepB: np.ndarray, joints: np.ndarray,
               bones: np.ndarray, lengths: np.ndarray, sigma_px: float,
               sigma_len: "float | np.ndarray", *, pxA: np.ndarray | None = None,
               pxB: np.ndarray | None = None, matched: bool = False
               ) -> tuple[np.ndarray, np.ndarray]:
    """Two refinements of one frame's joints (:func:`refine_with_bones` from two
    starting points: ``A``, the rays' midpoints, and ``B``, where the joints' tracks
    predict them) folded, joint by joint, into the moment-matched Gaussian of the two.

    At small parallax the frame's cost has a mode on either side of a joint's
    neighbours along its ray (a bone meets the ray twice), and the Gauss-Newton steps
    end in the one their start lies nearer. Each joint's two solutions weigh ``1 - w``
    and ``w = 1 / (1 + exp((c_B - c_A) / 2))`` with ``c`` the frame's cost at the joint
    in each solution (both views' squared whitened residuals, the squared whitened
    length errors of its bones, :func:`bone_branches`'s): the likelihood alone, the
    prediction only the start, so that the tracks' filter does not take its own
    prediction again. The fold: ``m = X_A + w (X_B - X_A)``, ``(1 - w) C_A + w C_B
    + w (1 - w) (X_B - X_A)(X_B - X_A)^T`` (Bar-Shalom, Li and Kirubarajan, 2001, sec.
    11.6). Where the two kept different views of a joint their costs do not compare,
    and ``A`` is kept.

    Args:
        K: ``(3, 3)`` camera matrix, px; normal, distance: the plane ``n . X = d``.
        XA, CA: ``(k, 3)``, ``(k, 3, 3)`` the refinement from the midpoints;
            XB, CB: the one from the prediction (NaN rows: none).
        u, um: ``(k, 2)`` the pixels in the camera and the mirror, undistorted.
        keepA, keepB: ``(k, 2)`` the views each kept.
        joints: ``(k,)`` the skeleton's indices; bones: ``(B, 2)``; lengths: ``(B,)``.
        sigma_px: the reprojection noise, px; sigma_len: the bones' spread, one for all
            or ``(B,)``.
        pxA, pxB: ``(k, 2)`` each view's reprojection residual at ``XA``, ``XB``, px
            (:func:`refine_with_bones`' ``full`` output), where known: the costs' views
            taken from them, not reprojected again.

    Returns:
        ``(X, cov)``: ``(k, 3)``, ``(k, 3, 3)``.
    """
    k = len(XA)
    a, b, L, sl = _frame_bones(joints, bones, lengths, sigma_len, k)
    ends = np.stack([a, b], 1)
    who = np.arange(k)
    with np.errstate(invalid="ignore", over="ignore"):
        gap = (_joint_cost(K, normal, distance, XB, who, XB, u, um, keepA, ends, L, sl,
                           sigma_px, pxB)
               - _joint_cost(K, normal, distance, XA, who, XA, u, um, keepA, ends, L, sl,
                             sigma_px, pxA))
    w = _mode_weight(gap, XB - XA, np.asarray(CA, float), matched)
    w = np.where(np.isfinite(gap) & np.isfinite(XB).all(1) & np.isfinite(CB).all((1, 2))
                 & (keepA == keepB).all(1), w, 0.0)
    D = XB - XA
    D = np.where(np.isfinite(D), D, 0.0)
    X = XA + w[:, None] * D
    C = ((1 - w)[:, None, None] * CA + w[:, None, None] * np.nan_to_num(CB)
         + (w * (1 - w))[:, None, None] * D[:, :, None] * D[:, None, :])
    return X, C


_DIAGONALS: dict = {}


def _diagonal(k: int) -> np.ndarray:
    """``(k, 3, 3)`` flat indices into a ``(3k, 3k)`` matrix of its ``3 x 3`` diagonal
    blocks (kept per joint count: a stream repeats a few)."""
    if k not in _DIAGONALS:
        i3 = np.arange(3)
        ar = np.arange(k)
        _DIAGONALS[k] = ((3 * ar[:, None, None] + i3[None, :, None]) * 3 * k
                         + 3 * ar[:, None, None] + i3[None, None, :])
    return _DIAGONALS[k]


def refine_with_bones(K: np.ndarray, normal: np.ndarray, distance: float, X: np.ndarray,
                      u: np.ndarray, um: np.ndarray, joints: np.ndarray, bones: np.ndarray,
                      lengths: np.ndarray, sigma_px: float, sigma_len: "float | np.ndarray",
                      iterations: int = 3, *, gate_px: float | None = None,
                      full: bool = False):
    """Refine one frame's triangulated joints with the bones' lengths.

    Args:
        K: ``(3, 3)`` camera matrix, px.
        normal, distance: the mirror plane ``n . X = d`` (camera frame, unit ``n``).
        X: ``(k, 3)`` the joints triangulated from their two rays (camera frame).
        u, um: ``(k, 2)`` their pixels in the camera and in the mirror (the reflection's
            keypoints in the person's labels), undistorted.
        joints: ``(k,)`` the skeleton's indices of the ``k`` joints.
        bones: ``(B, 2)`` skeleton joint indices of each bone's two ends (any two
            joints held at a distance: the torso's too).
        lengths: ``(B,)`` the bones' lengths (the unit of ``X``); NaN: not used.
        sigma_px: the reprojection noise, px.
        sigma_len: the bones' spread about their lengths (the unit of ``X``), one for
            all or ``(B,)`` one a bone.
        iterations: Gauss-Newton steps.
        gate_px: after the steps, of each joint held by bones the view whose residual
            is the larger and exceeds this (px) is left out (a keypoint displaced along
            its epipolar line, which the two rays follow in depth and the bones do not;
            the offline joints pass's rule, :func:`mirrorgraph.graph.outliers.one_view_outliers`,
            at most one view a joint) and the steps are taken again without it (their
            normal equations built anew; each step halved until the frame's cost without
            the views left out falls: a joint left one view is held along its ray by
            its bones alone); ``None``: every view kept.
        full: also return the views kept and the residuals at the joints returned.

    Returns:
        ``(X, cov)``: the refined ``(k, 3)`` joints and each one's ``(k, 3, 3)``
        covariance (a bone's two ends are correlated; the blocks are the marginals);
        with ``full`` also ``(k, 2)`` bool the views kept and ``(k, 2)`` each view's
        reprojection residual at the returned joints, px (direct, mirror).
    """
    Xs, cov, keep, px = refine_starts(K, normal, distance, np.asarray(X, float)[None], u,
                                      um, joints, bones, lengths, sigma_px, sigma_len,
                                      iterations, gate_px=gate_px)
    if full:
        return Xs[0], cov[0], keep[0], px[0]
    return Xs[0], cov[0]


def refine_starts(K: np.ndarray, normal: np.ndarray, distance: float, starts: np.ndarray,
                  u: np.ndarray, um: np.ndarray, joints: np.ndarray, bones: np.ndarray,
                  lengths: np.ndarray, sigma_px: float, sigma_len: "float | np.ndarray",
                  iterations: int = 3, *, gate_px: float | None = None,
                  views: np.ndarray | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`refine_with_bones` of one frame from ``m`` starting points at once, each
    refinement on its own (its steps, its views left out), vectorised over the starts.

    Args:
        starts: ``(m, k, 3)`` the starting joints (camera frame); the other arguments
            as :func:`refine_with_bones`'.
        views: ``(k, 2)`` bool the views each joint starts with (default: both; each
            joint needs one; a joint held by no bone keeps both, as a view left out
            would leave its depth to nothing).

    Returns:
        ``(X, cov, keep, px)``: ``(m, k, 3)`` the refined joints, ``(m, k, 3, 3)``
        their covariances, ``(m, k, 2)`` bool the views kept and ``(m, k, 2)`` each
        view's reprojection residual at the joints returned, px (direct, mirror).
    """
    X = np.array(starts, dtype=float)
    m, k = X.shape[:2]
    n = np.asarray(normal, float)
    H = np.eye(3) - 2.0 * np.outer(n, n)
    a, b, L, sl = _frame_bones(joints, bones, lengths, sigma_len, k)
    nb = len(L)
    held = np.zeros(k, bool)
    held[a] = held[b] = True
    keep = np.ones((m, k, 2), bool)
    if views is not None:                           # a joint no bone holds keeps both
        keep &= np.where(held[:, None], np.asarray(views, bool), True)[None]
    steps = np.full(m, max(int(iterations), 1))
    done = np.zeros(m, np.int64)
    gated = np.full(m, gate_px is not None)
    active = np.ones(m, bool)
    uu = np.stack([u, um], 1)                      # (k, view, 2)
    # both views' projections side by side: the camera's K, the mirror's K H (offset K c)
    KH = K @ H
    PT = np.concatenate([K.T, KH.T], 1)            # (3, 6)
    off = np.concatenate([np.zeros(3), K @ (2.0 * distance * n)])
    P = np.stack([K, KH])                          # (view, 3, 3)
    rows = np.arange(nb)
    Jb = np.zeros((m, nb, k, 3))                   # the bones' rows of the Jacobian
    inv_var = 1.0 / (sigma_px * sigma_px)
    # each refinement's state where it ends: its blocks, bone rows, residuals, solver
    Df, Jbf = np.empty((m, k, 3, 3)), np.empty((m, nb, k, 3))
    rnf, bothf = np.empty((m, k, 2)), np.zeros(m, bool)
    guard = np.zeros(m, bool)                      # views left out: steps line-searched
    while True:
        q = (X @ PT + off).reshape(m, k, 2, 3)
        z = q[..., 2:3]
        p = q[..., :2] / z
        Jv = (P[:, :2, :] - p[..., None] * P[:, 2:3, :]) / z[..., None]    # (m, k, 2, 2, 3)
        d = p - uu
        rn = np.sqrt(np.einsum("...i,...i->...", d, d)) / sigma_px           # (m, k, 2)
        w = np.minimum(1.0, HUBER_K / np.maximum(rn, 1e-12))
        w *= keep
        w *= inv_var
        JJ = (Jv.swapaxes(-1, -2) @ Jv) * w[..., None, None]
        Jr = (Jv.swapaxes(-1, -2) @ d[..., None])[..., 0] * w[..., None]     # (m, k, 2, 3)
        D = JJ[:, :, 0] + JJ[:, :, 1]             # the reprojection's diagonal blocks
        both = keep.all((1, 2))                   # every block of two views: invertible
        g = (Jr[:, :, 0] + Jr[:, :, 1]).reshape(m, 3 * k)
        if nb:
            diff = X[:, a] - X[:, b]
            length = np.sqrt(np.einsum("mbi,mbi->mb", diff, diff))
            e = diff / (np.maximum(length, 1e-12) * sl)[..., None]      # d r / d X_a
            Jb[:, rows, a], Jb[:, rows, b] = e, -e
            g += (Jb.reshape(m, nb, 3 * k).swapaxes(1, 2)
                  @ ((length - L) / sl)[..., None])[..., 0]
        due = active & (done >= steps)
        test = due & gated & held.any()
        end = due & ~test
        if test.any():
            px = sigma_px * rn[test]                                        # (t, k, 2)
            # the joints pass's rule (one home): the worst view over the threshold, at
            # most one a joint, here of the joints the bones hold
            drop = np.stack(one_view_outliers([px[..., 0], px[..., 1]], gate_px), -1)
            drop &= keep[test] & held[:, None]
            some = drop.any((1, 2))
            at = np.flatnonzero(test)
            end[at[~some]] = True
            keep[at[some]] &= ~drop[some]
            # the steps again without those views (their normal equations built anew,
            # by the pass below), then stop
            gated[at[some]] = False
            steps[at[some]] += max(int(iterations), 1)
            again = np.zeros(m, bool)
            again[at[some]] = True
            guard |= again
        else:
            again = np.zeros(m, bool)
        go = active & ~end & ~again
        if go.all() and not guard.any():          # every start steps: no rows to pick
            step, solved = _solve_many(D, Jb, both, g, "solve")
            if solved.all():
                X -= step.reshape(m, k, 3)
                done += 1
            else:
                X[solved] -= step[solved].reshape(-1, k, 3)
                done[solved] += 1
                end[~solved] = True               # a singular system: stop there
        elif go.any():
            step, solved = _solve_many(D[go], Jb[go], both[go], g[go], "solve")
            at = np.flatnonzero(go)
            step = step.reshape(-1, k, 3)
            ls = guard[at] & solved
            if ls.any():
                # the step after views were left out: a joint left one view is held
                # along that view's ray by its bones alone, whose linearisation can
                # overshoot; the step is halved until the frame's cost falls
                # (Nocedal and Wright, *Numerical Optimization*, 2nd ed., sec. 3.1)
                i = at[ls]
                c0 = _frame_cost(PT, off, uu, sigma_px, X[i], keep[i], a, b, L, sl)
                trial = X[i, None] - _HALVINGS[None, :, None, None] * step[ls][:, None]
                c = _frame_cost(PT, off, uu, sigma_px, trial.reshape(-1, k, 3),
                                np.repeat(keep[i], len(_HALVINGS), 0), a, b, L, sl
                                ).reshape(len(i), -1)
                fall = c <= c0[:, None]
                first = np.where(fall.any(1), fall.argmax(1), len(_HALVINGS))
                alpha = np.append(_HALVINGS, 0.0)[first]
                step[ls] *= alpha[:, None, None]
            X[at[solved]] -= step[solved]
            done[at[solved]] += 1
            end[at[~solved]] = True
        if end.any():
            Df[end], Jbf[end], rnf[end], bothf[end] = D[end], Jb[end], rn[end], both[end]
            active &= ~end
        if not active.any():
            break
    cov, solved = _solve_many(Df, Jbf, bothf, None, "covariance")
    cov = cov.reshape(m, k, 3, 3)
    cov[~solved] = np.nan
    return X, cov, keep, sigma_px * rnf


#: The step fractions the line search after views are left out tries, in turn.
_HALVINGS = 0.5 ** np.arange(5)


def _frame_cost(PT, off, uu, sigma_px, X, keep, a, b, L, sl) -> np.ndarray:
    """``(n,)`` the frames' costs at joints ``X`` ``(n, k, 3)``: the views ``keep``
    ``(n, k, 2)``'s Huber losses (twice Huber's rho of the whitened residual's norm,
    the Gauss-Newton weights' cost) and the bones' squared whitened length errors."""
    n, k = X.shape[:2]
    q = (X @ PT + off).reshape(n, k, 2, 3)
    d = q[..., :2] / q[..., 2:3] - uu
    r = np.sqrt(np.einsum("...i,...i->...", d, d)) / sigma_px
    rho = np.where(r <= HUBER_K, r * r, HUBER_K * (2.0 * r - HUBER_K))
    cost = np.where(keep, rho, 0.0).sum((1, 2))
    if len(L):
        e = (np.linalg.norm(X[:, a] - X[:, b], axis=2) - L) / sl
        cost += (e * e).sum(1)
    return np.where(np.isfinite(cost), cost, np.inf)


def _solve_many(D: np.ndarray, Jb: np.ndarray, both: np.ndarray, g: np.ndarray | None,
                what: str) -> tuple[np.ndarray, np.ndarray]:
    """``m`` frames' normal equations (:class:`_Normal`): ``(m, 3k)`` their steps
    ``A^-1 g`` (``what="solve"``) or ``(m, k, 3, 3)`` their covariance blocks
    (``"covariance"``), and ``(m,)`` bool where solved (NaN where singular)."""
    m, k = D.shape[:2]
    ok = np.ones(m, bool)
    if both.all() or not both.any():              # one solver for all: no rows to pick
        try:
            return _Normal(D, Jb, bool(both[0])).run(what, g), ok
        except np.linalg.LinAlgError:
            pass
    out = np.full((m, 3 * k) if what == "solve" else (m, k, 3, 3), np.nan)
    for flag in (True, False):
        sel = np.flatnonzero(both == flag)
        if not sel.size:
            continue
        try:
            out[sel] = _Normal(D[sel], Jb[sel], flag).run(what, None if g is None else g[sel])
        except np.linalg.LinAlgError:
            for i in sel:                         # one by one: which one is singular
                try:
                    out[i] = _Normal(D[i:i + 1], Jb[i:i + 1], flag).run(
                        what, None if g is None else g[i:i + 1])[0]
                except np.linalg.LinAlgError:
                    ok[i] = False
    return out, ok


class _Normal:
    """The normal equations ``A = blockdiag(D) + J_b^T J_b`` of ``m`` frames (or starts):
    ``D`` ``(m, k, 3, 3)`` the reprojection's blocks, ``J_b`` ``(m, B, k, 3)`` the bones'
    rows (``B`` small).

    With every block invertible (both views of every joint kept) by the Woodbury
    identity, ``A^-1 = D^-1 - D^-1 J_b^T S^-1 J_b D^-1`` with ``S = I + J_b D^-1 J_b^T``
    (``B x B``; Golub and Van Loan, *Matrix Computations*, 4th ed., sec. 2.1.4), else
    densely.
    """

    def __init__(self, D: np.ndarray, Jb: np.ndarray, blocks_invertible: bool):
        self.D, self.Jb = D, Jb
        self.m, self.k, self.B = D.shape[0], D.shape[1], Jb.shape[1]
        self.woodbury = bool(blocks_invertible)

    def run(self, what: str, g: np.ndarray | None) -> np.ndarray:
        return self.solve(g) if what == "solve" else self.covariance()

    def dense(self) -> np.ndarray:
        """``(m, 3k, 3k)`` the matrices."""
        k = self.k
        Jf = self.Jb.reshape(self.m, self.B, 3 * k)
        A = Jf.swapaxes(1, 2) @ Jf
        A.reshape(self.m, -1)[:, _diagonal(k)] += self.D
        return A

    def _parts(self):
        m, k, B = self.m, self.k, self.B
        Dinv = np.linalg.inv(self.D)                                          # (m, k, 3, 3)
        U = np.matmul(self.Jb.transpose(0, 2, 1, 3), Dinv).transpose(0, 2, 1, 3)  # J_b D^-1
        Uf = U.reshape(m, B, 3 * k)
        S = Uf @ self.Jb.reshape(m, B, 3 * k).swapaxes(1, 2)
        S[:, np.arange(B), np.arange(B)] += 1.0
        return Dinv, Uf, S

    def solve(self, g: np.ndarray) -> np.ndarray:
        """``(m, 3k)`` ``A^-1 g``."""
        if not self.woodbury:
            return np.linalg.solve(self.dense(), g[..., None])[..., 0]
        Dinv, Uf, S = self._parts()
        Dg = np.matmul(Dinv, g.reshape(self.m, self.k, 3, 1)).reshape(self.m, -1)
        if self.B == 0:
            return Dg
        return Dg - (Uf.swapaxes(1, 2) @ np.linalg.solve(S, (Uf @ g[..., None])))[..., 0]

    def covariance(self) -> np.ndarray:
        """``(m, k, 3, 3)`` the diagonal blocks of ``A^-1``."""
        m, k = self.m, self.k
        if not self.woodbury:
            inv = np.linalg.inv(self.dense()).reshape(m, k, 3, k, 3)
            return np.einsum("mkikj->mkij", inv)
        Dinv, Uf, S = self._parts()
        if self.B == 0:
            return Dinv
        V = np.linalg.solve(S, Uf).reshape(m, self.B, k, 3)
        U = Uf.reshape(m, self.B, k, 3)
        return Dinv - np.einsum("mbki,mbkj->mkij", U, V)


_HEADS: dict = {}
_EYE3 = np.diag_indices(3)


def head_layout(names) -> tuple | None:
    """``(face, trunk, level)``: the face keypoints' indices ``(f,)``, the trunk's
    ``(4,)`` (left and right shoulder, left and right hip) and each face keypoint's
    height over the shoulders, a fraction of the height ``(f,)``
    (:data:`mirrorgraph.completion.HEAD_LANDMARKS`); ``None`` without a face or a trunk.
    Kept per layout."""
    key = tuple(names)
    if key not in _HEADS:
        from ..completion import HEAD_LANDMARKS, head_level

        index = {n: i for i, n in enumerate(key)}
        trunk = [index.get(f"{side}_{part}") for part in ("shoulder", "hip")
                 for side in ("left", "right")]
        face = [i for i, n in enumerate(key) if n in HEAD_LANDMARKS]
        level = [head_level(key[i]) for i in face]
        _HEADS[key] = (None if not face or any(t is None for t in trunk) else
                       (np.array(face), np.array(trunk), np.array(level, float)))
    return _HEADS[key]


def with_head_prior(X: np.ndarray, cov: np.ndarray, joints: np.ndarray, names,
                    height: float) -> tuple[np.ndarray, np.ndarray]:
    """One frame's face keypoints fused with where its trunk puts them.

    The offline run's prior of the face (:func:`mirrorgraph.completion.head_prior`, here
    for one frame and one person, vectorised: the nose, eyes, ears and head top on the
    trunk's axis ``u`` (mid-hip to mid-shoulder) at their landmark heights over the
    shoulders, ``m = mid-shoulder + (h_k - h_shoulder) H u``, an isotropic spread of
    :data:`~mirrorgraph.completion.HEAD_PRIOR_SIGMA` ``H`` per axis plus the
    mid-shoulder's covariance: ``C``) fused with each face keypoint's own estimate
    ``(x, cov)``: ``(cov^-1 + C^-1)^-1 (cov^-1 x + C^-1 m)``, in its gain form ``x + G (m
    - x)``, ``G = cov (cov + C)^-1``, covariance ``cov - G cov``. The face has no bone,
    and where its two rays meet at a small angle its depth is the prior's. Applied to a
    frame's output after the joints' filter (its track keeps its own measurements), as
    the offline run fuses it after the smoothing.

    Args:
        X: ``(k, 3)`` the frame's joints (camera frame); cov: ``(k, 3, 3)`` their
            covariances.
        joints: ``(k,)`` their indices in the skeleton.
        names: ``(J,)`` the skeleton's joint names.
        height: the subject's height ``H``, the unit of ``X``.

    Returns:
        ``(X, cov)``, the face keypoints with the prior fused (copies), the others as
        given; as given without both shoulders and both hips.
    """
    from ..completion import HEAD_PRIOR_SIGMA

    layout = head_layout(names)
    if layout is None or not height > 0:
        return X, cov
    face, trunk, level = layout
    local = np.full(len(names), -1)
    local[joints] = np.arange(len(joints))
    t = local[trunk]
    rows = local[face]
    f = rows >= 0
    if t.min() < 0 or not f.any():
        return X, cov
    rows, level = rows[f], level[f]
    own = cov[rows]
    if not np.isfinite(own).all():
        good = np.isfinite(own).all((-2, -1))
        rows, level, own = rows[good], level[good], own[good]
    Xt = X[t]                                  # left, right shoulder; left, right hip
    ms = 0.5 * (Xt[0] + Xt[1])
    axis = ms - 0.5 * (Xt[2] + Xt[3])
    norm = float(np.sqrt(axis @ axis))
    if not norm > 0 or not len(rows):
        return X, cov
    m = ms + np.outer(level * (height / norm), axis)
    C = 0.25 * (cov[t[0]] + cov[t[1]])
    if not np.isfinite(C).all():
        C = np.zeros((3, 3))
    C[_EYE3] += (HEAD_PRIOR_SIGMA * height) ** 2
    try:
        G = own @ np.linalg.inv(own + C)
    except np.linalg.LinAlgError:
        return X, cov
    X, cov = X.copy(), cov.copy()
    X[rows] += (G @ (m - X[rows])[:, :, None])[:, :, 0]
    post = own - G @ own
    cov[rows] = 0.5 * (post + post.transpose(0, 2, 1))
    return X, cov
