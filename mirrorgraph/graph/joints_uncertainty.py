"""Each output joint's own uncertainty: its ``3 x 3`` covariance in every frame.

The covariance is that of the graph that outputs the joints (the joints pass, or the last
full-graph stage), linearised at the solution with the robust kernel's weights applied,
in four parts:

    Cov(x) = s^2 H_xx^-1  +  B  +  G C_z G^T   (+ d d^T where the rays disagree)

* ``H_xx^-1``: the joints' information from their views and the body priors, scaled by
  the noise the data show (``s^2``); a joint's chain of frames with its smoothness is
  inverted exactly by cyclic reduction (:func:`chain_marginals`), and widened where the
  detector's noise persists from frame to frame, which the smoothness's average does not
  remove (:func:`time_correlation_factor`: the residuals' autocorrelation through the
  smoother's kernel);
* ``B``: the detector's bias, from the residuals' mean per joint and view
  (:func:`_bias_weights`);
* ``G C_z G^T``: the reduced globals' covariance ``C_z`` (planes, estimated poses and
  intrinsics; :func:`~.optimizer.reduced_covariance_matrix`) taken through each joint's
  response ``G`` (:func:`_without_scale` with a subject height);
* ``d d^T``: where the graph's joint and its rays' triangulation disagree
  (:func:`with_disagreement`).

This is the marginal of a Gaussian whose joints are independent given the globals
(Bishop 2006, sec. 2.3.3), ``O(T J^3)``. Joints filled in by triangulation get
:func:`triangulated_covariance`; the metric scale's relative std ``r`` adds
``r^2 X X^T`` (:func:`with_scale`).

:func:`position_std` is the figure a user reads: ``sqrt(trace(Sigma))``, the RMS length
of the joint's 3D error (metres with a subject height). Calibration of the figure:
``bench/RESULTS_joints_std.md``; the parts in full: ``docs/internals.md``.
"""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache
from typing import Callable

import gtsam
import numpy as np

from .. import geometry as geo
from ..factors import plane_from_gtsam, plane_to_gtsam
from ..factors.smoothness import SmoothnessFactor
from ..factors.reprojection import kernel_weights
from .optimizer import reduced_covariance_matrix
from .options import RefineOptions
from .problem import X_BASE, GraphProblem, snap_virtual_poses
from .reduction import mirror_reduction
from .rig import Rig, spread_rows
from .solve_state import SolveState
from ..skeletons import person_of

__all__ = ["graph_joints_covariance", "chain_marginals", "triangulated_covariance",
           "mirror_plane_projections", "view_projections", "with_scale", "position_std",
           "globals_covariance", "with_disagreement", "DISAGREEMENT_CHI2"]

#: A joint's per-frame information gets this fraction of its frame's largest diagonal
#: entry on its diagonal (a relative std of ~3e4 where nothing in the frame fixes it).
RIDGE = 1e-9

#: Frames per group of :func:`chain_marginals` (``3 g x 3 g`` blocks, ``log2(N / g)``
#: levels of cyclic reduction: 2, the smallest, is the fastest).
CHAIN_GROUP = 2

#: Chains :func:`chain_marginals` reduces at once (memory: ``~50 x chains x frames x g``
#: 8-byte numbers; a few chains at a time stay in the caches better than many).
CHAIN_BATCH = 4

#: Frames whose per-frame blocks are formed at once (memory: ``frames x (3 J)^2``).
FRAME_BATCH = 2048


def position_std(cov: np.ndarray) -> np.ndarray:
    """``(...,)`` the RMS length of a point's 3D error, ``sqrt(trace(cov))``, from
    ``(..., 3, 3)`` covariances (NaN stays NaN)."""
    tr = np.trace(np.asarray(cov, float), axis1=-2, axis2=-1)
    return np.sqrt(np.where(np.isfinite(tr), np.maximum(tr, 0.0), np.nan))


def with_scale(cov: np.ndarray, points: np.ndarray, rel_std: float) -> np.ndarray:
    """``(..., 3, 3)`` covariances with a pure scale error of relative std ``rel_std``
    added: ``cov + rel_std^2 X X^T`` (``X`` ``(..., 3)``, the origin the scale's fixed
    point: the camera, or a rig's world frame)."""
    X = np.asarray(points, float)
    return np.asarray(cov, float) + float(rel_std) ** 2 * X[..., :, None] * X[..., None, :]


#: A joint whose graph estimate and its own rays' triangulation differ by more than this
#: squared Mahalanobis distance (their two covariances summed) is one the data do not
#: support (:func:`with_disagreement`): ``chi^2`` of three degrees of freedom at 0.99, the
#: usual level of an outlier test (at 0.999, 16.27, the fixtures' joints' error/std had a
#: 99th percentile of 3.54 against 3.01 here: ``bench/RESULTS_joints_std.md``).
DISAGREEMENT_CHI2 = 11.34


