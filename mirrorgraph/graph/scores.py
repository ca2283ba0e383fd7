"""The scores of the cluster-robust uncertainty: each joint's Schur complement and reduced score.

The estimate ``theta`` (the globals in reduced coordinates: the planes, the
estimated camera poses) solves ``sum_p s_p(theta) = 0``, ``s_p`` the score of joint
``p`` (one joint in one frame) once its own position is eliminated: with the
linearised, whitened reprojection rows of that joint ``[A_p B_p] (dX, dtheta) = b_p``,

    S_p = B_p^T B_p - B_p^T A_p (A_p^T A_p)^-1 A_p^T B_p        (its Schur complement)
    s_p = B_p^T b_p - B_p^T A_p (A_p^T A_p)^-1 A_p^T b_p        (its reduced score).

With the bone lengths a variable (an estimated focal length) the bones couple a
frame's joints, and each frame's joints are eliminated together
(:func:`frame_scores`); else joint by joint (:func:`joint_scores`). The
:class:`JointScores` they return are what the sandwich (:mod:`.sandwich`), the
headline figures (:mod:`.uncertainty`) and the sensitivity report
(:mod:`.sensitivity`) are made of. Whitened units (the reprojection rows divided by
the pixel sigma, the robust kernel's weights applied).

For :func:`joint_scores` the rows are the reprojection factors alone (the body
priors are not data): the Schur complements ignore the priors' pull on the joints,
which the benchmarks show changes the mirror little (``bench/RESULTS_ablation.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from .priors import intrinsics_prior_sigmas
from .problem import GraphProblem, point_keys
from .reduction import mirror_reduction

__all__ = ["JointScores", "joint_scores", "frame_scores", "scale_direction",
           "intrinsics_prior_spread"]


@dataclass
class JointScores:
    """Each estimated joint's Schur complement and reduced score on the globals.

    Attributes:
        frames: ``(N,)`` frame row of each joint; joints: ``(N,)`` its joint index.
        clusters: ``(N,)`` its left/right pair (the lower index of the joint and its
            mirror image in the skeleton).
        scores: ``(N, n)`` reduced scores ``s_p`` (whitened; ``n`` reduced coordinates).
        frame_info: ``(T, n, n)`` the Schur complements summed per frame row.
        joint_info: ``(J, n, n)`` the same per joint.
        z_keys: ``(key, dim)`` of the reduced coordinates (as
            :attr:`~.optimizer.GlobalReduction.z_keys`).
        gauge: ``(n,)`` the scale direction (:func:`scale_direction`): the reprojection
            alone does not fix it.
        prior_information: ``(n, n)`` the information of the factors on the globals
            alone (the length-only priors, a focal length's prior; :func:`frame_scores`),
            ``None`` for :func:`joint_scores` of the reprojection alone.
        joint_clusters: the joints' scores are independent across joints within a
            frame, so that the joint-pair clusters apply (:func:`joint_scores`); not
            where the bones couple a frame's joints (:func:`frame_scores`: the time
            figures alone).
        row_info: ``(N, n, n)`` each joint's own Schur complement ``S_p``, kept where the
            scores must later be moved to other globals (:meth:`moved`), else ``None``.
        prior_spread: ``(n, n)`` the information of the priors that stand for an
            unknown value drawn from a population (an estimated camera's focal length
            and principal point about their guess, :func:`~.priors.intrinsics_prior`):
            the spread of that value is added to the sandwich's meat
            (:func:`~.sandwich.sandwich`), since the scores do not contain it; ``None``: none.
        prior_floor: ``(n,)`` the least variance of each intrinsic's coordinate (of
            :attr:`prior_spread`; 0: none), in its unit squared (px^2): where the data
            do not determine a focal length its prior's, where two estimates of it from
            the same data disagree their difference squared
            (:func:`mirrorgraph.graph.solve.floor_focal`); ``None``: none.
        prior_cap: ``(n,)`` the most variance of each intrinsic's coordinate about its
            estimate (0: the prior's variance): the prior's variance plus the squared
            distance of the estimate from the prior's centre, the expected squared error
            of an estimate the data do not determine when the truth is drawn from the prior
            (:func:`~.marginals.floor_focal`); ``None``: the prior's.
        bias_score: ``(n,)`` the reduced score of the bones' curvature bias
            (:func:`frame_scores`): the estimate's first-order bias is
            ``H^-1 bias_score``, whose outer product every figure of :func:`~.sandwich.sandwich`
            holds (an error no std of the noise sees); ``None``: not computed.
        added_cov: ``(n, n)`` a covariance every figure of :func:`~.sandwich.sandwich` adds: what
            globals solved elsewhere and held here bring (a long video's chunks hold the
            intrinsics its subset estimated, :mod:`.chunked`); ``None``: none.
    """

    frames: np.ndarray
    joints: np.ndarray
    clusters: np.ndarray
    scores: np.ndarray
    frame_info: np.ndarray
    joint_info: np.ndarray
    z_keys: list
    gauge: np.ndarray | None = None
    prior_information: np.ndarray | None = None
    joint_clusters: bool = True
    row_info: np.ndarray | None = None
    prior_spread: np.ndarray | None = None
    prior_floor: np.ndarray | None = None
    prior_cap: np.ndarray | None = None
    bias_score: np.ndarray | None = None
    added_cov: np.ndarray | None = None

    @property
    def information(self) -> np.ndarray:
        """``(n, n)`` ``H = sum_p S_p`` (plus :attr:`prior_information`)."""
        H = self.frame_info.sum(0)
        return H if self.prior_information is None else H + self.prior_information

    def moved(self, z: np.ndarray) -> np.ndarray:
        """``(N, n)`` the scores after a step ``z`` (``(n,)``, reduced coordinates) of the
        globals, the joints re-eliminated: ``s_p - S_p z`` (first order)."""
        return self.scores - np.einsum("nab,b->na", self.row_info, np.asarray(z, float))


def joint_scores(problem: GraphProblem, values: gtsam.Values,
                 keep_rows: bool = False, bias_pixel_sigma: float | None = None) -> JointScores:
    """The Schur complement and reduced score of every joint of ``problem`` at ``values``.

    Where the bone lengths are a variable of the graph (an estimated focal length,
    which only the bones determine) this is :func:`frame_scores`.

    The reprojection factors are linearised by GTSAM (whitened, the robust kernel's
    weights applied), read as one sparse Jacobian, and reduced joint by joint in
    numpy: every factor has two rows and sees one joint and at most one pose.

    Args:
        problem: the solved graph; values: its solution.
        keep_rows: keep each joint's Schur complement (:attr:`JointScores.row_info`).
        bias_pixel_sigma: the pixel noise (px) of the bones' curvature bias where the
            bone lengths are a variable (:func:`frame_scores`); ``None``: not computed.

    Returns:
        :class:`JointScores` over the reduced coordinates of
        :func:`~.reduction.mirror_reduction` (planes, estimated camera poses).
    """
    if problem.length_key is not None:
        return frame_scores(problem, values, bias_pixel_sigma)
    red = mirror_reduction(problem, distance_gauge=None)
    T, J = problem.used.shape
    gfg = problem.reprojection.linearize(values)
    trip = np.asarray(gfg.sparseJacobian_(), dtype=float)                     # (3, nnz)
    rows, cols, vals = trip[0].astype(np.int64) - 1, trip[1].astype(np.int64) - 1, trip[2]
    keys = np.sort(np.asarray(gfg.keyVector(), dtype=np.uint64))
    dims = _dims(keys)
    offsets = np.concatenate([[0], np.cumsum(dims)])
    b_col = offsets[-1]
    key_of_col = np.repeat(np.arange(len(keys)), dims)
    local_of_col = np.arange(b_col) - np.repeat(offsets[:-1], dims)
    is_point = _chars(keys) == ord("x")
    # the basis: graph globals (virtual poses, cameras in the graph) -> z
    Tb = red.basis(values)
    row_of_key, off = {}, 0
    for k, d in red.graph_keys:
        row_of_key[int(k)] = off
        off += d
    nf = problem.reprojection.size()
    A = np.zeros((nf, 2, 3))
    Bg = np.zeros((nf, 2, Tb.shape[0]))
    b = np.zeros((nf, 2))
    point_of_factor = np.full(nf, -1, dtype=np.int64)
    f, r = rows // 2, rows % 2
    last = cols == b_col
    b[f[last], r[last]] = vals[last]
    rest = ~last
    kc = key_of_col[cols[rest]]
    lc = local_of_col[cols[rest]]
    fr, rr, vr = f[rest], r[rest], vals[rest]
    pt = is_point[kc]
    A[fr[pt], rr[pt], lc[pt]] = vr[pt]
    point_of_factor[fr[pt]] = kc[pt]
    glob_row = np.full(len(keys), -1, dtype=np.int64)
    for k, off in row_of_key.items():
        glob_row[np.searchsorted(keys, np.uint64(k))] = off
    gr = glob_row[kc[~pt]]
    ok = gr >= 0
    Bg[fr[~pt][ok], rr[~pt][ok], gr[ok] + lc[~pt][ok]] = vr[~pt][ok]
    B = Bg @ Tb                                                                  # (nf, 2, nz)
    # per joint: normal equations of its rows, then its Schur complement and score
    point_index = np.full(len(keys), -1, dtype=np.int64)
    pk = np.flatnonzero(is_point)
    point_index[pk] = np.arange(len(pk))
    p = point_index[point_of_factor]
    n_pts = len(pk)
    Hxx = _summed(p, np.einsum("fri,frj->fij", A, A), n_pts)
    Hxz = _summed(p, np.einsum("fri,frj->fij", A, B), n_pts)
    Hzz = _summed(p, np.einsum("fri,frj->fij", B, B), n_pts)
    gx = _summed(p, np.einsum("fri,fr->fi", A, b), n_pts)
    gz = _summed(p, np.einsum("fri,fr->fi", B, b), n_pts)
    Hxx += 1e-12 * np.eye(3)
    solve_xz = np.linalg.solve(Hxx, Hxz)                                         # (N, 3, nz)
    solve_x = np.linalg.solve(Hxx, gx[..., None])[..., 0]
    S = Hzz - np.einsum("nia,nib->nab", Hxz, solve_xz)
    s = gz - np.einsum("nia,ni->na", Hxz, solve_x)
    flat = keys[pk] - np.uint64(point_keys([0])[0])
    frames, joints = (flat // J).astype(np.int64), (flat % J).astype(np.int64)
    frame_info = _summed(frames, S, T)
    joint_info = _summed(joints, S, J)
    flip = np.asarray(problem.rig.skeleton.flip, dtype=np.int64)
    clusters = np.minimum(joints, flip[joints])
    spread = intrinsics_prior_spread(problem, list(red.z_keys))
    return JointScores(frames=frames, joints=joints, clusters=clusters, scores=s,
                       frame_info=frame_info,
                       joint_info=joint_info, z_keys=list(red.z_keys),
                       gauge=scale_direction(problem, values, list(red.z_keys)),
                       row_info=S if keep_rows else None,
                       # estimated intrinsics without bones (every bone biased): their
                       # priors are all that hold them (None with known intrinsics)
                       prior_information=spread, prior_spread=spread)


def frame_scores(problem: GraphProblem, values: gtsam.Values,
                 bias_pixel_sigma: float | None = None) -> JointScores:
    """:func:`joint_scores` with every factor, each frame's joints eliminated together.

    With the focal length estimated the reprojection alone carries no information on
    it (nor on the bone lengths): the bones do, and they couple the joints of a frame.
    So the rows of every factor but the gauge are linearised (whitened, the kernel's
    weights applied) and each frame's joints are eliminated together: with the
    frame's rows ``[A_t B_t]`` over (its joints, the reduced globals ``z``: planes,
    intrinsics, bone lengths) and ``M_t = (A_t^T A_t)^-1 A_t^T B_t``,

        S_t = B_t^T B_t - B_t^T A_t M_t          (the frame's Schur complement),
        s_r = (B_r - A_r M_t)^T b_r              (row ``r``'s share of its reduced score).

    Every row's share goes to the joints it sees (a bone's row half to each of its two
    joints, a reprojection row to its joint), so that a frame's joints' scores sum to
    the frame's score. The frames are the independent units: the time-series figures
    of the sandwich apply (:func:`~.sandwich.two_way_meat`). The joint-pair clusters do not
    (:attr:`JointScores.joint_clusters` is ``False``): a frame's bones couple its
    joints, their shares are anti-correlated within the frame, and the clusters'
    figure, which takes them as independent, is 9 times the marginal one on 1000 iid
    frames (the time figure 1.25 times). The rows of the factors on the globals alone
    (length priors, a focal length's prior) are in
    :attr:`JointScores.prior_information`. A joint's information (``joint_info``, for
    the sensitivity report) is that of its reprojection rows after the frame's
    elimination, ``sum (B_r - A_r M_t)^T (B_r - A_r M_t)``. The scale gauge is
    projected out (:func:`scale_direction`, with the lengths): the gauge's factor is a
    gauge, not information.

    With ``bias_pixel_sigma`` the bones' curvature bias enters too
    (:attr:`JointScores.bias_score`): a bone's length measured from noisy joints is long
    on average by ``tr(P S) / (2 L)`` (:func:`~.bones.bone_curvature_bias`, ``P`` the
    projection across the bone at the solution), a bias that no std holds and that
    the bones pass to the focal length (a stretch along the lines of sight); each bone
    row's share of the reduced score, with its whitened bias in place of its residual,
    summed, is the score of that bias.

    Args:
        problem: the solved graph (its bone lengths a variable); values: its solution.
        bias_pixel_sigma: the pixel noise of the curvature bias, px (``None``: none).

    Returns:
        :class:`JointScores` over the reduced coordinates of
        :func:`~.reduction.mirror_reduction` (planes, intrinsics, bone lengths).
    """
    red = mirror_reduction(problem, distance_gauge=None)
    T, J = problem.used.shape
    nz = sum(d for _, d in red.z_keys)
    graph = gtsam.NonlinearFactorGraph(problem.reprojection)
    for part in (problem.priors, problem.bones, problem.length_priors):
        graph.push_back(part)
    n_data = 2 * int(problem.reprojection.size())                # reprojection rows first
    n_rows, b, r, kc, pt, flat_of_key, frame, A, B = _frame_rows(problem, values, red, graph)
    local = frame >= 0
    prior_information = B[~local].T @ B[~local]
    # the local rows padded frame by frame: (T, most rows of a frame, ...)
    lr = np.flatnonzero(local)
    lr = lr[np.argsort(frame[lr], kind="stable")]
    fr = frame[lr]
    start = np.searchsorted(fr, np.arange(T))
    slot = np.arange(len(lr)) - start[fr]
    width = int(slot.max()) + 1 if len(lr) else 1
    Ap = np.zeros((T, width, 3 * J))
    Bp = np.zeros((T, width, nz))
    bp = np.zeros((T, width))
    Ap[fr, slot], Bp[fr, slot], bp[fr, slot] = A[lr], B[lr], b[lr]
    At = Ap.transpose(0, 2, 1)
    Hxx, Hxz, Hzz = At @ Ap, At @ Bp, Bp.transpose(0, 2, 1) @ Bp
    absent = np.einsum("tii->ti", Hxx) <= 0.0                 # joints a frame does not hold
    ti, ji = np.nonzero(absent)
    Hxx[ti, ji, ji] = 1.0
    M = np.linalg.solve(Hxx, Hxz)                                                # (T, 3J, nz)
    frame_info = Hzz - Hxz.transpose(0, 2, 1) @ M
    # every row's share of its frame's score, given to the joints it sees (a bone's row
    # half to each of its two joints): the joints' scores then sum to the frame's
    Bt = Bp - Ap @ M                                                             # (T, W, nz)
    share = Bt[fr, slot] * b[lr][:, None]                                        # (Rl, nz)
    pos = np.full(n_rows, -1, dtype=np.int64)
    pos[lr] = np.arange(len(lr))
    pairs = np.unique(np.stack([r[pt], flat_of_key[kc[pt]]], axis=1), axis=0)     # (row, joint)
    pairs = pairs[pos[pairs[:, 0]] >= 0]
    per_row = np.bincount(pairs[:, 0], minlength=n_rows)
    flat, inverse = np.unique(pairs[:, 1], return_inverse=True)
    scores = np.zeros((len(flat), nz))
    np.add.at(scores, inverse, share[pos[pairs[:, 0]]] / per_row[pairs[:, 0], None])
    frames, joints = flat // J, flat % J
    # a joint's information: its reprojection rows' after the frame's elimination
    data = pairs[pairs[:, 0] < n_data]
    Bd = Bt[fr[pos[data[:, 0]]], slot[pos[data[:, 0]]]]
    joint_info = np.stack([Bd[data[:, 1] % J == j].T @ Bd[data[:, 1] % J == j]
                           for j in range(J)])
    flip = np.asarray(problem.rig.skeleton.flip, dtype=np.int64)
    bias_score = None
    if bias_pixel_sigma is not None and problem.lengths is not None and len(problem.bone_rows):
        bias_score = _bias_score(problem, values, float(bias_pixel_sigma), n_data, n_rows, pos,
                                 Bt, fr, slot)
    return JointScores(frames=frames.astype(np.int64), joints=joints.astype(np.int64),
                       clusters=np.minimum(joints, flip[joints]), scores=scores,
                       frame_info=frame_info, joint_info=joint_info,
                       z_keys=list(red.z_keys),
                       gauge=scale_direction(problem, values, list(red.z_keys)),
                       prior_information=prior_information, joint_clusters=False,
                       prior_spread=intrinsics_prior_spread(problem, list(red.z_keys)),
                       bias_score=bias_score)


def _frame_rows(problem: GraphProblem, values: gtsam.Values, red,
                graph: gtsam.NonlinearFactorGraph) -> tuple:
    """The rows of ``graph`` linearised at ``values`` (whitened, the kernel's weights
    applied), read from GTSAM's sparse Jacobian for :func:`frame_scores`.

    Returns:
        ``n_rows``; ``b``: ``(R,)`` the right-hand side; ``r``, ``kc``, ``pt``: each
        Jacobian entry's row, its key's index and whether that key is a joint;
        ``flat_of_key``: per key the joint's ``t * J + j`` (-1 for a global); ``frame``:
        ``(R,)`` each row's frame (-1: a row on globals only); ``A``: ``(R, 3 J)`` the
        rows on the frame's joints; ``B``: ``(R, nz)`` the rows on the reduced globals
        (:meth:`~.reduction.GlobalReduction.basis`).
    """
    J = problem.used.shape[1]
    gfg = graph.linearize(values)
    trip = np.asarray(gfg.sparseJacobian_(), dtype=float)                     # (3, nnz)
    rows, cols, vals = trip[0].astype(np.int64) - 1, trip[1].astype(np.int64) - 1, trip[2]
    n_rows = int(rows.max()) + 1 if len(rows) else 0
    keys = sorted(int(k) for k in gfg.keyVector())
    nb = 0 if problem.lengths is None else len(problem.lengths)
    dims = [nb if k == problem.length_key else _dim(k) for k in keys]
    offsets = np.cumsum([0] + dims)
    b_col = offsets[-1]
    key_of_col = np.repeat(np.arange(len(keys)), dims)
    local_of_col = np.arange(b_col) - np.repeat(offsets[:-1], dims)
    x0 = int(point_keys([0])[0])
    is_point = np.array([gtsam.Symbol(k).chr() == ord("x") for k in keys])
    flat_of_key = np.array([k - x0 if p else -1 for k, p in zip(keys, is_point)], dtype=np.int64)
    Tb = red.basis(values)
    row_of_key, off = {}, 0
    for k, d in red.graph_keys:
        row_of_key[int(k)] = off
        off += d
    glob_row = np.array([row_of_key.get(k, -1) for k in keys])
    b = np.zeros(n_rows)
    last = cols == b_col
    b[rows[last]] = vals[last]
    r, c, v = rows[~last], cols[~last], vals[~last]
    kc = key_of_col[c]
    pt = is_point[kc]
    # every row's frame (the frame of the points it touches; -1: a row on globals only)
    frame = np.full(n_rows, -1, dtype=np.int64)
    frame[r[pt]] = flat_of_key[kc[pt]] // J
    A = np.zeros((n_rows, 3 * J))
    A[r[pt], (flat_of_key[kc[pt]] % J) * 3 + local_of_col[c[pt]]] = v[pt]
    Bg = np.zeros((n_rows, Tb.shape[0]))
    gr = glob_row[kc[~pt]]
    ok = gr >= 0
    Bg[r[~pt][ok], gr[ok] + local_of_col[c[~pt]][ok]] = v[~pt][ok]
    B = Bg @ Tb                                                                  # (R, nz)
    return n_rows, b, r, kc, pt, flat_of_key, frame, A, B


def _bias_score(problem: GraphProblem, values: gtsam.Values, pixel_sigma: float, n_data: int,
                n_rows: int, pos: np.ndarray, Bt: np.ndarray, fr: np.ndarray, slot: np.ndarray
                ) -> np.ndarray:
    """``(nz,)`` the score of the bones' curvature bias (:attr:`JointScores.bias_score`):
    each bone row's share of its frame's reduced score (``Bt``, the frame-eliminated
    rows, at ``fr``/``slot`` of the local row ``pos``) with its whitened bias
    (:func:`_bone_bias_rows`) in place of its residual, summed."""
    J = problem.used.shape[1]
    beta = _bone_bias_rows(problem, values, pixel_sigma)        # whitened
    n_prior = sum(int(problem.priors.at(i).dim()) for i in range(problem.priors.size()))
    first = n_data + n_prior
    br = np.asarray(problem.bone_rows)
    bframe = np.asarray(problem.flat_index, dtype=np.int64)[br[:, 0]] // J
    order = np.argsort(bframe, kind="stable")          # the bone factors' row order
    grow = first + np.arange(len(order))
    keep = (grow < n_rows) & (pos[np.minimum(grow, n_rows - 1)] >= 0)
    g = pos[grow[keep]]
    return (Bt[fr[g], slot[g]] * beta[order[keep]][:, None]).sum(0)


def _bone_bias_rows(problem: GraphProblem, values: gtsam.Values, pixel_sigma: float
                    ) -> np.ndarray:
    """``(N,)`` each bone row's curvature bias ``tr(P S) / (2 L)`` (``S`` its two joints'
    triangulation covariances at ``pixel_sigma``, ``P`` across the bone, ``L`` its
    length), over the bone factors' sigma (whitened), at the solution ``values``."""
    from ..geometry import triangulation_covariance
    from .problem import extract_camera_poses, extract_planes, extract_points
    from .rig import view_projections

    T, J = problem.used.shape
    points = extract_points(problem, values)
    planes = extract_planes(problem, values)
    poses = extract_camera_poses(problem, values)
    rig = problem.rig
    masks = [np.asarray(v.mask, bool) & problem.used for v in rig.views]
    cov = triangulation_covariance(view_projections(rig, poses, planes), points, masks,
                                   pixel_sigma)                                 # (T, J, 3, 3)
    br = np.asarray(problem.bone_rows)
    flat = np.asarray(problem.flat_index, dtype=np.int64)
    fa, fb = flat[br[:, 0]], flat[br[:, 1]]
    ta, ja, tb, jb = fa // J, fa % J, fb // J, fb % J
    S = cov[ta, ja] + cov[tb, jb]                                               # (N, 3, 3)
    diff = points[ta, ja] - points[tb, jb]
    L = np.linalg.norm(diff, axis=-1)
    u = diff / np.maximum(L, 1e-12)[:, None]
    trPS = np.trace(S, axis1=-2, axis2=-1) - np.einsum("ni,nij,nj->n", u, S, u)
    beta = trPS / (2.0 * np.maximum(L, 1e-12)) / float(problem.bone_sigma)
    return np.where(np.isfinite(beta), beta, 0.0)


