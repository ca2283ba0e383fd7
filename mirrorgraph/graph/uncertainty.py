"""An uncertainty that follows the data's real error structure: a cluster-robust sandwich.

The marginals of the graph (:func:`~.optimizer.reduced_covariance`) are right for
independent Gaussian pixel noise. A real detector's error is neither: a joint's
error in one frame predicts the next (frame-to-frame correlated noise), and a
detector places some joints consistently off the anatomical joint (a per-joint
bias). Both leave the estimate's spread far above what the marginals say.

The estimate ``theta`` (the globals in reduced coordinates: the planes, the
estimated camera poses) solves ``sum_p s_p(theta) = 0``, ``s_p`` the score of joint
``p`` (one joint in one frame) once its own position is eliminated: with the
linearised, whitened reprojection rows of that joint ``[A_p B_p] (dX, dtheta) = b_p``,

    S_p = B_p^T B_p - B_p^T A_p (A_p^T A_p)^-1 A_p^T B_p        (its Schur complement)
    s_p = B_p^T b_p - B_p^T A_p (A_p^T A_p)^-1 A_p^T b_p        (its reduced score).

The sandwich (Huber 1967; White 1980) ``Cov = H^-1 Omega H^-1`` with ``H = sum_p
S_p`` and ``Omega`` the covariance of ``sum_p s_p`` holds whatever the errors are,
if ``Omega`` sees how the scores are correlated. Two correlations are modelled, as
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
``dtheta_c = -(H - H_c)^-1 G_c``), and the information each segment carries.
The rows are the reprojection factors alone (the body priors are not data): the
Schur complements ignore the priors' pull on the joints, which the benchmarks
show changes the mirror little (``bench/RESULTS_ablation.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np
from ..stats import chdtri, fdtri

from .builder import GraphProblem, intrinsics_prior_sigmas, point_keys
from .reduction import mirror_reduction
from .result import normal_cov_from_tangent, rotation_std_from_normal_cov

#: A camera or mirror whose rotation std (the robust figure) exceeds this many degrees
#: is reported as poorly determined (a mirror seen almost edge-on or square-on, too few
#: frames, too little motion, or a detector's error that the frames do not average).
POORLY_DETERMINED_DEG = 0.5

__all__ = ["POORLY_DETERMINED_DEG", "JointScores", "joint_scores", "frame_scores", "long_run_covariance", "two_way_meat", "sandwich",
           "jackknife_cov", "leave_one_out",
           "gauge_inverse", "scale_direction", "andrews_bandwidth", "robust_normal_cov",
           "covariance_max", "robust_blocks", "robust_intrinsics_std", "ROBUST_PARTS",
           "REGION_LEVEL", "region_threshold", "region_rotation_deg",
           "intrinsics_contributions", "intrinsics_prior_spread", "held_intrinsics_cov"]


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
            and principal point about their guess, :func:`~.builder.intrinsics_prior`):
            the spread of that value is added to the sandwich's meat
            (:func:`sandwich`), since the scores do not contain it; ``None``: none.
        prior_floor: ``(n,)`` the least variance of each intrinsic's coordinate (of
            :attr:`prior_spread`; 0: none), in its unit squared (px^2): where the data
            do not determine a focal length its prior's, where two estimates of it from
            the same data disagree their difference squared
            (:func:`mirrorgraph.graph.solve.floor_focal`); ``None``: none.
        bias_score: ``(n,)`` the reduced score of the bones' curvature bias
            (:func:`frame_scores`): the estimate's first-order bias is
            ``H^-1 bias_score``, whose outer product every figure of :func:`sandwich`
            holds (an error no std of the noise sees); ``None``: not computed.
        added_cov: ``(n, n)`` a covariance every figure of :func:`sandwich` adds: what
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
    nz = sum(d for _, d in red.z_keys)
    gfg = problem.reprojection.linearize(values)
    trip = np.asarray(gfg.sparseJacobian_(), dtype=float)                     # (3, nnz)
    rows, cols, vals = trip[0].astype(np.int64) - 1, trip[1].astype(np.int64) - 1, trip[2]
    keys = sorted(int(k) for k in gfg.keyVector())
    dims = [_dim(k) for k in keys]
    offsets = np.cumsum([0] + dims)
    b_col = offsets[-1]
    key_of_col = np.repeat(np.arange(len(keys)), dims)
    local_of_col = np.arange(b_col) - np.repeat(offsets[:-1], dims)
    is_point = np.array([gtsam.Symbol(k).chr() == ord("x") for k in keys])
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
    glob_row = np.array([row_of_key.get(keys[i], -1) for i in range(len(keys))])
    gr = glob_row[kc[~pt]]
    ok = gr >= 0
    Bg[fr[~pt][ok], rr[~pt][ok], gr[ok] + lc[~pt][ok]] = vr[~pt][ok]
    B = Bg @ Tb                                                                  # (nf, 2, nz)
    # per joint: normal equations of its rows, then its Schur complement and score
    point_index = np.full(len(keys), -1, dtype=np.int64)
    pk = [i for i in range(len(keys)) if is_point[i]]
    point_index[pk] = np.arange(len(pk))
    p = point_index[point_of_factor]
    n_pts = len(pk)
    Hxx = np.zeros((n_pts, 3, 3))
    Hxz = np.zeros((n_pts, 3, nz))
    Hzz = np.zeros((n_pts, nz, nz))
    gx = np.zeros((n_pts, 3))
    gz = np.zeros((n_pts, nz))
    np.add.at(Hxx, p, np.einsum("fri,frj->fij", A, A))
    np.add.at(Hxz, p, np.einsum("fri,frj->fij", A, B))
    np.add.at(Hzz, p, np.einsum("fri,frj->fij", B, B))
    np.add.at(gx, p, np.einsum("fri,fr->fi", A, b))
    np.add.at(gz, p, np.einsum("fri,fr->fi", B, b))
    Hxx += 1e-12 * np.eye(3)
    solve_xz = np.linalg.solve(Hxx, Hxz)                                         # (N, 3, nz)
    solve_x = np.linalg.solve(Hxx, gx[..., None])[..., 0]
    S = Hzz - np.einsum("nia,nib->nab", Hxz, solve_xz)
    s = gz - np.einsum("nia,ni->na", Hxz, solve_x)
    flat = np.array([keys[i] for i in pk], dtype=np.uint64) - np.uint64(point_keys([0])[0])
    frames, joints = (flat // J).astype(np.int64), (flat % J).astype(np.int64)
    frame_info = np.zeros((T, nz, nz))
    joint_info = np.zeros((J, nz, nz))
    np.add.at(frame_info, frames, S)
    np.add.at(joint_info, joints, S)
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
    of the sandwich apply (:func:`two_way_meat`). The joint-pair clusters do not
    (:attr:`JointScores.joint_clusters` is ``False``): a frame's bones couple its
    joints, their shares are anti-correlated within the frame, and the clusters'
    figure, which takes them as independent, was 9 times the marginal one on 1000 iid
    frames (the time figure 1.25 times). The rows of the factors on the globals alone
    (length priors, a focal length's prior) are in
    :attr:`JointScores.prior_information`. A joint's information (``joint_info``, for
    the sensitivity report) is that of its reprojection rows after the frame's
    elimination, ``sum (B_r - A_r M_t)^T (B_r - A_r M_t)``. The scale gauge is
    projected out (:func:`scale_direction`, with the lengths): the gauge's factor is a
    gauge, not information.

    With ``bias_pixel_sigma`` the bones' curvature bias enters too
    (:attr:`JointScores.bias_score`): a bone's length measured from noisy joints is long
    on average by ``tr(P S) / (2 L)`` (:func:`~.builder.bone_curvature_bias`, ``P`` the
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
        beta = _bone_bias_rows(problem, values, float(bias_pixel_sigma))        # whitened
        n_prior = sum(int(problem.priors.at(i).dim()) for i in range(problem.priors.size()))
        first = n_data + n_prior
        br = np.asarray(problem.bone_rows)
        bframe = np.asarray(problem.flat_index, dtype=np.int64)[br[:, 0]] // J
        order = np.argsort(bframe, kind="stable")          # the bone factors' row order
        grow = first + np.arange(len(order))
        keep = (grow < n_rows) & (pos[np.minimum(grow, n_rows - 1)] >= 0)
        g = pos[grow[keep]]
        bias_score = (Bt[fr[g], slot[g]] * beta[order[keep]][:, None]).sum(0)
    return JointScores(frames=frames.astype(np.int64), joints=joints.astype(np.int64),
                       clusters=np.minimum(joints, flip[joints]), scores=scores,
                       frame_info=frame_info, joint_info=joint_info,
                       z_keys=list(red.z_keys),
                       gauge=scale_direction(problem, values, list(red.z_keys)),
                       prior_information=prior_information, joint_clusters=False,
                       prior_spread=intrinsics_prior_spread(problem, list(red.z_keys)),
                       bias_score=bias_score)


def _bone_bias_rows(problem: GraphProblem, values: gtsam.Values, pixel_sigma: float
                    ) -> np.ndarray:
    """``(N,)`` each bone row's curvature bias ``tr(P S) / (2 L)`` (``S`` its two joints'
    triangulation covariances at ``pixel_sigma``, ``P`` across the bone, ``L`` its
    length), over the bone factors' sigma (whitened), at the solution ``values``."""
    from ..geometry import triangulation_covariance
    from .builder import extract_camera_poses, extract_planes, extract_points, view_projections

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
    :func:`~.builder.intrinsics_prior_sigmas`), ``None`` where no camera has one.

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