def with_disagreement(cov: np.ndarray, points: np.ndarray, rays: np.ndarray,
                      rays_cov: np.ndarray, threshold: float = DISAGREEMENT_CHI2
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Covariances widened where a joint and its own rays disagree.

    The graph's joint ``X`` rests on its rays and the priors; where its two observations'
    own triangulation ``X_r`` lies farther from it than both covariances allow
    (``d^T (C + C_r)^-1 d > threshold``, ``d = X - X_r``), either the priors hold the joint
    somewhere its data are not (a depth the bones and the smoothness chose wrongly, a
    run of frames the graph followed off its observations) or the observations are
    wrong (an outlier the graph set aside): which, nothing in the frame says, and the
    covariance gains ``d d^T``. On one of the independent generator's scenes the joints
    more than 0.3 m off had a median squared distance of 18.6, the others 0.7
    (``bench/RESULTS_joints_std.md``).

    Args:
        cov: ``(..., 3, 3)`` the joints' covariances; points: ``(..., 3)`` the joints.
        rays, rays_cov: ``(..., 3)`` their two-ray triangulations and ``(..., 3, 3)``
            covariances (NaN where not seen in both views: unchanged).
        threshold: the squared distance beyond which a joint is widened.

    Returns:
        the covariances and ``(...,)`` bool, the joints widened.
    """
    cov = np.array(cov, dtype=float, copy=True)
    d = np.asarray(points, float) - np.asarray(rays, float)
    C = cov + np.asarray(rays_cov, float)
    ok = np.isfinite(d).all(-1) & np.isfinite(C).all((-2, -1))
    m2 = np.zeros(ok.shape)
    if ok.any():
        m2[ok] = _mahalanobis2(C[ok], d[ok])
    wide = ok & (m2 > float(threshold))
    cov[wide] += d[wide][:, :, None] * d[wide][:, None, :]
    return cov, wide


def _mahalanobis2(C: np.ndarray, d: np.ndarray) -> np.ndarray:
    """``(n,)`` ``d^T C^+ d`` of symmetric positive semi-definite ``(n, 3, 3)`` ``C`` and
    ``(n, 3)`` ``d``: the adjugate over the determinant where ``C`` is well conditioned,
    the pseudo-inverse (its lower triangle, as :func:`numpy.linalg.pinv` reads it) where
    not."""
    H = np.stack([C[:, a, b] if a == b else C[:, b, a] for a, b in geo.SYM3])   # lower
    adj, det = geo.sym3_adjugate(H)
    scale = (H[0] + H[1] + H[2]) / 3.0
    fine = det > 1e-6 * np.abs(scale) ** 3
    dt = d.T
    out = np.empty(len(d))
    with np.errstate(divide="ignore", invalid="ignore"):
        out[fine] = (np.einsum("in,in->n", dt[:, fine], geo.sym3_product(adj[:, fine],
                                                                          dt[:, fine]))
                     / det[fine])
    if not fine.all():
        Ci = np.linalg.pinv(C[~fine], hermitian=True)
        out[~fine] = np.einsum("ni,nij,nj->n", d[~fine], Ci, d[~fine])
    return out


# --------------------------------------------------------------------------- globals
def globals_covariance(state: SolveState, z_keys: list[tuple[int, int]],
                       inflation: float = 1.0) -> np.ndarray:
    """``(n, n)`` the covariance of the reduced globals ``z_keys`` (a subset of the
    solve's :attr:`~.solve_state.SolveState.z_keys`: the bone lengths, held in the joints
    pass, are marginalised out by leaving them out), scaled by the noise, times
    ``inflation^2`` (the headline's ratio to the marginal std), with the intrinsics'
    headline spread on the planes' and cameras' blocks. NaN where not computed."""
    n = sum(d for _, d in z_keys)
    if state.information is None or not n:
        return np.full((n, n), np.nan)
    C = reduced_covariance_matrix(state.information) * state.variance_factor
    where, off = {}, 0
    for key, dim in state.z_keys:
        where[int(key)] = np.arange(off, off + dim)
        off += dim
    if any(int(k) not in where for k, _ in z_keys):
        return np.full((n, n), np.nan)
    idx = np.concatenate([where[int(k)] for k, _ in z_keys])
    out = C[np.ix_(idx, idx)] * float(inflation) ** 2
    problem = state.problem
    extra = {}
    if problem is not None:
        extra.update({int(k): s for k, s in zip(problem.plane_keys, state.plane_spread)})
        extra.update({int(problem.camera_keys[i]): s for i, s in enumerate(state.camera_spread)
                      if i in problem.camera_keys})
    off = 0
    for key, dim in z_keys:
        s = extra.get(int(key))
        if s is not None and np.shape(s) == (dim, dim) and np.all(np.isfinite(s)):
            out[off:off + dim, off:off + dim] += s
        off += dim
    return out


# --------------------------------------------------------------------------- graph joints
def _solution_values(state: SolveState, rows: np.ndarray) -> gtsam.Values:
    """The solve's values at its solution: the globals of ``state.z_values``, the virtual
    poses snapped onto their planes, the output joints of the graph's frame ``rows``."""
    problem = state.problem
    values = gtsam.Values(problem.values)
    if state.z_values is not None:
        values.update(state.z_values)
    snap_virtual_poses(problem, values)
    pts = np.asarray(state.points, float)[rows].reshape(-1, 3)
    fi = np.asarray(problem.flat_index, dtype=np.int64)
    fi = fi[np.isfinite(pts[fi]).all(1)]
    base = int(X_BASE)
    for i, X in zip(fi.tolist(), pts[fi]):
        values.erase(base + i)
        values.insertPoint3(base + i, X)
    return values


def graph_joints_covariance(state: SolveState, opts: RefineOptions, *, joints_pass: bool,
                            inflation: float = 1.0, rig: Rig | None = None) -> np.ndarray:
    """The covariance of every joint the graph estimated (the module docstring).

    Args:
        state: the driver's solution (:func:`~.solve.solve`), its ``problem`` kept; a
            long video solved in chunks (``problem`` ``None``, :mod:`.chunked`) gets its
            joints' own rays with the smoothness (:func:`_chunked`).
        opts: the solve's options (the joints pass's priors: its smoothness, bones, hip).
        joints_pass: the output joints come from the joints pass
            (:func:`~.stages.joints_pass`; else from the last full-graph stage).
        inflation: the globals' headline std over their marginal one.
        rig: the solved rig (its intrinsics the solution's): needed for chunked solves.

    Returns:
        ``(T, J, 3, 3)`` graph units squared, the frames of ``state.points``; NaN where
        the graph holds no joint (a frame outside a long video's graph, a joint the graph
        did not estimate) or its information is singular.
    """
    from .builder import with_motion_priors

    problem = state.problem
    T, J = np.shape(state.used)
    out = np.full((T, J, 3, 3), np.nan)
    if problem is None:
        return _chunked(state, opts, joints_pass, inflation, rig, out)
    Tg = problem.used.shape[0]
    rows = np.arange(T) if Tg == T else np.flatnonzero(spread_rows(T, opts.max_graph_frames))
    if len(rows) != Tg:
        return out
    values = _solution_values(state, rows)
    sigma = opts.joints_smoothness_sigma
    graph_problem, smooth = problem, None
    if joints_pass and sigma is not None:
        # the joints pass's graph but for its smoothness, whose rows (linear, known) are
        # added to each joint's chain directly (SmoothnessFactor's own triples)
        jopts = replace(opts, use_smoothness=False)
        torso = (state.prior_info.get("joints_pass") or {}).get("torso", {}).get("lengths", {})
        graph_problem = with_motion_priors(problem, values, state.bone_lengths, jopts,
                                           torso=torso)
        values = graph_problem.values
        smooth = SmoothnessFactor(problem.body_height * sigma, opts.smoothness_max_gap)
    red = mirror_reduction(graph_problem, distance_gauge=None)
    Cz = globals_covariance(state, list(red.z_keys), inflation)
    cov = _graph_covariance(graph_problem, values, red, Cz, float(state.variance_factor),
                            np.asarray(state.points, float)[rows],
                            state.scale == "subject_height", smooth)
    out[rows] = cov
    out[~np.asarray(state.used, bool)] = np.nan
    return out


def _chunked(state: SolveState, opts: RefineOptions, joints_pass: bool, inflation: float,
             rig: Rig | None, out: np.ndarray) -> np.ndarray:
    """:func:`graph_joints_covariance` of a long video solved in chunks (:mod:`.chunked`,
    whose graphs are not kept; one camera, one mirror): each joint's own rays (the
    observations the joints pass kept, :attr:`~.solve_state.SolveState.joints_masks`,
    weighted by the robust kernel at their residuals as the graph's rows are) with the
    smoothness over its frames (:func:`chain_marginals`), the detector's bias and the
    mirror's uncertainty as for the graph, a joint one view sees with the graph's ridge;
    the bones and the hip are left out (information dropped: the std is wider than the
    graph's, not thinner; without them the two agree to ~1e-8). Vectorised over every
    frame: a fraction of a second for 16,000 frames, where rebuilding every chunk's
    graph took a quarter of the run."""
    if rig is None or len(state.planes) != 1 or len(rig.views) != 2:
        return out
    used = np.asarray(state.used, bool) & np.isfinite(state.points).all(-1)
    if not used.any():
        return out
    n, d = state.planes[0]
    K = np.asarray(rig.cameras[0].K, float)
    views = mirror_plane_projections(K, n, float(d))
    masks = [np.asarray(m, bool) & used for m in (state.joints_masks or state.view_masks)]
    pixels = [np.asarray(v.pixels, float) for v in rig.views]
    t, j = np.nonzero(used)
    X = np.asarray(state.points, float)[t, j]
    m = [mk[t, j] for mk in masks]
    u = [px[t, j] for px in pixels]
    sigma = float(opts.pixel_sigma)               # whitened as the graph's rows, scaled below
    P0 = views(np.zeros(0))
    T, J = used.shape
    kernel = next((s["kernel"] for s in reversed(state.stages) if s.get("kernel")), None)
    # each view's information on the point (six entries xx, yy, zz, xy, xz, yz, whitened
    # and weighted by the robust kernel as the graph's rows) and its whitened, weighted
    # residuals, (n,) columns
    Hv, r, wts, rows = [], [], [], []
    Xt = X.T
    for P, uv, mk in zip(P0, u, m):
        y = P[:, :3] @ Xt + P[:, 3:4]
        inv = 1.0 / y[2]
        px, py = y[0] * inv, y[1] * inv
        res = np.stack([px - uv[:, 0], py - uv[:, 1]], 1)
        w = kernel_weights(kernel, np.linalg.norm(np.nan_to_num(res), axis=1),
                           float(opts.final_kernel_scale_px))
        wts.append(w)
        jx = (P[0, :3, None] - P[2, :3, None] * px) * (inv / sigma)
        jy = (P[1, :3, None] - P[2, :3, None] * py) * (inv / sigma)
        Hv.append(np.where(mk, w * np.stack([jx[a] * jx[b] + jy[a] * jy[b]
                                             for a, b in geo.SYM3]), 0.0))
        r.append(res * (np.sqrt(w) / sigma)[:, None])
        rows += [np.sqrt(w) * jx, np.sqrt(w) * jy]
    H6 = Hv[0] + Hv[1]
    # the joints both views determine (the bias and the globals' response: their rays')
    adj, det = geo.sym3_adjugate(H6)
    own = m[0] & m[1] & (det > 0)
    Hinv = np.zeros((len(t), 3, 3))
    Hinv[own] = _full3(adj[:, own] / det[own])
    # every joint's information in its frame with the graph's ridge (:data:`RIDGE`): a
    # joint one view sees (the other left out) is fixed by the smoothness below
    top = np.zeros(T)
    np.maximum.at(top, t, H6[:3].max(0))
    Hr = H6                                  # in place: H6 is not read again
    Hr[:3] += RIDGE * top[t]
    adj, det = geo.sym3_adjugate(Hr)
    ok = det > 0
    # the detector's bias: each joint's mean residual in each view (:func:`_bias_weights`)
    Hb6 = np.zeros_like(Hv[0])
    for mk, rv, Hk in zip(m, r, Hv):
        cnt = np.maximum(np.bincount(j[mk], minlength=J), 1)
        mean = np.stack([np.bincount(j[mk], rv[mk, i], minlength=J) for i in range(2)], 1)
        Hb6 += (2.0 * np.sum((mean / cnt[:, None]) ** 2, axis=1))[j] * Hk
    Hb = _full3(Hb6)
    marg = np.full((T, J, 3, 3), np.nan)
    marg[t[ok], j[ok]] = _full3(adj[:, ok] / det[ok])
    used_ok = np.zeros((T, J), bool)
    used_ok[t[ok], j[ok]] = True
    if joints_pass and opts.joints_smoothness_sigma is not None:
        smooth = SmoothnessFactor(state.body_height * opts.joints_smoothness_sigma,
                                  opts.smoothness_max_gap)
        band = _smoothness_band(used_ok, rig.frame_ids, smooth)
        if band is not None:
            info = np.zeros((T, J, 3, 3))
            info[t[ok], j[ok]] = _full3(Hr[:, ok])
            frame_marg = marg
            marg = _chain_solve(marg, used_ok, band, info)
            # the noise correlated in time (:func:`time_correlation_factor`)
            both = np.flatnonzero(m[0] & m[1])
            A = np.stack(rows, 1).transpose(2, 1, 0)[both]                    # (k, 4, 3)
            e = np.full((T, J), np.nan)
            e[t[both], j[both]] = null_component(A, np.concatenate(r, 1)[both])  # x0 y0 x1 y1
            marg = marg * time_correlation_factor(e, frame_marg, marg)[..., None, None]
    plane_key = [(k, dim) for k, dim in state.z_keys if dim == 3][:1]
    Cz = globals_covariance(state, plane_key, inflation) if plane_key else None
    glob = triangulated_covariance(views, Cz, X, u, m, 1.0, frames=t if (
        state.scale == "subject_height") else None, rays=False, weights=wts,
        ridge=RIDGE * top[t])
    cov = np.full((T, J, 3, 3), np.nan)
    cov[t, j] = (float(state.variance_factor) * marg[t, j] + Hinv @ Hb @ Hinv
                 + np.nan_to_num(glob))
    cov[~used_ok] = np.nan
    return cov


def _full3(S: np.ndarray) -> np.ndarray:
    """``(n, 3, 3)`` symmetric matrices from their six entries ``(6, n)`` (xx, yy, zz, xy,
    xz, yz)."""
    return S[[0, 3, 4, 3, 1, 5, 4, 5, 2]].T.reshape(-1, 3, 3)


def view_projections(rig: Rig, poses: list[np.ndarray], planes: list[tuple[np.ndarray, float]]
                     ) -> list[np.ndarray]:
    """Each view's ``(3, 4)`` world-to-pixel matrix of a solved rig (a camera's own, or
    through its mirror)."""
    out = []
    for v in rig.views:
        c = rig.camera_index(v.camera)
        K = np.asarray(rig.cameras[c].K, float)
        if v.mirror is None:
            out.append(geo.camera_projection(K, poses[c]))
        else:
            out.append(geo.mirror_projection(K, poses[c], *planes[rig.mirror_index(v.mirror)]))
    return out


def _graph_covariance(problem: GraphProblem, values: gtsam.Values, red, Cz: np.ndarray,
                      factor: float, points: np.ndarray, body_gauge: bool,
                      smooth: SmoothnessFactor | None = None) -> np.ndarray:
    """``(Tg, J, 3, 3)`` of the graph's joints: the module docstring's first three parts."""
    Tg, J = problem.used.shape
    graph = problem.full()
    gfg = graph.linearize(values)
    trip = np.asarray(gfg.sparseJacobian_(), dtype=float)
    r, c, v = trip[0].astype(np.int64) - 1, trip[1].astype(np.int64) - 1, trip[2]
    keys = np.sort(np.asarray(gfg.keyVector(), dtype=np.uint64))
    chars = (keys >> np.uint64(56)).astype(np.int64)           # gtsam.Symbol's character
    dims = np.where(np.isin(chars, (ord("x"), ord("p"))), 3,
                    np.where(np.isin(chars, (ord("k"), ord("q"))), 5, 6))
    offsets = np.concatenate([[0], np.cumsum(dims)])
    ncol = int(offsets[-1])
    keep = c < ncol                                            # the right-hand side aside
    rhs_rows, rhs = r[~keep], v[~keep]
    r, c, v = r[keep], c[keep], v[keep]
    key_of_col = np.repeat(np.arange(len(keys)), dims)
    local_col = np.arange(ncol) - np.repeat(offsets[:-1], dims)
    is_point = chars == ord("x")
    flat_of_key = np.where(is_point, (keys - np.uint64(X_BASE) * is_point).astype(np.int64), -1)
    kc = key_of_col[c]
    pt = is_point[kc]
    flat = np.where(pt, flat_of_key[kc], -1)
    n_rows = int(r.max()) + 1 if len(r) else 0
    n_data = 2 * int(problem.reprojection.size())           # the reprojection rows come first
    # each row's frames: one (a view, a bone, the hip) or several (the smoothness)
    big = np.iinfo(np.int64).max
    fmin = np.full(n_rows, big)
    fmax = np.full(n_rows, -1)
    np.minimum.at(fmin, r[pt], flat[pt] // J)
    np.maximum.at(fmax, r[pt], flat[pt] // J)
    local_row = (fmax >= 0) & (fmin == fmax)
    cross_row = (fmax >= 0) & (fmin != fmax)
    # the globals' columns through the reduction: B = Bg T
    Tb = red.basis(values)
    row_of_key, off = {}, 0
    for k, d in red.graph_keys:
        row_of_key[int(k)] = off
        off += d
    glob_row = np.full(len(keys), -1, dtype=np.int64)
    at = np.searchsorted(keys, np.array(list(row_of_key), dtype=np.uint64))
    hit = at < len(keys)
    hit[hit] = keys[at[hit]] == np.array(list(row_of_key), dtype=np.uint64)[hit]
    glob_row[at[hit]] = np.array(list(row_of_key.values()), dtype=np.int64)[hit]
    nz = Tb.shape[1]
    bias_w = _bias_weights(r, kc, pt, flat, rhs_rows, rhs, n_rows, n_data, J, is_point)

    # per-frame blocks from the local rows: H_xx (Tg, 3J, 3J), H_xz (Tg, 3J, nz)
    lr_idx = np.flatnonzero(local_row)
    frame_of_row = np.where(local_row, fmin, -1)
    sel = local_row[r]
    rp, cp, vp = r[sel & pt], c[sel & pt], v[sel & pt]
    used = np.asarray(problem.used, bool)
    jsel = np.flatnonzero(used.any(0))              # the graph's joints: the dense blocks' columns
    Jc = len(jsel)
    compact = np.full(J, -1)
    compact[jsel] = np.arange(Jc)
    # several people side by side (skeletons.people_skeleton): no row holds two people's
    # joints, so a frame's block is one block per person, each built and inverted alone
    # (the same numbers; the work grows with the people, not with their square or cube)
    tags = [person_of(problem.rig.skeleton.joints[j]) for j in jsel]
    group_of = np.unique(np.array(tags), return_inverse=True)[1].ravel().astype(np.int64)
    group_of = group_of if len(group_of) else np.zeros(0, np.int64)
    n_groups = int(group_of.max()) + 1 if len(group_of) else 1
    local_of = np.zeros(Jc, np.int64)
    for g in range(n_groups):
        local_of[group_of == g] = np.arange(np.count_nonzero(group_of == g))
    groups = [np.ravel(3 * np.flatnonzero(group_of == g)[:, None] + np.arange(3))
              for g in range(n_groups)]
    Jg = max((len(c) // 3 for c in groups), default=Jc)
    joint_c = compact[flat_of_key[key_of_col[cp]] % J]
    colx = local_of[joint_c] * 3 + local_col[cp]
    sg = sel & ~pt & (glob_row[kc] >= 0)
    rg, vg = r[sg], v[sg]
    colg = glob_row[kc[sg]] + local_col[c[sg]]
    pos = np.full(n_rows, -1, dtype=np.int64)
    pos[lr_idx] = np.arange(len(lr_idx))
    A = np.zeros((len(lr_idx), 3 * Jg))       # each row's person's columns
    A[pos[rp], colx] = vp
    row_group = np.zeros(len(lr_idx), np.int64)
    row_group[pos[rp]] = group_of[joint_c]
    Bg = np.zeros((len(lr_idx), Tb.shape[0]))
    Bg[pos[rg], colg] = vg                          # one entry per row and column
    B = Bg @ Tb
    fr = frame_of_row[lr_idx]
    order = np.argsort(fr, kind="stable")
    fr_sorted = fr[order]
    start = np.searchsorted(fr_sorted, np.arange(Tg + 1))
    # each joint's own rays (its reprojection rows alone), summed row by row
    dr = sel & pt & (r < n_data)
    dpos = pos[r[dr]]
    dcol = compact[flat[dr] % J] * 3 + local_col[c[dr]]
    Ad = np.zeros((len(lr_idx), 3))
    Ad[dpos, dcol % 3] = v[dr]
    cell = np.full(len(lr_idx), -1)
    cell[dpos] = (flat[dr] // J) * Jc + dcol // 3
    rows_d = np.flatnonzero(cell >= 0)
    cell, Ad, Bd = cell[rows_d], Ad[rows_d], B[rows_d]
    wb = bias_w[lr_idx[rows_d]]
    n_cells = Tg * Jc

    def summed(x: np.ndarray) -> np.ndarray:
        flat_x = x.reshape(len(x), -1)
        return np.stack([np.bincount(cell, flat_x[:, i], minlength=n_cells)
                         for i in range(flat_x.shape[1])], axis=1)

    outer = Ad[:, :, None] * Ad[:, None, :]
    Hjj = summed(outer).reshape(Tg, Jc, 3, 3)
    Hb = summed(outer * wb[:, None, None]).reshape(Tg, Jc, 3, 3)
    lam = np.linalg.eigvalsh(Hjj)
    own = (lam[..., 0] > 1e-6 * np.maximum(lam[..., -1], 1e-300)) & used[:, jsel]
    Hinv = np.zeros_like(Hjj)
    Hinv[own] = np.linalg.inv(Hjj[own])
    # the detector's bias: its rays' response, not averaged over frames
    bias = np.zeros((Tg, J, 3, 3))
    bias[:, jsel] = Hinv @ Hb @ Hinv
    Gown = None
    if nz:
        Hjz = summed(Ad[:, :, None] * Bd[:, None, :]).reshape(Tg, Jc, 3, nz)
        Gown = -(Hinv @ Hjz)
    marg = np.full((Tg, J, 3, 3), np.nan)           # each joint's info in its frame, inverted
    G_all = np.zeros((Tg, J, 3, nz))
    usedc = used[:, jsel]
    for a in range(0, Tg, FRAME_BATCH):
        b = min(a + FRAME_BATCH, Tg)
        rr = order[start[a]:start[b]]
        f = fr_sorted[start[a]:start[b]] - a
        Hxx = np.zeros((b - a, 3 * Jc, 3 * Jc))
        Hxz = np.zeros((b - a, 3 * Jc, nz))
        for g, cols in enumerate(groups):
            mine = row_group[rr] == g
            rg_, fg = rr[mine], f[mine]
            slot = np.arange(len(rg_)) - np.searchsorted(fg, fg, side="left")
            width = int(slot.max()) + 1 if len(rg_) else 1
            Ap = np.zeros((b - a, width, len(cols)))
            Bp = np.zeros((b - a, width, nz))
            Ap[fg, slot], Bp[fg, slot] = A[rg_, :len(cols)], B[rg_]
            At = Ap.transpose(0, 2, 1)
            if n_groups == 1:
                Hxx, Hxz = At @ Ap, At @ Bp
            else:
                Hxx[:, cols[:, None], cols[None, :]] = At @ Ap
                Hxz[:, cols] = At @ Bp
        absent = ~np.repeat(usedc[a:b], 3, axis=1)
        ti, ji = np.nonzero(absent | (np.einsum("tii->ti", Hxx) <= 0.0))
        Hxx[ti, ji, :] = 0.0
        Hxx[ti, :, ji] = 0.0
        Hxx[ti, ji, ji] = 1.0
        Hxz[ti, ji, :] = 0.0
        # a ridge far below any joint's information: a joint only the smoothness fixes
        # (one view, no bone) keeps a finite, very large covariance in its frame
        ridge = RIDGE * np.max(np.einsum("tii->ti", Hxx), axis=1)
        Hxx += ridge[:, None, None] * np.eye(3 * Jc)
        if n_groups == 1:
            P = _inverse(Hxx)                                              # (n, 3Jc, 3Jc)
        else:
            P = np.zeros_like(Hxx)
            for cols in groups:
                P[:, cols[:, None], cols[None, :]] = _inverse(
                    Hxx[:, cols[:, None], cols[None, :]])
        blocks = P.reshape(b - a, Jc, 3, Jc, 3)[:, np.arange(Jc), :, np.arange(Jc), :]
        marg[a:b, jsel] = blocks.transpose(1, 0, 2, 3)
        if nz:
            # the globals: a joint re-triangulated with the moved globals; where one
            # view is left (the other down-weighted), the frame's, bones and all
            G = -(P @ Hxz).reshape(b - a, Jc, 3, nz)
            G_all[a:b, jsel] = np.where(own[a:b, :, None, None], Gown[a:b], G)
    # the smoothness: each joint's chain of frames
    rows = None
    if cross_row.any():
        rows = _cross_rows(used, r, c, v, pt, flat, local_col, cross_row, J)
    if smooth is not None:
        extra = _smoothness_rows(problem, used, smooth, 0 if rows is None else rows[0].max() + 1)
        rows = extra if rows is None else tuple(np.concatenate([a, b]) for a, b in zip(rows, extra))
    if rows is not None and len(rows[0]):
        frame_marg = marg
        marg = _with_smoothness(marg, used, rows, J)
        # the noise correlated in time: the smoothed share widened by the residuals'
        # autocorrelation (each cell's four whitened rows, their component no point fits)
        res = np.zeros(n_rows)
        res[rhs_rows] = rhs
        e = np.full((Tg, J), np.nan)
        e[:, jsel] = epipolar_residuals(cell, Ad, res[lr_idx[rows_d]], Tg * Jc).reshape(Tg, Jc)
        person = np.zeros(J, np.int64)
        person[jsel] = group_of
        marg = marg * time_correlation_factor(e, frame_marg, marg, person)[..., None, None]
    glob = np.zeros((Tg, J, 3, 3))
    if nz and np.all(np.isfinite(Cz)):
        if body_gauge:
            G_all = _without_scale(G_all, points, used)
        glob = np.einsum("tjan,nm,tjbm->tjab", G_all, Cz, G_all)
    elif nz:
        glob[:] = np.nan
    cov = factor * marg + bias + glob
    cov[~used] = np.nan
    return cov


def _without_scale(G: np.ndarray, points: np.ndarray, used: np.ndarray) -> np.ndarray:
    """The globals' response ``G`` ``(T, J, 3, n)`` less its change of the body's size:
    ``G - X k^T``, ``k`` the relative change of the body's spread about each frame's
    centroid, ``sum (X - c) . (G - G_c) / sum |X - c|^2`` (a scale the gauge and the
    stature's rescale take back)."""
    w = used[..., None].astype(float)
    cnt = np.maximum(w.sum(1, keepdims=True), 1.0)
    X = np.where(used[..., None], points, 0.0)
    c = (X * w).sum(1, keepdims=True) / cnt
    Gw = G * w[..., None]
    Gc = Gw.sum(1, keepdims=True) / cnt[..., None]
    dX = (X - c) * w
    den = float(np.sum(dX ** 2))
    if den <= 0:
        return G
    k = np.einsum("tja,tjan->n", dX, (G - Gc) * w[..., None]) / den
    return G - X[..., None] * k[None, None, None, :]


def _bias_weights(r, kc, pt, flat, rhs_rows, rhs, n_rows: int, n_data: int, J: int,
                  is_point) -> np.ndarray:
    """``(n_rows,)`` the detector's bias variance of every reprojection row (whitened,
    per coordinate; 0 for the other rows): ``2 |m|^2``, ``m`` the mean whitened residual
    of the row's joint in the row's view over the video.

    A detector's per-joint bias that the frames share shows in the residuals' mean across
    the epipolar line (the two views split that inconsistency, so each residual is about
    half of it); along the line it is invisible, and taken as large as across. Under iid
    noise ``|m|^2`` is ``~2 / frames``."""
    w = np.zeros(n_rows)
    if n_data == 0:
        return w
    res = np.zeros(n_rows)
    res[rhs_rows] = rhs
    rows = np.arange(min(n_data, n_rows))
    joint = np.full(n_rows, -1)
    m = pt & (r < n_data)
    joint[r[m]] = flat[m] % J
    view = np.full(n_rows, -1)                   # the view: the largest global key it touches
    g = ~pt & (r < n_data)
    np.maximum.at(view, r[g], kc[g])
    pair = rows // 2
    fj = joint[0::2][:len(rows) // 2]
    fv = view[0::2][:len(rows) // 2]
    fr = res[rows].reshape(-1, 2)                                   # (factors, 2)
    ok = fj >= 0
    key = fj * (int(view.max()) + 2) + (fv + 1)
    uniq, inv = np.unique(key[ok], return_inverse=True)
    count = np.bincount(inv, minlength=len(uniq)).astype(float)
    mean = np.stack([np.bincount(inv, fr[ok, i], minlength=len(uniq)) for i in range(2)],
                    axis=1) / count[:, None]
    var = 2.0 * np.sum(mean ** 2, axis=1)
    per_factor = np.zeros(len(fr))
    per_factor[np.flatnonzero(ok)] = var[inv]
    w[rows] = per_factor[pair]
    return w


def _inverse(H: np.ndarray) -> np.ndarray:
    """Batched inverse of symmetric ``(n, k, k)`` blocks; NaN where singular."""
    out = np.full_like(H, np.nan)
    try:
        return np.linalg.inv(H)
    except np.linalg.LinAlgError:
        for i in range(len(H)):
            try:
                out[i] = np.linalg.inv(H[i])
            except np.linalg.LinAlgError:
                pass
        return out


def _smoothness_rows(problem: GraphProblem, used: np.ndarray, smooth: SmoothnessFactor,
                     first: int) -> tuple:
    """The whitened rows of ``smooth`` on every joint's track (its consecutive triples,
    :meth:`~mirrorgraph.factors.SmoothnessFactor.triples`), as :func:`_cross_rows`
    gives them: ``(row, chain index, joint, value, axis)``, rows numbered from ``first``."""
    fid = np.asarray(problem.rig.frame_ids, dtype=np.int64)
    rank = np.cumsum(used, axis=0) - 1
    parts = []
    for j in np.flatnonzero(used.any(0)):
        t = np.flatnonzero(used[:, j])
        tri = t[smooth.triples(fid[t])]                                        # (M, 3)
        if len(tri):
            parts.append((tri, j, smooth.coefficients(fid[tri]) / smooth.sigma))
    if not parts:
        return tuple(np.zeros(0, dtype=np.int64) for _ in range(5))
    idx, jj, cc = [], [], []
    for tri, j, coef in parts:
        idx.append(rank[tri, j])
        jj.append(np.full(tri.shape, j))
        cc.append(coef)
    idx, jj, cc = (np.concatenate(a) for a in (idx, jj, cc))                   # (M, 3)
    M = len(idx)
    # three rows a factor (x, y, z), each with one coordinate of its three points
    row = first + np.arange(3 * M).reshape(M, 3)[:, :, None].repeat(3, axis=2)   # (M, axis, k)
    axis = np.broadcast_to(np.arange(3)[None, :, None], (M, 3, 3))
    return (row.ravel(), np.broadcast_to(idx[:, None, :], (M, 3, 3)).ravel(),
            np.broadcast_to(jj[:, None, :], (M, 3, 3)).ravel(),
            np.broadcast_to(cc[:, None, :], (M, 3, 3)).ravel(), axis.ravel())


def _cross_rows(used: np.ndarray, r, c, v, pt, flat, local_col, cross_row: np.ndarray,
                J: int) -> tuple:
    """The linearised rows spanning several frames (a smoothness in the graph) as
    ``(row, chain index, joint, value, axis)`` per entry."""
    rank = np.cumsum(used, axis=0) - 1                    # a joint's index in its own chain
    sel = cross_row[r] & pt
    rs, fs, vs, axis = r[sel], flat[sel], v[sel], local_col[c[sel]]
    t, j = fs // J, fs % J
    return rs, rank[t, j], j, vs, axis


def _with_smoothness(marg: np.ndarray, used: np.ndarray, rows: tuple, J: int) -> np.ndarray:
    """Each joint's per-frame covariance ``marg`` ``(Tg, J, 3, 3)`` with the rows across
    frames ``rows`` (:func:`_cross_rows`) of its own chain (:func:`chain_marginals`)."""
    n = used.sum(0)
    N = int(n.max()) if n.size else 0
    if N == 0:
        return marg
    rs, idx, j, vs, axis = rows
    # a row spanning more than two chain steps (not the smoothness's consecutive triples)
    # or two joints is left out: dropping information keeps the covariance an upper bound
    nr = int(rs.max()) + 1
    lo = np.full(nr, np.iinfo(np.int64).max)
    hi = np.full(nr, -1)
    np.minimum.at(lo, rs, idx)
    np.maximum.at(hi, rs, idx)
    jl = np.full(nr, -1)
    jl[rs] = j
    same = np.ones(nr, bool)
    np.logical_and.at(same, rs, jl[rs] == j)
    good = (hi[rs] - lo[rs] <= 2) & same[rs]
    rs, idx, j, vs, axis = rs[good], idx[good], j[good], vs[good], axis[good]
    # H_s entries between the entries of one row: (joint, chain i, chain k, axis a, axis b)
    order = np.argsort(rs, kind="stable")
    rs, idx, j, vs, axis = rs[order], idx[order], j[order], vs[order], axis[order]
    bounds = np.flatnonzero(np.diff(rs)) + 1
    starts = np.concatenate([[0], bounds])
    counts = np.diff(np.concatenate([starts, [len(rs)]]))
    band = np.zeros((3, J, N, 3, 3))                 # H[i, i + k] for k = 0, 1, 2
    size = band.size
    width = int(counts.max()) if len(counts) else 0
    for p in range(width):
        for q in range(width):
            m = counts > max(p, q)
            ip, iq = starts[m] + p, starts[m] + q
            dk = idx[iq] - idx[ip]
            s = (dk >= 0) & (dk <= 2)
            ip, iq, dk = ip[s], iq[s], dk[s]
            at = np.ravel_multi_index((dk, j[ip], idx[ip], axis[ip], axis[iq]), band.shape)
            band += np.bincount(at, vs[ip] * vs[iq], minlength=size).reshape(band.shape)
    return _chain_solve(marg, used, band)


def _smoothness_band(used: np.ndarray, frame_ids, smooth: SmoothnessFactor
                     ) -> np.ndarray | None:
    """The information of ``smooth`` on every joint's track (its consecutive triples,
    :meth:`~mirrorgraph.factors.SmoothnessFactor.triples`) as the block band of each
    joint's chain, ``(3, J, N, 3, 3)``: ``H[i, i + k]`` for ``k = 0, 1, 2`` (``N`` the
    longest chain): the band :func:`_with_smoothness` builds from the rows, built
    directly (a factor's rows are its three coefficients times the identity); ``None``
    without a triple."""
    fid = np.asarray(frame_ids, dtype=np.int64)
    n = used.sum(0)
    N, J = (int(n.max()) if n.size else 0), used.shape[1]
    w = np.zeros((3, J, N))                             # the band's scalar (x I3) entries
    found = False
    for j in np.flatnonzero(n):
        t = np.flatnonzero(used[:, j])
        tri = smooth.triples(fid[t])                                          # (M, 3)
        if not len(tri):
            continue
        found = True
        c = smooth.coefficients(fid[t[tri]]) / smooth.sigma                   # (M, 3)
        i0 = tri[:, 0]                          # i0 distinct: no index twice in one sum
        for a in range(3):
            for b in range(a, 3):
                w[b - a, j, i0 + a] += c[:, a] * c[:, b]
    return w[..., None, None] * np.eye(3) if found else None


def _chain_solve(marg: np.ndarray, used: np.ndarray, band: np.ndarray,
                 info: np.ndarray | None = None) -> np.ndarray:
    """:func:`_with_smoothness` given the smoothness's block band ``(3, J, N, 3, 3)``
    (``info``: ``marg``'s inverse where known, else inverted here)."""
    J, N = band.shape[1:3]
    ok = np.isfinite(marg).all((-2, -1)) & used
    if info is None:
        info = np.zeros_like(marg)
        info[ok] = np.linalg.inv(marg[ok])
    diag, off1, off2 = band
    # the per-frame information on the diagonal, identity on the padding
    t_of = np.full((J, N), -1)
    for jj in range(J):
        tt = np.flatnonzero(used[:, jj])
        t_of[jj, :len(tt)] = tt
    has = t_of >= 0
    jj, kk = np.nonzero(has)
    diag[jj, kk] += info[t_of[jj, kk], jj]
    bad = ~has | ~ok[np.maximum(t_of, 0), np.arange(J)[:, None]]
    diag[bad] = np.eye(3)
    off1[bad] = 0.0
    off2[bad] = 0.0
    off1[:, :-1][bad[:, 1:]] = 0.0                 # H[i - 1, i] and H[i - 2, i] of a bad i
    off2[:, :-2][bad[:, 2:]] = 0.0
    C = chain_marginals(diag, off1, off2)
    out = np.array(marg)
    out[t_of[jj, kk], jj] = np.where(ok[t_of[jj, kk], jj][:, None, None], C[jj, kk], np.nan)
    return out


def chain_marginals(diag: np.ndarray, off1: np.ndarray, off2: np.ndarray,
                    group: int = CHAIN_GROUP, rhs: np.ndarray | None = None):
    """The diagonal ``3 x 3`` blocks of the inverse of block-banded information matrices.

    Each of ``B`` chains of ``N`` blocks has ``H[i, i] = diag[i]``, ``H[i, i + 1] =
    off1[i]``, ``H[i, i + 2] = off2[i]`` (and their transposes): the smoothness over a
    joint's consecutive estimates. Groups of ``g`` blocks (``g >= 2``) make it
    block-tridiagonal with ``3 g x 3 g`` blocks, whose inverse's diagonal blocks
    :func:`_tridiagonal_marginals` gives by cyclic reduction: every chain and every
    block of a level at once, ``log2(N / g)`` levels.

    Args:
        diag, off1, off2: ``(B, N, 3, 3)``; the entries past a chain's end are ignored
            (``off1[N-1]``, ``off2[N-2:]``).
        group: ``g``, blocks per group.
        rhs: ``(B, N, 3)``: also solve ``H x = rhs``.

    Returns:
        ``(B, N, 3, 3)`` the diagonal blocks of ``H^-1``; with ``rhs`` ``x`` ``(B, N, 3)``
        and them.
    """
    g = max(int(group), 2)
    Bn, N = diag.shape[:2]
    if Bn > CHAIN_BATCH:
        parts = [chain_marginals(diag[b:b + CHAIN_BATCH], off1[b:b + CHAIN_BATCH],
                                 off2[b:b + CHAIN_BATCH], g,
                                 None if rhs is None else rhs[b:b + CHAIN_BATCH])
                 for b in range(0, Bn, CHAIN_BATCH)]
        if rhs is None:
            return np.concatenate(parts)
        return tuple(np.concatenate(p) for p in zip(*parts))
    M = -(-N // g)
    pad = M * g - N

    def grouped(x: np.ndarray, fill: np.ndarray, valid: int) -> np.ndarray:
        """``(M, B, g, 3, 3)``: the chain's blocks by group, zero past ``valid``."""
        x = np.concatenate([x, np.broadcast_to(fill, (Bn, pad, 3, 3))], axis=1)
        x = np.moveaxis(x.reshape(Bn, M, g, 3, 3), 0, 1)
        keep = (np.arange(M * g) < valid).reshape(M, 1, g, 1, 1)
        return x * keep

    d = grouped(diag, np.eye(3), M * g)
    o1, o2 = grouped(off1, np.zeros((3, 3)), N - 1), grouped(off2, np.zeros((3, 3)), N - 2)
    # H as (M, B) blocks within a group (D) and to the next group (U)
    D = np.zeros((M, Bn, g, 3, g, 3))
    U = np.zeros((M, Bn, g, 3, g, 3))
    for i in range(g):
        D[:, :, i, :, i, :] = d[:, :, i]
        for k, o in ((1, o1), (2, o2)):
            if i + k < g:
                D[:, :, i, :, i + k, :] = o[:, :, i]
                D[:, :, i + k, :, i, :] = np.swapaxes(o[:, :, i], -1, -2)
            else:
                U[:, :, i, :, i + k - g, :] = o[:, :, i]
    b = None
    if rhs is not None:
        b = np.concatenate([rhs, np.zeros((Bn, pad, 3))], axis=1).reshape(Bn, M, 3 * g)
        b = np.moveaxis(b, 0, 1)[..., None]                                  # (M, B, 3g, 1)
    C = _tridiagonal_marginals(D.reshape(M, Bn, 3 * g, 3 * g), U.reshape(M, Bn, 3 * g, 3 * g),
                               b=b)
    C, x = C if rhs is not None else (C, None)
    C = C.reshape(M, Bn, g, 3, g, 3)
    out = np.stack([C[:, :, i, :, i, :] for i in range(g)], axis=2)        # (M, B, g, 3, 3)
    marg = np.moveaxis(out, 1, 0).reshape(Bn, M * g, 3, 3)[:, :N]
    if rhs is None:
        return marg
    return np.moveaxis(x[..., 0], 1, 0).reshape(Bn, M * g, 3)[:, :N], marg


def _tridiagonal_marginals(D: np.ndarray, U: np.ndarray, off: bool = False,
                           b: np.ndarray | None = None):
    """The diagonal blocks of the inverse of symmetric positive definite block-tridiagonal
    matrices, by cyclic reduction (Golub and Van Loan, *Matrix Computations*, 4th ed.,
    sec. 4.5.4) run backwards for the covariance.

    The odd blocks ``i`` are eliminated, every one at once: the even ones keep
    ``D_e - U_{e-1}^T D_{e-1}^-1 U_{e-1} - U_e D_{e+1}^-1 U_e^T`` and couple to the next
    even one by ``-U_e D_{e+1}^-1 U_{e+1}``, a system half the size, solved the same way.
    Given the covariance of an odd block's two neighbours ``l, r`` (their blocks and
    ``Sigma_lr``), its own is ``D_i^-1 + A Sigma_nb A^T`` and its cross-covariances
    ``-A Sigma_nb``, ``A = D_i^-1 [H_il, H_ir]``; with a right-hand side ``b`` the
    reduction carries it along and its solution is ``x_i = D_i^-1 b_i - A x_nb``.

    Args:
        D: ``(m, B, s, s)`` the diagonal blocks of ``B`` matrices; U: ``(m, B, s, s)``
            ``H[k, k + 1]`` (``U[m - 1]`` zero).
        off: also return ``Sigma[k, k + 1]`` ``(m - 1, B, s, s)``.
        b: ``(m, B, s, 1)``: also solve ``H x = b``.

    Returns:
        ``(m, B, s, s)`` the inverse's diagonal blocks, with ``off`` the next ones, with
        ``b`` the solution ``(m, B, s, 1)`` (in that order).
    """
    m = len(D)
    if m == 1:
        S = np.linalg.inv(D)
        out = (S,) + ((np.zeros((0,) + D.shape[1:]),) if off else ()) + (
            (S @ b,) if b is not None else ())
        return out if len(out) > 1 else S
    tr = lambda x: np.swapaxes(x, -1, -2)                                # noqa: E731
    mo, me = m // 2, m - m // 2
    nr = me - 1                                       # odd blocks with a right neighbour
    Di = np.linalg.inv(D[1::2])
    Ul = U[0:2 * mo:2]                                # H[i - 1, i], odd i
    R = U[1::2][:nr]                                  # H[i, i + 1]
    Al, Ar = Di @ tr(Ul), Di[:nr] @ R
    Dc = D[0::2].copy()
    Dc[:mo] -= Ul @ Al
    Dc[1:] -= tr(R) @ Ar
    Uc = np.zeros_like(Dc)
    Uc[:nr] = -(Ul[:nr] @ Ar)
    bc = None
    if b is not None:
        Db = Di @ b[1::2]                                 # D_i^-1 b_i, odd i
        bc = b[0::2].copy()
        bc[:mo] -= Ul @ Db
        bc[1:] -= tr(R) @ Db[:nr]
    Sc, Oc, *xc = _tridiagonal_marginals(Dc, Uc, off=True, b=bc)
    Sil = -(Al @ Sc[:mo])                             # Sigma[i, i - 1]
    Sil[:nr] -= Ar @ tr(Oc)
    Sir = -(Al[:nr] @ Oc + Ar @ Sc[1:])               # Sigma[i, i + 1]
    Si = Di - Sil @ tr(Al)
    Si[:nr] -= Sir @ tr(Ar)
    S = np.empty_like(D)
    S[0::2], S[1::2] = Sc, Si
    out = (S,)
    if off:
        O = np.empty((m - 1,) + D.shape[1:])
        O[0::2], O[1::2] = tr(Sil), Sir
        out += (O,)
    if b is not None:
        x = np.empty_like(b)
        x[0::2] = xc[0]
        xi = Db - Al @ xc[0][:mo]
        xi[:nr] -= Ar @ xc[0][1:]
        x[1::2] = xi
        out += (x,)
    return out if len(out) > 1 else S


# --------------------------------------------------------------------------- triangulated
def triangulated_covariance(projections: Callable[[np.ndarray], list[np.ndarray]],
                            Cz: np.ndarray | None, points: np.ndarray, pixels: list,
                            masks: list, pixel_sigma: float, step: float = 1e-6,
                            frames: np.ndarray | None = None, rays: bool = True,
                            weights: list | None = None, ridge: np.ndarray | None = None
                            ) -> np.ndarray:
    """The covariance of points triangulated from two views or more, the globals' share
    included.

    The rays' share is :func:`~mirrorgraph.geometry.triangulation_covariance`; a change
    ``dz`` of the globals moves the least-squares point by ``G dz``,
    ``G = -(J_x^T J_x)^-1 J_x^T J_z`` (the implicit function of the normal equations,
    ``J_x``, ``J_z`` the reprojection's derivatives in the point and in ``z``, the
    latter by central differences of the views' matrices), which adds ``G C_z G^T``.

    Args:
        projections: ``z`` ``(n,)`` -> the ``V`` views' ``(3, 4)`` world-to-pixel matrices
            (``z = 0``: the solution).
        Cz: ``(n, n)`` the globals' covariance (``None``: the rays alone).
        points: ``(N, 3)`` the triangulated points; pixels: ``V`` arrays ``(N, 2)``;
            masks: ``V`` bool ``(N,)``.
        pixel_sigma: the pixels' std.
        step: the central differences' step in ``z``.
        frames: ``(N,)`` each point's frame: with them the change of the body's size is
            taken out of the globals' response (a metric scale set by the subject's
            stature: :func:`graph_joints_covariance`); ``None``: kept (the distance the
            unit).
        rays: with the rays' share; ``False``: the globals' share alone (``G C_z G^T``,
            zero without ``Cz``).
        weights: ``V`` arrays ``(N,)``, each observation's weight in the globals'
            response (a robust kernel's, :func:`~mirrorgraph.factors.reprojection.
            kernel_weights`); ``None``: 1.
        ridge: ``(N,)`` added to each point's information in the globals' response
            (the graph's :data:`RIDGE`), which then covers points one view sees too
            (their response across the ray); with ``rays=False`` only.

    Returns:
        ``(N, 3, 3)``; NaN where fewer than two views see a point.
    """
    X = np.asarray(points, float).reshape(-1, 3)
    P0 = projections(np.zeros(0 if Cz is None else len(Cz)))
    alone = not rays and Cz is not None and len(Cz) and len(X) and np.all(np.isfinite(Cz))
    # the globals' share alone: where the rays determine a point, from the loop's information
    cov = None if alone else geo.triangulation_covariance(P0, X, masks, pixel_sigma)
    if not rays and not alone:
        cov = np.where(np.isfinite(cov), 0.0, np.nan)
    if Cz is None or not len(Cz) or not len(X):
        return cov
    if not np.all(np.isfinite(Cz)):
        cov[:] = np.nan
        return cov
    n = len(Cz)
    Xs = np.nan_to_num(X)
    Xt = Xs.T                                                    # (3, N)
    N = len(X)
    info = np.zeros((6, N))                                      # xx, yy, zz, xy, xz, yz
    rhs = np.zeros((3, n, N))
    moved = []                                  # per k: every view's matrix at +-step
    for k in range(n):
        e = np.zeros(n)
        e[k] = step
        moved.append((projections(e), projections(-e)))
    with np.errstate(divide="ignore", invalid="ignore"):
        for vi, (P, m) in enumerate(zip(P0, masks)):
            m = np.asarray(m, bool).reshape(-1)
            y = P[:, :3] @ Xt + P[:, 3:4]
            inv = np.where(m, 1.0 / y[2], 0.0)
            jx = (P[0, :3, None] - P[2, :3, None] * (y[0] * inv)) * inv       # (3, N)
            jy = (P[1, :3, None] - P[2, :3, None] * (y[1] * inv)) * inv
            if weights is not None:                  # w J^T J and w J^T J_z
                root = np.sqrt(np.asarray(weights[vi], float).reshape(-1))
                jx, jy = jx * root, jy * root
            for c, (a, b) in enumerate(geo.SYM3):
                info[c] += jx[a] * jx[b] + jy[a] * jy[b]
            for k in range(n):
                Pp, Pm = moved[k][0][vi], moved[k][1][vi]
                if np.array_equal(Pp, Pm):      # a view the globals do not move (the camera)
                    continue
                yp, ym = Pp[:, :3] @ Xt + Pp[:, 3:4], Pm[:, :3] @ Xt + Pm[:, 3:4]
                dx = np.where(m, (yp[0] / yp[2] - ym[0] / ym[2]) / (2 * step), 0.0)
                dy = np.where(m, (yp[1] / yp[2] - ym[1] / ym[2]) / (2 * step), 0.0)
                if weights is not None:
                    dx, dy = dx * root, dy * root
                rhs[:, k] += jx * dx + jy * dy
    if ridge is not None:
        info[:3] += np.asarray(ridge, float)
    adj, det = geo.sym3_adjugate(info)
    if cov is None:                      # as geo.triangulation_covariance decides it
        seen = (np.sum([np.asarray(m, bool).reshape(-1) for m in masks], axis=0)
                >= (2 if ridge is None else 1))
        ok = seen & np.isfinite(info).all(0)
        ok[ok] = det[ok] > 0
        cov = np.where(ok[:, None, None], 0.0, np.nan) * np.ones((1, 3, 3))
    good = np.isfinite(cov).all((1, 2))
    G = np.zeros((3, n, N))
    with np.errstate(divide="ignore", invalid="ignore"):
        G[:, :, good] = -np.stack([geo.sym3_product(adj[:, good], rhs[:, k, good])
                                   for k in range(n)], axis=1) / det[good]
    if frames is not None and good.any():
        Gn = G.transpose(2, 0, 1)[good]                          # (M, 3, n)
        rows, inv = np.unique(np.asarray(frames)[good], return_inverse=True)
        cols = np.zeros(int(good.sum()), dtype=np.int64)
        order = np.argsort(inv, kind="stable")
        start = np.searchsorted(inv[order], np.arange(len(rows)))
        cols[order] = np.arange(len(order)) - start[inv[order]]
        width = int(cols.max()) + 1
        Gp = np.zeros((len(rows), width, 3, n))
        Xp = np.zeros((len(rows), width, 3))
        up = np.zeros((len(rows), width), bool)
        Gp[inv, cols], Xp[inv, cols], up[inv, cols] = Gn, Xs[good], True
        G[:, :, good] = _without_scale(Gp, Xp, up)[inv, cols].transpose(1, 2, 0)
    GC = np.einsum("ikN,kl->ilN", G, np.asarray(Cz, float))
    share = np.einsum("ikN,jkN->Nij", GC, G)
    return cov + share


def mirror_plane_projections(K: np.ndarray, normal: np.ndarray, distance: float
                             ) -> Callable[[np.ndarray], list[np.ndarray]]:
    """``z`` -> the real camera's and the mirror view's ``(3, 4)`` matrices, the plane
    moved by ``z`` ``(3,)`` in GTSAM's tangent of :class:`gtsam.OrientedPlane3` (the
    coordinates of the solve's plane covariance); ``z`` of length 0: the plane as is."""
    K = np.asarray(K, float)
    plane = plane_to_gtsam(normal, distance)
    P_real = geo.camera_projection(K, np.eye(4))

    def views(z: np.ndarray) -> list[np.ndarray]:
        z = np.asarray(z, float)
        n, d = (plane_from_gtsam(plane.retract(z)) if z.size == 3
                else (np.asarray(normal, float), float(distance)))
        return [P_real, geo.mirror_projection(K, np.eye(4), n, d)]

    return views


# --------------------------------------------------------------------------- noise in time
#: The longest lag of the residuals' autocorrelation :func:`time_correlation_factor` reads
#: (frames; also at most ``SMOOTHER_LAGS_PER_FRAME`` times the widest smoother's frames).
MAX_LAG = 512

#: Lags read per frame of the smoother's width (``1 / w_0``): its equivalent kernel's
#: autocorrelation is below 1e-3 of its peak beyond ~4 widths.
SMOOTHER_LAGS_PER_FRAME = 6


def epipolar_residuals(cell: np.ndarray, A: np.ndarray, r: np.ndarray, n_cells: int
                       ) -> np.ndarray:
    """``(n_cells,)`` each joint-frame's residual no point can fit: its four whitened
    reprojection rows' (two views, ``x`` and ``y``) residual ``r`` along the left null
    vector of their ``4 x 3`` Jacobian ``A``.

    Moving the point moves the rows' residual within the Jacobian's column space, so this
    component is the detector's noise itself (first order), whatever the smoothness did
    to the point: its disagreement across the epipolar line, in the whitened rows' unit.
    The null vector is the four signed ``3 x 3`` minors (a generalised cross product),
    continuous in ``A``, so its sign is kept from frame to frame.

    Args:
        cell: ``(m,)`` each row's joint-frame; A: ``(m, 3)`` its point Jacobian; r:
            ``(m,)`` its whitened residual (either sign, the same for every row).
        n_cells: the number of joint-frames.

    Returns:
        NaN where a joint-frame has not exactly four rows (one view; more than two).
    """
    out = np.full(n_cells, np.nan)
    cell = np.asarray(cell, np.int64)
    if not len(cell):
        return out
    order = np.argsort(cell, kind="stable")
    cs = cell[order]
    four = (np.bincount(cell, minlength=n_cells) == 4)[cs]
    if not four.any():
        return out
    Af = np.asarray(A, float)[order][four].reshape(-1, 4, 3)
    rf = np.asarray(r, float)[order][four].reshape(-1, 4)
    out[cs[four][::4]] = null_component(Af, rf)
    return out


def null_component(A: np.ndarray, r: np.ndarray) -> np.ndarray:
    """``(k,)`` the residuals ``r`` ``(k, 4)`` along the unit left null vector of their
    Jacobians ``A`` ``(k, 4, 3)`` (:func:`epipolar_residuals`): the signed ``3 x 3``
    minors, each a triple product; NaN where ``A`` has no single null vector."""
    a0, a1, a2, a3 = (A[:, i] for i in range(4))
    c23, c01 = np.cross(a2, a3), np.cross(a0, a1)
    minors = np.stack([np.einsum("ki,ki->k", a1, c23), -np.einsum("ki,ki->k", a0, c23),
                       np.einsum("ki,ki->k", c01, a3), -np.einsum("ki,ki->k", c01, a2)], 1)
    norm = np.linalg.norm(minors, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        e = np.einsum("ki,ki->k", minors, r) / norm
    e[~(norm > 0)] = np.nan
    return e


@lru_cache(maxsize=1)
def _smoother_kernels(max_lag: int = MAX_LAG, n_grid: int = 120, size: int = 8192
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The equivalent kernel of a chain smoothed by a second-difference prior, over a
    grid of its strengths: ``(n_grid,)`` each one's width ``1 / w_0`` (the variance over
    a lone frame's over the smoothed one's) and ``(n_grid, max_lag)`` its autocorrelation
    ``a_k = sum_t w_t w_{t+k}`` at lags ``1..max_lag``, unit per-frame information.

    A chain of frames with information 1 each and a prior ``lambda |x_{t-1} - 2 x_t +
    x_{t+1}|^2`` is a linear filter ``x = w * y`` with the transfer function ``1 / (1 +
    lambda (2 - 2 cos omega)^2)`` (away from its ends; the discrete cubic smoothing spline,
    Silverman 1984's equivalent kernel), whose posterior variance is ``w_0``; its kernel
    and the kernel's autocorrelation are inverse FFTs."""
    omega = 2.0 * np.pi * np.fft.rfftfreq(size)
    lam = np.logspace(-3, 10, n_grid)
    G = 1.0 / (1.0 + lam[:, None] * (2.0 - 2.0 * np.cos(omega)) ** 2)
    w0 = np.fft.irfft(G, n=size, axis=1)[:, 0]
    acf = np.fft.irfft(G * G, n=size, axis=1)[:, 1:max_lag + 1]
    return 1.0 / w0, acf


def residual_autocorrelation(e: np.ndarray, groups: np.ndarray, max_lag: int) -> np.ndarray:
    """``(P, max_lag)`` the autocorrelation of the residual series ``e`` ``(T, J)`` (NaN
    where none) at lags ``1..max_lag`` frames, each joint's series less its own mean (its
    bias, which :func:`_bias_weights` holds), pooled over the joints of each group
    (``groups`` ``(J,)`` in ``0..P-1``): the sum of the lagged products over the sum of
    squares, each over its own count of pairs (the lagged sums by FFT, zero-padded: every
    lag at once). A group without a pair at a lag gets 0."""
    e = np.asarray(e, float)
    T, J = e.shape
    P = int(groups.max()) + 1 if len(groups) else 0
    ok = np.isfinite(e)
    cnt = ok.sum(0)
    mean = np.where(cnt > 0, np.nansum(e, 0) / np.maximum(cnt, 1), 0.0)
    x = np.where(ok, e - mean, 0.0)
    onehot = np.zeros((J, P))
    onehot[np.arange(J), groups] = 1.0
    size = 1 << int(np.ceil(np.log2(2 * T)))
    F = np.fft.rfft(np.concatenate([x, ok.astype(float)], 1), n=size, axis=0)
    lagged = np.fft.irfft(F * F.conj(), n=size, axis=0)[:max_lag + 1]     # (L + 1, 2J)
    s, n = lagged[:, :J] @ onehot, np.rint(lagged[:, J:]) @ onehot          # (L + 1, P)
    with np.errstate(divide="ignore", invalid="ignore"):
        var = s[0] / np.maximum(n[0], 1)
        rho = np.where((n[1:] > 0) & (var > 0), s[1:] / np.maximum(n[1:], 1) / var, 0.0)
    out = np.zeros((P, max_lag))
    out[:, :rho.shape[0]] = rho.T
    return out


def time_correlation_factor(e: np.ndarray, frame_cov: np.ndarray, smoothed_cov: np.ndarray,
                            groups: np.ndarray | None = None) -> np.ndarray:
    """``(T, J)`` the factor on each smoothed joint's covariance for noise correlated in
    time.

    A smoothness over a joint's frames averages its per-frame estimates as if their noise
    were independent, and its covariance shrinks by the frames it averages; a detector's
    noise that persists from frame to frame does not average out. The smoothed estimate is
    a linear filter ``sum_t w_t y_t`` of the per-frame ones, so its variance under noise of
    autocorrelation ``rho_k`` is ``sum_{t,s} w_t w_s rho_{t-s}`` in the per-frame unit
    (the long-run variance of a filtered series: Bartlett 1946; the lag window the
    filter's own kernel, as the Newey and West 1987 estimator's is Bartlett's); the
    covariance the graph states, ``w_0`` (``1 / n``, ``n`` the per-frame covariance's trace
    over the smoothed one's), gains the cross terms:

        factor = 1 + 2 n sum_{k >= 1} a_k(n) rho_k,   clipped to [1, n]

    ``a_k(n)`` the autocorrelation of the smoother's equivalent kernel of width ``n``
    (:func:`_smoother_kernels`), ``rho_k`` the residuals' own (:func:`residual_
    autocorrelation` of :func:`epipolar_residuals`, a component of the noise no point
    fits). Independent noise leaves 1 up to the pooled autocorrelation's sampling noise;
    noise fully correlated gives ``n``, the per-frame covariance again. Vectorised: a few
    milliseconds for a thousand frames.

    Args:
        e: ``(T, J)`` the residual series (NaN where none).
        frame_cov, smoothed_cov: ``(T, J, 3, 3)`` each joint's covariance in its frame
            alone and smoothed.
        groups: ``(J,)`` the joints pooled for the autocorrelation (a person's, in
            ``0..P-1``); ``None``: every joint together.

    Returns:
        ``(T, J)``; 1 where either covariance is not finite.
    """
    e = np.asarray(e, float)
    T, J = e.shape
    groups = np.zeros(J, np.int64) if groups is None else np.asarray(groups, np.int64)
    tf = np.trace(np.asarray(frame_cov, float), axis1=-2, axis2=-1)
    ts = np.trace(np.asarray(smoothed_cov, float), axis1=-2, axis2=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        n = tf / ts
    good = np.isfinite(n) & (ts > 0)
    out = np.ones((T, J))
    if not good.any() or T < 2:
        return out
    widths, acf = _smoother_kernels()
    n = np.clip(np.where(good, n, 1.0), 1.0, widths[-1])
    lags = max(int(min(MAX_LAG, T - 1, np.ceil(SMOOTHER_LAGS_PER_FRAME * n[good].max()))), 1)
    rho = residual_autocorrelation(e, groups, lags)                    # (P, lags)
    table = 1.0 + 2.0 * widths[:, None] * (acf[:, :lags] @ rho.T)      # (grid, P)
    # linear in the width's logarithm between the grid's two kernels about it
    f = np.ones((T, J))
    for g in np.unique(groups):
        cols = groups == g
        f[:, cols] = np.interp(np.log(n[:, cols]), np.log(widths), table[:, g])
    return np.where(good, np.clip(f, 1.0, n), 1.0)


@lru_cache(maxsize=4)
def fixed_lag_kernels(lag: int, max_lag: int = MAX_LAG, n_grid: int = 120, size: int = 4096
                      ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_smoother_kernels` of a filter that has seen ``lag`` frames after the one
    it gives (0: the Kalman filter's newest frame; the live run's fixed-lag smoother):
    the batch maximum a posteriori over the frames up to ``lag`` after it, which the
    Kalman filter and its fixed-lag smoother give exactly (Sarkka 2013, ch. 8), its
    kernel the row of ``(I + lambda D^T D)^-1`` of a ``size``-frame chain ending ``lag``
    frames after it (``D`` the second differences; a banded solve per strength)."""
    from scipy.linalg import solveh_banded

    lam = np.logspace(-3, 10, n_grid)
    t = size - 1 - int(lag)
    widths = np.empty(n_grid)
    acf = np.empty((n_grid, max_lag))
    d = np.ones(size)
    # D^T D's bands (upper form): diagonal 1 5 6 ... 6 5 1, first -2 -4 ... -4 -2, second 1
    d0 = np.full(size, 6.0)
    d0[[0, -1]], d0[[1, -2]] = 1.0, 5.0
    d1 = np.full(size, -4.0)
    d1[[1, -1]] = -2.0
    d2 = np.ones(size)
    e = np.zeros(size)
    e[t] = 1.0
    for i, lm in enumerate(lam):
        ab = np.stack([lm * d2, lm * d1, d + lm * d0])
        ab[0, :2] = 0.0
        ab[1, 0] = 0.0
        w = solveh_banded(ab, e)
        widths[i] = 1.0 / w[t]
        F = np.fft.rfft(w, n=2 * size)
        acf[i] = np.fft.irfft(F * F.conj(), n=2 * size)[1:max_lag + 1]
    return widths, acf


def rays_time_correlation_factor(views: list[np.ndarray], points: np.ndarray, pixels: list,
                                 t: np.ndarray, j: np.ndarray, frame_cov: np.ndarray,
                                 smoothed_cov: np.ndarray) -> np.ndarray:
    """:func:`time_correlation_factor` of points triangulated from two views and smoothed
    over their frames (the completion's joints, :func:`mirrorgraph.completion.
    smooth_tracks`): the residual series from the points' own two rays.

    Args:
        views: the two views' ``(3, 4)`` world-to-pixel matrices.
        points: ``(n, 3)`` the points at joint-frames ``t``, ``j`` ``(n,)``; pixels: two
            ``(n, 2)`` arrays, their observations in each view.
        frame_cov, smoothed_cov: ``(T, J, 3, 3)`` the covariances in each frame alone and
            smoothed (NaN where none).

    Returns:
        ``(T, J)``, 1 where either covariance is not finite.
    """
    T, J = np.shape(frame_cov)[:2]
    X = np.asarray(points, float)
    A, r = [], []
    for P, uv in zip(views, pixels):
        y = X @ P[:, :3].T + P[:, 3]
        p = y[:, :2] / y[:, 2:]
        r.append(p - np.asarray(uv, float))
        A.append((P[None, :2, :3] - p[:, :, None] * P[None, 2:3, :3]) / y[:, 2, None, None])
    e = np.full((T, J), np.nan)
    e[t, j] = null_component(np.concatenate(A, 1), np.concatenate(r, 1))
    return time_correlation_factor(e, frame_cov, smoothed_cov)