def intrinsics_prior_spread(problem: GraphProblem, z_keys: list) -> np.ndarray | None:
    """``(n, n)`` the information of the estimated cameras' intrinsics priors in the
    reduced coordinates ``z_keys`` (diagonal: ``1 / sigma^2`` on ``f`` and on ``cx, cy``,
    :func:`~.priors.intrinsics_prior_sigmas`), ``None`` where no camera has one.

    A prior about a guess stands for the population the unknown true value comes from
    (cameras' focal lengths, principal points off the image centre): the estimate's
    error then holds the prior's own draw, ``Var = H^-1 (Omega + P) H^-1`` with ``P``
    this matrix, which the data's scores (``Omega``) cannot show."""
    by_key = {int(pair[0]): c for c, pair in problem.calibration_keys.items()}
    n = sum(d for _, d in z_keys)
    P = np.zeros((n, n))
    off, found = 0, False
    for key, dim in z_keys:
        c = by_key.get(int(key))
        if c is not None:
            w = 1.0 / intrinsics_prior_sigmas(problem.rig.cameras[c]) ** 2
            if np.any(w > 0):
                P[off:off + dim, off:off + dim] = np.diag(w[:dim])
                found = True
        off += dim
    return P if found else None


def scale_direction(problem: GraphProblem, values: gtsam.Values, z_keys: list) -> np.ndarray:
    """``(n,)`` the scale gauge in the reduced coordinates: every length grows together.

    Reprojection alone does not fix the scale: scaling every joint, every camera
    position and every mirror distance leaves the images unchanged. In the tangent
    coordinates that is ``delta d = d`` for a plane (:class:`gtsam.OrientedPlane3`'s
    third coordinate) and ``v = R^T t`` for a pose (:class:`gtsam.Pose3`'s
    translation coordinates, body frame); ``delta L = L`` for the bone lengths where
    they are a variable; intrinsics do not change with the scale.
    """
    out = []
    for key, dim in z_keys:
        if gtsam.Symbol(key).chr() == ord("k"):
            out.append(np.zeros(dim))
        elif gtsam.Symbol(key).chr() == ord("l"):          # the bone lengths
            out.append(np.asarray(values.atVector(key), dtype=float))
        elif gtsam.Symbol(key).chr() == ord("p"):
            plane = values.atOrientedPlane3(key)
            out.append([0.0, 0.0, float(plane.distance())])
        else:
            pose = values.atPose3(key)
            R, t = np.asarray(pose.rotation().matrix()), np.asarray(pose.translation())
            out.append(np.concatenate([np.zeros(3), R.T @ t]))
    return np.concatenate([np.asarray(o, dtype=float) for o in out]) if out else np.zeros(0)


