"""MirrorCalib (Liao, Zheng and Mitchell) as the paper writes it, for comparison.

The paper's pipeline (sections "Initial estimation", "Refining 2D joint locations",
"Outlier rejection", "Training"):

1. **Initial estimate.** The 6-unknown reflective eight-point algorithm (eq. 5-7,
   :func:`mirrorgraph.initial.solvers.eightpoint.fundamental_reflective_eight_point`) on
   every joint pair, ``E = K^T F K``, the virtual camera ``(R, t)`` from the SVD of ``E``
   (:func:`mirrorgraph.geometry.decompose_reflective_essential`).
2. **Refinement of the 2D joints** of both views: each evaluation triangulates them with
   the current virtual camera ``Theta'`` and scores the 3D joints with six losses (bone
   length variation, symmetry, anthropometric ratios, hip colinearity, smoothness and a
   Geman-McClure reprojection term); L-BFGS (``torch.optim.LBFGS``, learning rate 1, at
   most 20 iterations a step), ``Theta'`` re-estimated by the eight-point algorithm after
   every step.
3. **RANSAC** on samples of six refined pairs, inliers by the summed epipolar distance
   ``g(F) = d(x', F x) + d(x, F^T x')``; the final ``F`` and pose from the largest set.

Where the text is ambiguous or silent (the variation of a bone length, eq. 12's
smoothness, the reprojection term's reading, the weights ``lambda``, the RANSAC threshold
and iterations, ...), each choice is an option of :class:`PaperOptions`; the choices and
their reasons are listed in ``docs/internals.md``. The relative weights were picked on
tuning scenes never used in the benchmark (``bench/compare.py --tune-paper``).

Scale: the decomposition gives ``|t| = 1`` and the losses' 3D joints are in that unit.
The reported pose is the decomposition's ``R`` and ``t``; the normal is ``D t``,
oriented by cheirality.

PyTorch is imported lazily; without it :func:`mirrorcalib` raises
:class:`~mirrorgraph.baselines.BenchDependencyError` saying
``pip install 'mirrorgraph[bench]'``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .. import geometry as geo
from ..anthropometry import femur_ratios
from ..errors import DegenerateGeometryError
from ..metrics import rotation_error_deg
from ..skeletons import Skeleton
from ..initial.solvers.eightpoint import fundamental_reflective_eight_point
from . import require, triangulate_virtual

LOSSES = ("var", "sym", "anth", "hip", "smooth", "repro")

#: Relative weights ``w`` of the losses after balancing (see the module docstring).
DEFAULT_WEIGHTS = {"var": 1.0, "sym": 1.0, "anth": 1.0, "hip": 1.0, "smooth": 1.0,
                   "repro": 10.0}

#: RANSAC threshold on ``g(F)``, the *sum* of the two point-to-line distances, px.
DEFAULT_THRESHOLD_PX = 2.0 * np.sqrt(2.0) * 10.0


@dataclass
class PaperOptions:
    """Options of :func:`mirrorcalib`; defaults are the choices documented above.

    Attributes:
        steps: outer optimisation steps (``LBFGS.step`` calls).
        lbfgs_lr: L-BFGS learning rate (paper: 1).
        lbfgs_max_iter: L-BFGS iterations per step (paper: 20).
        line_search: ``None`` (paper, PyTorch default) or ``"strong_wolfe"``.
        weights: relative weight ``w`` of each loss (keys of :data:`LOSSES`).
        balance: divide each loss by its value at the detections.
        gm_scale_px: scale ``c`` of the Geman-McClure function, px.
        threshold_px: RANSAC threshold on the summed epipolar distance, px.
        ransac_confidence, ransac_min_iterations, ransac_max_iterations: RANSAC.
        stop_rotation_deg: stop when ``Theta'`` turns less than this in a step.
        seed: RANSAC seed.
        threads: ``torch.set_num_threads`` (``None``: leave as is).
        refine: run step 2 (``False`` gives the eight-point + RANSAC alone).
    """

    steps: int = 10
    lbfgs_lr: float = 1.0
    lbfgs_max_iter: int = 20
    line_search: str | None = None
    weights: dict[str, float] = field(default_factory=lambda: dict(DEFAULT_WEIGHTS))
    balance: bool = True
    gm_scale_px: float = 10.0
    threshold_px: float = DEFAULT_THRESHOLD_PX
    ransac_confidence: float = 0.99
    ransac_min_iterations: int = 50
    ransac_max_iterations: int = 1000
    stop_rotation_deg: float = 1e-3
    seed: int = 0
    threads: int | None = None
    refine: bool = True


@dataclass
class PaperResult:
    """What :func:`mirrorcalib` returns.

    Attributes:
        rotation: ``(3, 3)`` virtual-camera rotation ``R`` from the final ``E``.
        translation: ``(3,)`` unit translation ``t`` (``X_v = D (R X + t)``).
        normal: ``(3,)`` unit mirror normal ``D t`` (away from the camera).
        fundamental: ``(3, 3)`` final ``F`` (pixels, unit norm, ``u'^T F u = 0``).
        initial_rotation, initial_translation: the eight-point estimate before refinement.
        inliers: ``(T, J)`` bool, the largest RANSAC inlier set.
        real_refined, mirror_refined: ``(T, J, 2)`` refined 2D joints (NaN where
            not used).
        joints3d: ``(T, J, 3)`` the refined joints triangulated with the final
            camera, unit ``|t| = 1``; NaN where not used.
        steps: outer steps run.
        ransac_iterations: RANSAC samples drawn.
        history: per step: the six losses (unweighted), total, rotation change.
        lambdas: the weights actually applied (after balancing).
        timings: seconds per stage.
    """

    rotation: np.ndarray
    translation: np.ndarray
    normal: np.ndarray
    fundamental: np.ndarray
    initial_rotation: np.ndarray
    initial_translation: np.ndarray
    inliers: np.ndarray
    real_refined: np.ndarray
    mirror_refined: np.ndarray
    joints3d: np.ndarray
    steps: int = 0
    ransac_iterations: int = 0
    history: list = field(default_factory=list)
    lambdas: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)


# --------------------------------------------------------------------------- pose from F
def pose_from_fundamental(F: np.ndarray, K: np.ndarray, u: np.ndarray, um: np.ndarray
                          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(R, t, n)`` of the virtual camera from a reflective ``F`` (paper sec. 3.2).

    ``E = K^T F K`` is decomposed by SVD; the normal ``n = D t`` is oriented by
    cheirality on the pairs ``u, um`` (``(N, 2)`` each); ``|t| = 1``.
    """
    E = K.T @ F @ K
    R, _t, n = geo.decompose_reflective_essential(E)
    n = geo.orient_normal(K, n, u, um)
    return R, geo.D_FLIP @ n, n


def summed_epipolar_distance(F: np.ndarray, u: np.ndarray, um: np.ndarray) -> np.ndarray:
    """The paper's ``g(F)``: distance of ``u'`` to ``F u`` plus distance of ``u`` to ``F^T u'``."""
    return 2.0 * geo.epipolar_distances_fundamental(F, u, um)


# --------------------------------------------------------------------------- RANSAC
def paper_ransac(u: np.ndarray, um: np.ndarray, options: PaperOptions
                 ) -> tuple[np.ndarray, np.ndarray, int]:
    """RANSAC of sec. "Outlier rejection": six pairs, largest inlier set, refit once.

    Returns:
        ``(F, inliers, iterations)``.
    """
    N = len(u)
    if N < 6:
        raise DegenerateGeometryError(f"MirrorCalib's RANSAC needs 6 pairs, got {N}")
    rng = np.random.default_rng(options.seed)
    thr = options.threshold_px
    best, best_count = None, -1
    needed = float(options.ransac_max_iterations)
    it = 0
    while it < options.ransac_max_iterations and (it < options.ransac_min_iterations
                                                  or it < needed):
        it += 1
        s = rng.choice(N, 6, replace=False)
        try:
            F = fundamental_reflective_eight_point(u[s], um[s])
        except (DegenerateGeometryError, np.linalg.LinAlgError):
            continue
        inl = summed_epipolar_distance(F, u, um) < thr
        c = int(np.count_nonzero(inl))
        if c > best_count:
            best, best_count = inl, c
            p = (c / N) ** 6
            if p >= 1.0:
                needed = 0.0
            elif p <= 1e-12:
                needed = np.inf
            else:
                needed = np.log(1.0 - options.ransac_confidence) / np.log1p(-p)
    if best is None or best_count < 6:
        raise DegenerateGeometryError("MirrorCalib's RANSAC found fewer than 6 inliers")
    F = fundamental_reflective_eight_point(u[best], um[best])
    return F, best, it


# --------------------------------------------------------------------------- body structure
@dataclass
class _Body:
    bones: np.ndarray        # (B, 2) local joint indices
    pair: np.ndarray         # (B,) index of the symmetric bone (itself if unpaired)
    sigma: np.ndarray        # (B,) expected length / femur
    femurs: np.ndarray       # (<=2,) bone indices of the femurs
    hip: tuple | None        # (left_hip, right_hip, mid_hip) local indices or None


def _body(skeleton: Skeleton, joints: np.ndarray) -> _Body:
    local = {int(j): i for i, j in enumerate(joints)}
    names = skeleton.bone_names
    idx = skeleton.bone_index
    keep = [k for k in range(len(names)) if idx[k, 0] in local and idx[k, 1] in local]
    kept_names = [names[k] for k in keep]
    pos = {n: i for i, n in enumerate(kept_names)}
    pair = np.arange(len(keep))
    for a, b in skeleton.symmetric_bones:
        if a in pos and b in pos:
            pair[pos[a]], pair[pos[b]] = pos[b], pos[a]
    ratios = femur_ratios(skeleton)
    sigma = np.array([ratios[n] for n in kept_names])
    femurs = np.array([pos[n] for n in kept_names if n.endswith("femur")], dtype=int)
    bones = np.array([[local[idx[k, 0]], local[idx[k, 1]]] for k in keep], dtype=int
                     ).reshape(-1, 2)
    hip = None
    if skeleton.mid_hip is not None:
        need = ("left_hip", "right_hip", skeleton.mid_hip)
        if all(skeleton.has(n) and skeleton.index(n) in local for n in need):
            hip = tuple(local[skeleton.index(n)] for n in need)
    return _Body(bones=bones, pair=pair, sigma=sigma, femurs=femurs, hip=hip)


# --------------------------------------------------------------------------- losses
class _Objective:
    """The six losses of eq. 8-14 on torch tensors, for one fixed virtual camera."""

    def __init__(self, torch, K, r_obs, m_obs, ok, body: _Body, frame_ids, gm_scale):
        self.torch = torch
        dt = torch.float64
        self.K = torch.tensor(K, dtype=dt)
        self.r_obs = torch.tensor(r_obs, dtype=dt)
        self.m_obs = torch.tensor(m_obs, dtype=dt)
        self.ok = torch.tensor(ok)
        self.okf = self.ok.to(dt)
        self.body = body
        self.c2 = float(gm_scale) ** 2
        b = body.bones
        self.ba = torch.tensor(b[:, 0], dtype=torch.long)
        self.bb = torch.tensor(b[:, 1], dtype=torch.long)
        okb = ok[:, b[:, 0]] & ok[:, b[:, 1]] if len(b) else np.zeros((len(ok), 0), bool)
        self.okb = torch.tensor(okb.astype(float), dtype=dt)
        self.pair = torch.tensor(body.pair, dtype=torch.long)
        paired = body.pair != np.arange(len(body.pair))
        oks = okb & okb[:, body.pair] & paired[None, :]
        self.oks = torch.tensor(oks.astype(float), dtype=dt)
        self.sigma = torch.tensor(body.sigma, dtype=dt)
        if len(body.femurs):
            okfem = okb[:, body.femurs]                       # (T, nf)
            self.femurs = torch.tensor(body.femurs, dtype=torch.long)
            self.okfem = torch.tensor(okfem)
            oka = okb & okfem.any(1)[:, None]
        else:
            self.femurs = None
            oka = np.zeros_like(okb)
        self.oka = torch.tensor(oka.astype(float), dtype=dt)
        if body.hip is not None:
            lh, rh, mh = body.hip
            okh = ok[:, lh] & ok[:, rh] & ok[:, mh]
            self.okh = torch.tensor(okh.astype(float), dtype=dt)
        # consecutive frames for the second difference
        fid = np.asarray(frame_ids)
        cons = np.zeros(len(fid), bool)
        if len(fid) >= 3:
            cons[1:-1] = (fid[2:] - fid[1:-1] == 1) & (fid[1:-1] - fid[:-2] == 1)
        oks2 = np.zeros_like(ok)
        if len(fid) >= 3:
            oks2[1:-1] = cons[1:-1, None] & ok[:-2] & ok[1:-1] & ok[2:]
        self.ok2 = torch.tensor(oks2[1:-1].astype(float), dtype=dt)
        self.set_camera(np.eye(3), np.array([1.0, 0.0, 0.0]))

    def set_camera(self, R, t):
        torch = self.torch
        M = geo.D_FLIP @ R
        c = geo.D_FLIP @ np.asarray(t, float)
        self.M = torch.tensor(M, dtype=torch.float64)
        self.c = torch.tensor(c, dtype=torch.float64)

    def _normalised(self, u):
        return (u - self.K[:2, 2]) @ torch_inv2(self.torch, self.K).T

    def triangulate(self, u, um):
        """Linear inhomogeneous triangulation, ``(T, J, 2)`` x 2 -> ``(T, J, 3)``."""
        torch = self.torch
        x = self._normalised(u)
        xm = self._normalised(um)
        M, c = self.M, self.c
        T, J = u.shape[:2]
        one = torch.ones(T, J, dtype=u.dtype)
        zero = torch.zeros(T, J, dtype=u.dtype)
        r1 = torch.stack([-one, zero, x[..., 0]], -1)
        r2 = torch.stack([zero, -one, x[..., 1]], -1)
        r3 = xm[..., :1] * M[2] - M[0]
        r4 = xm[..., 1:2] * M[2] - M[1]
        A = torch.stack([r1, r2, r3, r4], -2)                         # (T, J, 4, 3)
        b = torch.stack([zero, zero, -(xm[..., 0] * c[2] - c[0]),
                         -(xm[..., 1] * c[2] - c[1])], -1)            # (T, J, 4)
        AtA = A.transpose(-1, -2) @ A
        Atb = (A.transpose(-1, -2) @ b[..., None])
        return torch.linalg.solve(AtA, Atb)[..., 0]

    def _project(self, X):
        y = X @ self.K.T
        return y[..., :2] / y[..., 2:3]

    def losses(self, u, um):
        torch = self.torch
        eps = 1e-12
        X = self.triangulate(u, um)
        out = {}
        zero = X.sum() * 0.0
        if len(self.body.bones):
            d = X[:, self.ba] - X[:, self.bb]
            lk = torch.sqrt((d * d).sum(-1) + eps)                     # (T, B)
            w = self.okb
            cnt = w.sum(0)
            use = cnt >= 2
            mean = (lk * w).sum(0) / cnt.clamp(min=1)
            var = (((lk - mean) ** 2) * w).sum(0) / (cnt - 1).clamp(min=1)
            std = torch.sqrt(var + eps)
            out["var"] = torch.where(use, std / mean.clamp(min=eps), zero).sum()
            out["sym"] = (torch.abs(lk - lk[:, self.pair]) * self.oks).sum()
            if self.femurs is not None:
                lf = lk[:, self.femurs].masked_fill(~self.okfem, 0.0)
                fem = lf.max(1).values.clamp(min=eps)
                out["anth"] = ((((lk / fem[:, None]) - self.sigma) ** 2) * self.oka).sum()
            else:
                out["anth"] = zero
        else:
            out["var"] = out["sym"] = out["anth"] = zero
        if self.body.hip is not None:
            lh, rh, mh = self.body.hip
            vl = X[:, mh] - X[:, lh]
            vr = X[:, mh] - X[:, rh]
            cr = torch.linalg.cross(vl, vr)
            out["hip"] = (torch.sqrt((cr * cr).sum(-1) + eps) * self.okh).sum()
        else:
            out["hip"] = zero
        if X.shape[0] >= 3:
            acc = X[2:] - 2.0 * X[1:-1] + X[:-2]
            out["smooth"] = ((acc * acc).sum(-1) * self.ok2).sum()
        else:
            out["smooth"] = zero
        p1 = self._project(X)
        p2 = self._project(X @ self.M.T + self.c)
        e1 = torch.sqrt(((p1 - self.r_obs) ** 2).sum(-1) + eps)
        e2 = torch.sqrt(((p2 - self.m_obs) ** 2).sum(-1) + eps)
        e = e1 + e2
        rho = self.c2 * e * e / (self.c2 + e * e)
        out["repro"] = (rho * self.okf).sum()
        return out


def torch_inv2(torch, K):
    """``(2, 2)`` inverse of the upper-left block of ``K`` (skew allowed)."""
    return torch.linalg.inv(K[:2, :2])


# --------------------------------------------------------------------------- main entry
def mirrorcalib(real: np.ndarray, mirror: np.ndarray, K: np.ndarray, skeleton: Skeleton, *,
                valid: np.ndarray | None = None, joints: np.ndarray | None = None,
                frame_ids: np.ndarray | None = None,
                options: PaperOptions | None = None) -> PaperResult:
    """Run MirrorCalib as written on paired joints.

    Args:
        real: ``(T, J, 2|3)`` direct-view pixels (undistorted).
        mirror: ``(T, J, 2|3)`` mirror-view pixels in the *real joints' labels*
            (the reflection's labels already flipped, as the paper requires).
        K: ``(3, 3)`` intrinsics.
        skeleton: keypoint layout (bones, symmetric pairs, mid-hip).
        valid: ``(T, J)`` bool pairs to use (default: finite in both views).
        joints: joint indices used (default: the skeleton's calibration joints,
            no face, hands or feet, as the paper).
        frame_ids: ``(T,)`` frame numbers (consecutive frames for ``L_smooth``).
        options: :class:`PaperOptions`.

    Returns:
        :class:`PaperResult`.

    Raises:
        BenchDependencyError: PyTorch is not installed (only with ``refine=True``).
        DegenerateGeometryError: fewer than 6 usable pairs.
    """
    opts = options or PaperOptions()
    K = np.asarray(K, float)
    real = np.asarray(real, float)[..., :2]
    mirror = np.asarray(mirror, float)[..., :2]
    T, J = real.shape[:2]
    joints = skeleton.calibration_joints if joints is None else np.asarray(joints, int)
    fin = np.isfinite(real).all(-1) & np.isfinite(mirror).all(-1)
    ok_full = fin if valid is None else (np.asarray(valid, bool) & fin)
    r_obs = real[:, joints]
    m_obs = mirror[:, joints]
    ok = ok_full[:, joints]
    if np.count_nonzero(ok) < 6:
        raise DegenerateGeometryError(
            f"MirrorCalib needs at least 6 joint pairs, got {np.count_nonzero(ok)}")
    frame_ids = np.arange(T) if frame_ids is None else np.asarray(frame_ids)
    timings: dict[str, float] = {}

    t0 = time.perf_counter()
    F0 = fundamental_reflective_eight_point(r_obs[ok], m_obs[ok])
    R0, tr0, _ = pose_from_fundamental(F0, K, r_obs[ok], m_obs[ok])
    timings["initial"] = time.perf_counter() - t0

    r_ref, m_ref = r_obs.copy(), m_obs.copy()
    history: list[dict] = []
    lambdas: dict[str, float] = {}
    steps = 0
    if opts.refine:
        t0 = time.perf_counter()
        r_ref, m_ref, history, lambdas, steps = _refine(K, r_obs, m_obs, ok, R0, tr0, skeleton,
                                                        joints, frame_ids, opts)
        timings["refine"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    a, b = r_ref[ok], m_ref[ok]
    F, inl, iters = paper_ransac(a, b, opts)
    R, tr, n = pose_from_fundamental(F, K, a[inl], b[inl])
    timings["ransac"] = time.perf_counter() - t0

    inliers = np.zeros((T, J), bool)
    sub = np.zeros_like(ok)
    sub[ok] = inl
    inliers[:, joints] = sub
    rr = np.full((T, J, 2), np.nan)
    mr = np.full((T, J, 2), np.nan)
    rr[:, joints] = np.where(ok[..., None], r_ref, np.nan)
    mr[:, joints] = np.where(ok[..., None], m_ref, np.nan)
    X = triangulate_virtual(K, R, tr, rr, mr)
    return PaperResult(rotation=R, translation=tr, normal=n, fundamental=F,
                       initial_rotation=R0, initial_translation=tr0, inliers=inliers,
                       real_refined=rr, mirror_refined=mr, joints3d=X, steps=steps,
                       ransac_iterations=iters, history=history, lambdas=lambdas,
                       timings=timings)


def _refine(K, r_obs, m_obs, ok, R, tr, skeleton, joints, frame_ids, opts: PaperOptions):
    torch = require("torch", "MirrorCalib's refinement (mirrorgraph.baselines.paper)")
    if opts.threads is not None:
        torch.set_num_threads(int(opts.threads))
    body = _body(skeleton, joints)
    # fill unused entries with one valid pair so that every triangulation is finite;
    # the masks keep them out of every loss, so they get no gradient
    first = np.argwhere(ok)[0]
    r0 = np.where(ok[..., None], r_obs, r_obs[first[0], first[1]])
    m0 = np.where(ok[..., None], m_obs, m_obs[first[0], first[1]])
    obj = _Objective(torch, K, r0, m0, ok, body, frame_ids, opts.gm_scale_px)
    obj.set_camera(R, tr)
    u = torch.tensor(np.ascontiguousarray(r0), dtype=torch.float64, requires_grad=True)
    um = torch.tensor(np.ascontiguousarray(m0), dtype=torch.float64, requires_grad=True)
    with torch.no_grad():
        start = {k: float(v) for k, v in obj.losses(u, um).items()}
    lambdas = {}
    for k in LOSSES:
        w = float(opts.weights.get(k, 0.0))
        if w == 0.0 or start[k] <= 0.0 or not np.isfinite(start[k]):
            continue
        lambdas[k] = w / start[k] if opts.balance else w

    def total():
        L = obj.losses(u, um)
        return sum(lam * L[k] for k, lam in lambdas.items()), L

    history = [dict(step=0, **start, rotation_change_deg=float("nan"))]
    steps = 0
    R_prev = R
    for s in range(opts.steps):
        opt = torch.optim.LBFGS([u, um], lr=opts.lbfgs_lr, max_iter=opts.lbfgs_max_iter,
                                line_search_fn=opts.line_search)

        def closure():
            opt.zero_grad()
            loss, _ = total()
            loss.backward()
            return loss

        keep_u, keep_um = u.detach().clone(), um.detach().clone()
        try:
            opt.step(closure)
        except torch.linalg.LinAlgError:      # singular triangulation after a wild step
            u.data.copy_(keep_u)
            um.data.copy_(keep_um)
        with torch.no_grad():
            loss, L = total()
            bad = not (torch.isfinite(loss) and torch.isfinite(u).all()
                       and torch.isfinite(um).all())
            if bad:
                u.copy_(keep_u)
                um.copy_(keep_um)
        steps = s + 1
        if bad:
            history.append(dict(step=steps, diverged=True))
            break
        a = u.detach().numpy()[ok]
        b = um.detach().numpy()[ok]
        try:
            F = fundamental_reflective_eight_point(a, b)
            R_new, tr_new, _ = pose_from_fundamental(F, K, a, b)
        except (DegenerateGeometryError, np.linalg.LinAlgError):
            history.append(dict(step=steps, degenerate=True))
            break
        change = rotation_error_deg(R_prev, R_new)
        history.append(dict(step=steps, total=float(loss),
                            **{k: float(v) for k, v in L.items()},
                            rotation_change_deg=change))
        R_prev = R_new
        obj.set_camera(R_new, tr_new)
        if change < opts.stop_rotation_deg:
            break
    return u.detach().numpy().copy(), um.detach().numpy().copy(), history, lambdas, steps


def mirrorcalib_paired(paired, K: np.ndarray, *, min_confidence: float = 0.0,
                       joints: np.ndarray | None = None,
                       options: PaperOptions | None = None) -> PaperResult:
    """:func:`mirrorcalib` on a :class:`~mirrorgraph.keypoints.PairedKeypoints`."""
    valid = paired.valid(min_confidence)
    return mirrorcalib(paired.real, paired.mirror, K, paired.skeleton, valid=valid,
                       joints=joints, frame_ids=paired.frame_ids, options=options)