def _dim(key: int) -> int:
    """Tangent dimension of a reprojection factor's variable: a point 3, a calibration
    (``K(c)``, ``Q(c)``) 5, a pose 6."""
    c = gtsam.Symbol(key).chr()
    return 3 if c == ord("x") else 5 if c in (ord("k"), ord("q")) else 6


# --------------------------------------------------------------------------- the meat
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
        scores: :func:`joint_scores`.
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
        scores: :func:`joint_scores` (with its scale gauge).

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
    for C in [sw["bread"], *_candidates(sw).values()]:
        if np.all(np.isfinite(C)) and np.trace(C[np.ix_(a, a)]) > best_tr:
            best, best_tr = C, float(np.trace(C[np.ix_(a, a)]))
    k = np.asarray(k)
    Cak = best[np.ix_(a, k)]
    return Cak @ np.linalg.pinv(best[np.ix_(k, k)]) @ Cak.T


def _with_unknown_intrinsics(out: dict, scores: JointScores, H: np.ndarray, meat: dict) -> None:
    """The sandwich's figures where intrinsics with a prior about a guess are estimated
    (:attr:`JointScores.prior_spread`), in place.

    With ``k`` the intrinsics' coordinates and ``a`` the rest, the estimate moves as
    ``delta a = H_aa^-1 s_a + G delta k``, ``G = -H_aa^-1 H_ak``: the first term is the
    sandwich with the intrinsics held (``H_aa^-1 Omega_aa H_aa^-1``, the figure of a
    known camera), the second carries the intrinsics' own error (Gaussian conditioning;
    the two are uncorrelated where the scores' covariance is their information). The
    intrinsics' covariance ``C_k`` is each figure's own ``k`` block, at least the
    marginal (``H^-1``, which holds the prior) and at most the prior's spread in each
    coordinate: where the data hardly hold them (no bones, rays meeting at a few
    degrees) the scores' ``k`` part is numerically meaningless (it gave a focal std of
    5e7 px), and the truth's spread about the guess is the prior's. So the reported
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
    marg_k = bread[np.ix_(k, k)]
    if scores.prior_floor is not None:
        # an intrinsic the data do not determine: its variance at least the floor
        # (the prior's, or the disagreement of two estimates), at most the prior's
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


def robust_intrinsics_std(scores: JointScores, marginal: dict[int, np.ndarray]
                          ) -> dict[int, tuple[np.ndarray, str]]:
    """The headline standard deviations of every estimated camera's intrinsics.

    As :func:`robust_normal_cov` for the reduced block of each camera's ``K(c)``
    (``f`` or ``f, cx, cy``, px): of the marginal covariance and the sandwich's
    figures (:data:`ROBUST_PARTS`), the largest standard deviation of each entry.

    Args:
        scores: :func:`frame_scores` of the solution.
        marginal: ``K(c)`` key -> its ``(d, d)`` marginal covariance (scaled by the noise).

    Returns:
        ``K(c)`` key -> ``((d,) stds px, the name of the figure that gave the focal's)``.
    """
    cands = _candidates(sandwich(scores))
    out, off = {}, 0
    for key, dim in scores.z_keys:
        block = slice(off, off + dim)
        off += dim
        if key not in marginal:
            continue
        best = np.sqrt(np.maximum(np.diag(np.asarray(marginal[key], float)), 0.0))
        chosen = "marginal"
        for name, C in cands.items():
            std = np.sqrt(np.maximum(np.diag(C[block, block]), 0.0))
            if np.all(np.isfinite(std)):
                if std[0] > best[0]:
                    chosen = name
                best = np.maximum(best, std)
        out[int(key)] = (best, chosen)
    return out


#: The figures :func:`robust_normal_cov` chooses from, largest rotation std first wins.
ROBUST_PARTS = ("marginal", "time", "joint", "two_way", "jack_time", "jack_joint")


def robust_normal_cov(scores: JointScores, basis: np.ndarray, marginal: np.ndarray
                      ) -> tuple[np.ndarray, dict]:
    """The headline covariance of a mirror's unit normal, and what it is made of.

    Of the marginal covariance (iid noise), the sandwich seeing the time series alone,
    the joint-pair clusters alone and both together (:func:`sandwich`), the one with
    the largest rotation std, widened where it is thinner than the marginals
    (:func:`covariance_max`): each is an estimate with its own noise (with six pairs
    of joints the clusters' is a six-degree-of-freedom one, which the two-way
    combination's subtraction can take below either part), and an uncertainty a user
    plans on must not be the lucky one.

    Args:
        scores: :func:`joint_scores` of a single mirror (reduced coordinates: the plane).
        basis: ``(3, 2)`` the plane's normal tangent basis (the scores' coordinates).
        marginal: ``(3, 3)`` the marginal covariance of the normal (scaled by the noise).

    Returns:
        ``(3, 3)`` covariance (camera frame, rad^2) and a record: each candidate's
        rotation std (deg) and ``(3, 3)`` covariance, the chosen one, the ratio to the
        marginal std, the time series' bandwidth (frames), the chosen figure's clusters
        (0: none), the 90 % region's squared radius (:func:`region_threshold`) and its
        largest rotation error ``rotation_90_deg`` (twice the normal's largest angle in
        the region, deg).
    """
    sw = sandwich(scores)
    covs = {"marginal": np.asarray(marginal, dtype=float),
            "time": normal_cov_from_tangent(basis, sw["cov_time"][:2, :2]),
            "joint": normal_cov_from_tangent(basis, sw["cov_joint"][:2, :2]),
            "two_way": normal_cov_from_tangent(basis, sw["cov"][:2, :2]),
            "jack_time": normal_cov_from_tangent(basis, sw["cov_jack_time"][:2, :2]),
            "jack_joint": normal_cov_from_tangent(basis, sw["cov_jack_joint"][:2, :2])}
    stds = {k: rotation_std_from_normal_cov(c) for k, c in covs.items()}
    finite = [k for k in ROBUST_PARTS if np.isfinite(stds[k])]
    chosen = max(finite, key=lambda k: stds[k]) if finite else "marginal"
    # no thinner than the marginals in any direction (a cluster estimate from six pairs
    # can be nearly flat in one): the smallest covariance above both
    headline = covariance_max(covs["marginal"], covs[chosen])
    std = rotation_std_from_normal_cov(headline)
    clusters = {"jack_time": int(sw["segments"]), "joint": len(np.unique(scores.clusters)),
                "two_way": len(np.unique(scores.clusters)),
                "jack_joint": len(np.unique(scores.clusters))}.get(chosen)
    m2 = region_threshold(2, clusters, REGION_LEVEL)
    parts = {f"{k}_rotation_std_deg": float(stds[k]) for k in ROBUST_PARTS}
    full = sw["bread"] if chosen == "marginal" else _candidates(sw)[chosen]
    parts.update({f"{k}_normal_cov": covs[k] for k in ROBUST_PARTS},
                 contributions=intrinsics_contributions(full, scores.z_keys),
                 chosen=chosen, bandwidth_frames=float(sw["bandwidth"]),
                 segments=int(sw["segments"]), clusters=int(clusters or 0),
                 region90_mahalanobis2=float(m2),
                 rotation_90_deg=region_rotation_deg(headline, clusters),
                 ratio_to_marginal=float(std / stds["marginal"])
                 if stds["marginal"] > 0 else float("nan"))
    return headline, parts


def intrinsics_contributions(cov: np.ndarray, z_keys: list, block: slice = slice(0, 2)
                             ) -> dict[str, float]:
    """How much of a rotation's variance the unknown intrinsics make.

    With ``C`` the covariance of the reduced coordinates, ``a`` the rotation's block
    (a plane's first two: its normal) and ``x`` one group of intrinsics, the variance
    ``a`` would lose were ``x`` known is ``C_ax C_xx^-1 C_xa`` (Gaussian conditioning);
    its trace over ``tr C_aa`` is that group's share.

    Args:
        cov: ``(n, n)`` covariance over ``z_keys`` (any scale: the shares are ratios).
        z_keys: ``(key, dim)`` of the reduced coordinates; an intrinsics block (a
            ``k`` key) is ``f`` or ``f, cx, cy`` (:mod:`.reduction`).
        block: the rotation's coordinates in ``cov``.

    Returns:
        ``{"focal_length": share, "principal_point": share}`` (0-1; the groups the
        coordinates hold; the rest of the variance is the geometry's and the noise's).
    """
    C = 0.5 * (np.asarray(cov, float) + np.asarray(cov, float).T)
    groups: dict[str, list[int]] = {}
    off = 0
    for key, dim in z_keys:
        if gtsam.Symbol(key).chr() == ord("k"):
            groups.setdefault("focal_length", []).append(off)
            if dim == 3:
                groups.setdefault("principal_point", []).extend([off + 1, off + 2])
        off += dim
    a = np.arange(C.shape[0])[block]
    total = float(np.trace(C[np.ix_(a, a)]))
    out = {}
    for name, idx in groups.items():
        x = np.asarray(idx)
        Cax, Cxx = C[np.ix_(a, x)], C[np.ix_(x, x)]
        if not (np.all(np.isfinite(Cax)) and np.all(np.isfinite(Cxx))) or total <= 0:
            out[name] = float("nan")
            continue
        out[name] = float(np.clip(np.trace(Cax @ np.linalg.pinv(Cxx) @ Cax.T) / total, 0, 1))
    return out


#: The confidence level of the region :func:`robust_normal_cov` reports.
REGION_LEVEL = 0.9


def region_threshold(dim: int, clusters: int | None, level: float = REGION_LEVEL) -> float:
    """The squared Mahalanobis radius of a ``level`` confidence region of ``dim`` parameters.

    A covariance estimated from ``G`` independent clusters (joint pairs, time segments)
    is itself uncertain with ``G - 1`` degrees of freedom; the region then follows
    Hotelling's ``T^2 = dim (G - 1) / (G - dim) F(dim, G - dim)`` (Cameron and Miller
    2015, small-cluster inference), wider than the Gaussian's ``chi^2(dim)``, which it
    is for ``G`` large or for the marginals and the time series' long-run covariance
    (``clusters=None``).

    Args:
        dim: parameters (2 for a unit normal); clusters: ``G``, or ``None``.
        level: the confidence level.

    Returns:
        the threshold ``c``: the region is ``delta^T Sigma^-1 delta <= c``.
    """
    if clusters is None or clusters <= dim:
        return float(chdtri(dim, 1.0 - level))
    G = int(clusters)
    return float(dim * (G - 1) / (G - dim) * fdtri(dim, G - dim, level))


def region_rotation_deg(normal_cov: np.ndarray, clusters: int | None = None,
                        level: float = REGION_LEVEL) -> float:
    """The largest virtual-camera rotation error in a mirror normal's confidence region.

    Args:
        normal_cov: ``(3, 3)`` covariance of the unit normal (camera frame, rad^2).
        clusters: as :func:`region_threshold`; level: the confidence level.

    Returns:
        ``2 sqrt(c lambda_max)`` in degrees: the mirror turns the virtual camera by
        twice the normal's angle.
    """
    C = np.asarray(normal_cov, dtype=float)
    if not np.all(np.isfinite(C)):
        return float("nan")
    lam = float(np.linalg.eigvalsh(0.5 * (C + C.T))[-1])
    return float(2.0 * np.degrees(np.sqrt(region_threshold(2, clusters, level) * max(lam, 0.0))))


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


def _candidates(sw: dict) -> dict[str, np.ndarray]:
    """The sandwich's full covariances by name (:data:`ROBUST_PARTS` but the marginals)."""
    return {"time": sw["cov_time"], "joint": sw["cov_joint"], "two_way": sw["cov"],
            "jack_time": sw["cov_jack_time"], "jack_joint": sw["cov_jack_joint"]}


def robust_blocks(scores: JointScores, marginal_blocks: list[np.ndarray]
                  ) -> tuple[list[np.ndarray], list[dict]]:
    """Headline covariances of a rig's estimated cameras and mirrors, block by block.

    As :func:`robust_normal_cov` for each reduced variable of ``scores.z_keys`` (a
    camera pose: its rotation block, the first three tangent coordinates; a plane:
    its normal block, the first two): the candidate with the largest trace there,
    widened where thinner than the marginals (:func:`covariance_max`); the rest of the
    block (a position, a distance, whose reprojection-only figure depends on the
    scale gauge) is the marginal one scaled by the same ratio of stds.

    Args:
        scores: :func:`joint_scores` of the rig.
        marginal_blocks: the marginal covariance of each reduced variable, in
            ``scores.z_keys`` order (scaled by the noise).

    Returns:
        the headline blocks and, per block, ``{"chosen", "ratio_to_marginal",
        "contributions"}`` (the unknown intrinsics' shares of its rotation's variance,
        :func:`intrinsics_contributions`).
    """
    sw = sandwich(scores)
    cands = _candidates(sw)
    out, parts, off = [], [], 0
    for (key, dim), M in zip(scores.z_keys, marginal_blocks):
        M = np.asarray(M, dtype=float)
        rot = slice(0, 3) if dim == 6 else slice(0, 2)
        block = slice(off, off + dim)
        off += dim
        mrot = M[rot, rot]
        best, best_tr = "marginal", float(np.trace(mrot))
        for name, C in cands.items():
            B = C[block, block][rot, rot]
            if np.all(np.isfinite(B)) and np.trace(B) > best_tr:
                best, best_tr = name, float(np.trace(B))
        head = mrot if best == "marginal" else covariance_max(mrot, cands[best][block, block][rot, rot])
        tr = float(np.trace(mrot))
        ratio = float(np.sqrt(np.trace(head) / tr)) if tr > 0 else 1.0
        H = M * ratio ** 2
        H[rot, rot] = head
        out.append(H)
        full = sw["bread"] if best == "marginal" else cands[best]
        parts.append({"chosen": best, "ratio_to_marginal": ratio,
                      "contributions": intrinsics_contributions(
                          full, scores.z_keys, slice(block.start + rot.start,
                                                     block.start + rot.stop))})
    return out, parts