def _chars(keys: np.ndarray) -> np.ndarray:
    """``(n,)`` the :class:`gtsam.Symbol` character of every key of ``(n,)`` uint64."""
    return (np.asarray(keys, dtype=np.uint64) >> np.uint64(56)).astype(np.int64)


def _dims(keys: np.ndarray) -> np.ndarray:
    """:func:`_dim` of every key of ``(n,)`` uint64, vectorised."""
    c = _chars(keys)
    return np.where(c == ord("x"), 3, np.where(np.isin(c, (ord("k"), ord("q"))), 5, 6))


def _summed(index: np.ndarray, rows: np.ndarray, n: int) -> np.ndarray:
    """``(n, ...)`` the ``rows`` ``(m, ...)`` summed by ``index`` ``(m,)``: ``np.add.at``
    through ``np.bincount``, one entry of the rows at a time."""
    rows = np.asarray(rows, dtype=float)
    flat = rows.reshape(len(rows), -1)
    out = np.empty((n, flat.shape[1]))
    for i in range(flat.shape[1]):
        out[:, i] = np.bincount(index, flat[:, i], minlength=n)
    return out.reshape((n,) + rows.shape[1:])


def _dim(key: int) -> int:
    """Tangent dimension of a reprojection factor's variable: a point 3, a calibration
    (``K(c)``, ``Q(c)``) 5, a pose 6."""
    c = gtsam.Symbol(key).chr()
    return 3 if c == ord("x") else 5 if c in (ord("k"), ord("q")) else 6
