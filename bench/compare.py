#!/usr/bin/env python
"""Side by side: mirrorgraph, the paper's MirrorCalib, and what a user would pick instead.

    python bench/compare.py                 # full run: 300 scenes, ~55 min on 2 cores
    python bench/compare.py --quick         # smoke run (~2.5 min), written to a temp folder
    python bench/compare.py --sweep-frames 300   # sweeps at T=300: roughly half the time
    python bench/compare.py --seeds 20 --jobs 2 --out bench/
    python bench/compare.py --replot        # tables and plots again from compare_results.json
    python bench/compare.py --tune-paper    # the grid that chose MirrorCalib's weights

Needs the ``bench`` extra (``torch``, ``aniposelib`` with its ``numba``, ``jax``,
``pandas``, ``toml``, ``tqdm``, and ``matplotlib``). A method whose library is
missing is reported as not run, not silently dropped.

Methods, on the same scenes:

``baseline1``  the paper's Baseline1: OpenCV's normalised eight-point without
               mirror constraint, pose from the essential matrix (``R`` as the
               decomposition gives it).
``paper``      MirrorCalib as written (:mod:`mirrorgraph.baselines.paper`): 6-unknown
               eight-point, L-BFGS refinement of the 2D joints on the six losses,
               RANSAC with six pairs.
``anipose``    aniposelib's ``bundle_adjust_iter`` on the person and the
               horizontally flipped reflection (:mod:`mirrorgraph.baselines.anipose`),
               started the way a user without a board would: OpenCV's five-point
               essential matrix with RANSAC on the flipped pairs.
``anipose_mg`` (headline table only) the same bundle adjustment started from
               mirrorgraph's initial estimate.
``mg_init``    mirrorgraph's initialisation only (``refine=False``).
``mg_full``    mirrorgraph's full pipeline with the factor graph, ``subject_height``
               given (the true height).

Inputs. mirrorgraph gets the raw detections (it pairs person and reflection and
fixes left/right itself, and that time is in its wall time). The other methods
get the ground-truth pairing with the reflection's labels flipped once by the
skeleton's map, but *not* the per-frame left/right confusions undone (the paper
does not detect them, and neither does aniposelib): ``scene.paired(fix_lr=False)``.
All methods get the true intrinsics and use the same joints (no face, hands or feet).

Metrics (MirrorCalib's definitions, :mod:`mirrorgraph.metrics`): rotation error
of the virtual camera (deg, axis-angle of ``R_est^T R_true``), translation error
after scaling the estimate to the true norm (mm), PA-MPJPE of the 3D joints each
method delivers (mm; baseline1, mg_init and aniposelib triangulate the
detections with their camera, the paper's method triangulates its refined 2D
joints, mg_full returns the graph's joints), evaluated on the calibration joints
seen in both views; wall time of the method call (single-threaded BLAS, two
scenes in parallel with ``--jobs 2``); peak memory of the call (the rise of the
process's peak resident set over its size before the call, measured for each
method in a fresh process on one protocol scene).

Cramer-Rao bound. For each scene the Fisher information of the two-view
reprojection model (direct and mirrored image of every joint observation that
is not an outlier, isotropic Gaussian noise of the scene's sigma) is formed at
the *true* plane and 3D joints; the 3D joints are eliminated (Schur complement,
what ``gtsam.Marginals`` of a reprojection-only graph at the truth computes),
leaving the 2x2 covariance of the mirror normal. The rotation error of a mirror
is twice the normal's angle, so the bound on the RMS rotation error is
``2 sqrt(trace Sigma_n)`` and its median (the Gaussian's) follows by sampling.
It is the limit for an unbiased estimator that uses the 2D joints alone and iid
noise; body priors (constant bones, symmetry) add information and can beat it,
correlated noise or biases make it unreachable.

Scenes (all :func:`mirrorgraph.synth.make_scene`, fixed seeds): the paper's
protocol (1920x1080, T=1000, noise mean 0.076 px, std 4 px, nothing else) and
sweeps around it, one plot each: noise std, frames, mirror angle to the optical
axis, outlier rate, temporally correlated noise, a per-joint detector bias,
left/right confusions, and real motion capture (the CMU take shipped in
``mirrorgraph/data``) when ``make_scene`` accepts ``motion``. Temporally correlated
noise and the per-joint bias are not part of ``make_scene``; they are added
here to noiseless projections:

* correlated noise: per joint, view and coordinate an AR(1) sequence
  ``e_t = rho e_{t-1} + sqrt(1 - rho^2) w_t``, ``w_t ~ N(0, 4^2)`` (stationary
  std 4 px, as the protocol), plus the protocol's 0.076 px mean;
* per-joint bias: every detector label ``j`` gets one fixed image offset
  ``b_j`` of the given length in a random direction, added to the person's
  joint ``j`` and, mirrored horizontally (the reflection *looks* mirrored), to
  the reflection's joint the detector calls ``j``; on top of the protocol's
  4 px noise.

Outputs: ``RESULTS.md`` (tables), ``compare_<sweep>.png`` (median and
inter-quartile band per method), ``compare_protocol.png`` and
``compare_results.json`` (every number, for ``--replot``).
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
           "NUMEXPR_NUM_THREADS", "VECLIB_MAXIMUM_THREADS"):
    os.environ.setdefault(_v, "1")
os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false "
                                   "intra_op_parallelism_threads=1")
os.environ.setdefault("JAX_PLATFORMS", "cpu")

import argparse  # noqa: E402
import inspect  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import textwrap  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
import warnings  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))      # bench/: _report

import _report  # noqa: E402
import mirrorgraph as mg  # noqa: E402
from mirrorgraph import geometry as geo  # noqa: E402
from mirrorgraph import metrics  # noqa: E402
from mirrorgraph.metrics import cramer_rao_mirror  # noqa: E402
from mirrorgraph.keypoints import PairedKeypoints, RawDetections  # noqa: E402
from mirrorgraph.synth import make_scene  # noqa: E402
from mirrorgraph.synth.mocap import cmu_example_path  # noqa: E402

METHODS = ("baseline1", "paper", "anipose", "mg_init", "mg_full")
HEADLINE_EXTRA = ("anipose_mg",)
LABELS = {
    "baseline1": "Baseline1 (OpenCV 8-point)",
    "paper": "MirrorCalib as written",
    "anipose": "aniposelib BA (5-point init)",
    "anipose_mg": "aniposelib BA (mirrorgraph init)",
    "mg_init": "mirrorgraph init",
    "mg_full": "mirrorgraph full graph",
}
COLORS = {"baseline1": "#8c8c8c", "paper": "#d62728", "anipose": "#ff7f0e",
          "anipose_mg": "#ffbb78", "mg_init": "#1f77b4", "mg_full": "#2ca02c"}

#: The paper's protocol (case study): 1920x1080, T = 1000, noise mean 0.076 px, std 4 px.
PROTOCOL = dict(frames=1000, image_size=(1920, 1080), noise_mean=0.076, noise_std=4.0)

#: Sweeps: name -> (parameter, values, axis label, log x). ``frames`` of the
#: other sweeps comes from ``--sweep-frames``.
SWEEPS = {
    "noise": ("noise_std", [1.0, 2.0, 4.0, 8.0, 12.0], "detector noise std (px)", False),
    "frames": ("frames", [30, 100, 300, 1000, 3000], "frames T", True),
    "angle": ("mirror_angle_deg", [10.0, 25.0, 40.0, 55.0, 70.0],
              "mirror normal to optical axis (deg)", False),
    "outliers": ("outlier_rate", [0.0, 0.05, 0.1, 0.2, 0.3], "outlier rate", False),
    "correlated": ("ar_rho", [0.0, 0.5, 0.9, 0.97, 0.99],
                   "AR(1) frame-to-frame correlation of the noise", False),
    "bias": ("bias_px", [0.0, 2.0, 4.0, 8.0], "per-joint detector bias (px)", False),
    "lr_swaps": ("lr_swap_rate", [0.0, 0.05, 0.1, 0.2, 0.3],
                 "frames with left/right confused on the reflection", False),
}
PERTURBATIONS = ("ar_rho", "bias_px")
BVH_DEFAULT = cmu_example_path()


# =========================================================================== scenes
@dataclass
class Case:
    """One scene: which sweep, which x, which seed, and the make_scene arguments."""

    sweep: str
    x: float | None
    seed: int
    params: dict = field(default_factory=dict)

    def key(self) -> str:
        return f"{self.sweep}|{self.x}|{self.seed}"


@dataclass
class Prepared:
    scene: object
    raw: RawDetections
    paired: PairedKeypoints
    eval_mask: np.ndarray        # (T, J) joints scored by PA-MPJPE
    crb_mask: np.ndarray         # (T, J) observations counted by the bound
    sigma: float


def build_case(case: Case) -> Prepared:
    """Make the scene of a case, with the perturbations make_scene does not offer."""
    kw = dict(PROTOCOL)
    kw.update({k: v for k, v in case.params.items() if k not in PERTURBATIONS})
    rho = float(case.params.get("ar_rho", 0.0) or 0.0)
    bias = float(case.params.get("bias_px", 0.0) or 0.0)
    perturb = "ar_rho" in case.params or "bias_px" in case.params
    sigma = float(kw.get("noise_std", 4.0))
    if perturb:
        noise_mean, noise_std = kw.pop("noise_mean"), kw.pop("noise_std")
        sc = make_scene(seed=case.seed, noise_mean=0.0, noise_std=0.0, **kw)
        rng = np.random.default_rng([case.seed, 7919])
        real = sc.real_observed.copy()
        mirror = sc.mirror_observed.copy()              # real-joint labels
        T, J = real.shape[:2]
        e = _ar1_noise(rng, (2, T, J, 2), rho, noise_std) + noise_mean
        if bias > 0:
            ang = rng.uniform(0, 2 * np.pi, J)
            b = bias * np.stack([np.cos(ang), np.sin(ang)], -1)          # per detector label
            flip = sc.skeleton.flip
            e[0] += b[None]
            bm = b[flip] * np.array([-1.0, 1.0])        # reflection's detector label of joint k
            e[1] += bm[None]
        w, h = sc.image_size
        for arr, ee in ((real, e[0]), (mirror, e[1])):
            arr[..., :2] += ee
            np.clip(arr[..., 0], 0.0, w - 1.0, out=arr[..., 0])
            np.clip(arr[..., 1], 0.0, h - 1.0, out=arr[..., 1])
        paired = PairedKeypoints(skeleton=sc.skeleton, frame_ids=sc.frame_ids.copy(), real=real,
                                 mirror=mirror, source=f"synthetic(seed={case.seed})+{case.sweep}",
                                 format="synthetic", image_size=tuple(sc.image_size), fps=sc.fps,
                                 lr_fixes=0, frames_read=T)
        raw = _raw_from_paired(paired, rng)
    else:
        sc = make_scene(seed=case.seed, **kw)
        paired = sc.paired(fix_lr=False)
        raw = sc.detections
    sk = sc.skeleton
    calib = np.zeros(sk.num_joints, bool)
    calib[sk.calibration_joints] = True
    seen = ~sc.missing_real & ~sc.missing_mirror & calib[None, :]
    crb = seen & ~sc.outlier_mask_real & ~sc.outlier_mask_mirror
    return Prepared(scene=sc, raw=raw, paired=paired, eval_mask=seen, crb_mask=crb, sigma=sigma)


def _ar1_noise(rng, shape, rho, sigma):
    """Stationary AR(1) noise along axis 1 (frames), std ``sigma``."""
    w = rng.normal(0.0, sigma, shape)
    if rho <= 0:
        return w
    out = np.empty(shape)
    out[:, 0] = w[:, 0]
    a = math.sqrt(1.0 - rho * rho)
    for t in range(1, shape[1]):
        out[:, t] = rho * out[:, t - 1] + a * w[:, t]
    return out


def _raw_from_paired(paired: PairedKeypoints, rng) -> RawDetections:
    """Detector output of paired keypoints: reflection in the detector's labels, random order."""
    flip = paired.skeleton.flip
    people = []
    for t in range(len(paired)):
        rows = [paired.real[t], paired.mirror[t][flip]]
        rows = [r for r in rows if np.isfinite(r[:, :2]).any()]
        if len(rows) == 2 and rng.random() < 0.5:
            rows = rows[::-1]
        people.append(np.stack(rows) if rows else np.zeros((0, paired.skeleton.num_joints, 3)))
    return RawDetections(skeleton=paired.skeleton, frame_ids=paired.frame_ids.copy(),
                         people=people, source=paired.source, format="synthetic",
                         image_size=paired.image_size, fps=paired.fps)


# =========================================================================== Cramer-Rao bound
#: The analytic bound lives in the package (one home); bench scripts import it from here too.
cramer_rao = cramer_rao_mirror


def scene_bound(prep: Prepared) -> dict:
    sc = prep.scene
    X = sc.joints3d[prep.crb_mask]
    return cramer_rao(sc.K, sc.normal, sc.distance, X, prep.sigma)


# =========================================================================== methods
def _calib_mask(paired: PairedKeypoints) -> np.ndarray:
    sk = paired.skeleton
    ok = paired.valid()
    sel = np.zeros(sk.num_joints, bool)
    sel[sk.calibration_joints] = True
    return ok & sel[None, :]


def _masked(arr, mask):
    out = np.array(arr[..., :2], dtype=float, copy=True)
    out[~mask] = np.nan
    return out


def run_baseline1(prep: Prepared, seed: int) -> dict:
    from mirrorgraph.baselines import triangulate_virtual
    from mirrorgraph.initial.estimators import estimate_mirror
    p, K = prep.paired, prep.scene.K
    ok = _calib_mask(p)
    est = estimate_mirror(p.real[ok][:, :2], p.mirror[ok][:, :2], K, estimator="eightpoint")
    R, t = est.decomposed_rotation, geo.D_FLIP @ est.normal
    X = triangulate_virtual(K, R, t, _masked(p.real, ok), _masked(p.mirror, ok))
    return dict(R=R, t=t, X=X)


def run_paper(prep: Prepared, seed: int) -> dict:
    from mirrorgraph.baselines.paper import PaperOptions, mirrorcalib_paired
    res = mirrorcalib_paired(prep.paired, prep.scene.K, options=PaperOptions(seed=seed))
    return dict(R=res.rotation, t=res.translation, X=res.joints3d,
                extra=dict(steps=res.steps, init_rot_deg=metrics.rotation_error_deg(
                    res.initial_rotation, prep.scene.virtual_R)))


def _run_anipose(prep: Prepared, seed: int, init: str) -> dict:
    from mirrorgraph.baselines.anipose import AniposeOptions, calibrate_anipose_paired
    res = calibrate_anipose_paired(prep.paired, prep.scene.K,
                                   options=AniposeOptions(init=init, seed=seed))
    return dict(R=res.rotation, t=res.translation, X=res.joints3d,
                extra=dict(reprojection_px=res.error, init_rot_deg=metrics.rotation_error_deg(
                    res.initial_rotation, prep.scene.virtual_R)))


def run_anipose(prep, seed):
    return _run_anipose(prep, seed, "essential")


def run_anipose_mg(prep, seed):
    return _run_anipose(prep, seed, "reflective")


def _frames_to_scene(run_frame_ids, scene_T, arr):
    out = np.full((scene_T,) + arr.shape[1:], np.nan)
    fid = np.asarray(run_frame_ids)
    ok = (fid >= 0) & (fid < scene_T)
    out[fid[ok]] = arr[ok]
    return out


def _run_mg(prep: Prepared, seed: int, refine: bool) -> dict:
    sc = prep.scene
    opts = mg.CalibrateOptions(refine=refine, seed=seed,
                               subject_height=sc.subject_height if refine else None)
    run = mg.calibrate(prep.raw, sc.intrinsics, opts)
    c = run.calibration
    T = len(sc)
    if refine and run.joints3d is not None:
        X = _frames_to_scene(run.paired.frame_ids, T, run.joints3d)
        extra = dict(reported_rot_std_deg=c.uncertainty.get("rotation_std_deg"))
    else:
        ok = _calib_mask(run.paired)
        Xr = geo.triangulate_mirror(sc.K, c.normal, 1.0, _masked(run.paired.real, ok),
                                    _masked(run.paired.mirror, ok))
        X = _frames_to_scene(run.paired.frame_ids, T, Xr)
        extra = {}
    return dict(R=c.virtual_rotation, t=c.virtual_translation, X=X, extra=extra)


def run_mg_init(prep, seed):
    return _run_mg(prep, seed, False)


def run_mg_full(prep, seed):
    return _run_mg(prep, seed, True)


RUNNERS = {"baseline1": run_baseline1, "paper": run_paper, "anipose": run_anipose,
           "anipose_mg": run_anipose_mg, "mg_init": run_mg_init, "mg_full": run_mg_full}


def evaluate(method: str, prep: Prepared, seed: int) -> dict:
    """Run one method on one scene and score it; failures are recorded, not raised."""
    sc = prep.scene
    rec = dict(method=method, ok=False)
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = RUNNERS[method](prep, seed)
    except Exception as exc:  # noqa: BLE001 - a failing method is a result
        rec.update(time_s=time.perf_counter() - t0, error=f"{type(exc).__name__}: {exc}"[:300])
        if isinstance(exc, ImportError):
            rec["not_installed"] = True
        return rec
    rec["time_s"] = time.perf_counter() - t0
    R, t = np.asarray(out["R"], float), np.asarray(out["t"], float)
    if not (np.all(np.isfinite(R)) and np.all(np.isfinite(t))):
        rec["error"] = "non-finite result"
        return rec
    rec["ok"] = True
    rec["rot_deg"] = metrics.rotation_error_deg(R, sc.virtual_R)
    rec["trans_mm"] = metrics.translation_error(t, sc.virtual_t) * 1000.0
    rec["normal_deg"] = metrics.normal_angle_deg(geo.D_FLIP @ t, sc.normal)
    X = out.get("X")
    if X is not None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rec["pampjpe_mm"] = metrics.pa_mpjpe(X, sc.joints3d, valid=prep.eval_mask) * 1000.0
    for k, v in (out.get("extra") or {}).items():
        rec[k] = v
    return rec


# =========================================================================== worker
_WARM = False


def _warm_up(methods):
    """Import every library and compile once (JAX, numba) outside the timed calls."""
    global _WARM
    if _WARM:
        return
    _WARM = True
    prep = build_case(Case("warmup", None, 12345, dict(frames=60)))
    for m in methods:
        evaluate(m, prep, 0)


def run_case(args) -> dict:
    case, methods = args
    _warm_up(methods)
    t0 = time.perf_counter()
    try:
        prep = build_case(case)
    except Exception as exc:  # noqa: BLE001
        return dict(case=case.__dict__, error=f"scene: {type(exc).__name__}: {exc}", results=[])
    bound = scene_bound(prep)
    results = [evaluate(m, prep, case.seed) for m in methods]
    sc = prep.scene
    info = dict(distance=sc.distance, mirror_angle_deg=float(np.degrees(np.arccos(sc.normal[2]))),
                pairs=int(prep.eval_mask.sum()))
    return dict(case=case.__dict__, crb=bound, scene=info, results=results,
                elapsed=time.perf_counter() - t0)


# =========================================================================== memory
def memory_probe(method: str, frames: int, seed: int) -> dict:
    """Peak RSS rise of one call in this (fresh) process, MB."""
    prep = build_case(Case("protocol", None, seed, dict(frames=frames)))
    _warm_up([method])
    import gc
    gc.collect()
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")                      # reset VmHWM to the current RSS
    except OSError:
        return dict(method=method, peak_mb=None, note="cannot reset the peak RSS")
    base = _status_kb("VmRSS")
    rec = evaluate(method, prep, seed)
    peak = _status_kb("VmHWM")
    return dict(method=method, peak_mb=(peak - base) / 1024.0, ok=rec.get("ok", False),
                time_s=rec.get("time_s"))


def _status_kb(key):
    with open("/proc/self/status") as fh:
        for line in fh:
            if line.startswith(key + ":"):
                return float(line.split()[1])
    return float("nan")


def measure_memory(methods, frames, seed) -> dict:
    out = {}
    for m in methods:
        cmd = [sys.executable, str(Path(__file__).resolve()), "--_memprobe", m,
               "--_memframes", str(frames), "--_memseed", str(seed)]
        try:
            p = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
            line = [ln for ln in p.stdout.splitlines() if ln.startswith("{")][-1]
            out[m] = json.loads(line)
        except Exception as exc:  # noqa: BLE001
            out[m] = dict(method=m, peak_mb=None, note=f"probe failed: {exc}")
    return out


# =========================================================================== plan
def plan(seeds: int, sweep_frames: int, quick: bool, bvh: Path | None) -> tuple[list, list]:
    """The cases to run and notes about rows skipped."""
    notes = []
    cases = [Case("protocol", None, s, dict(frames=PROTOCOL["frames"])) for s in range(seeds)]
    center = dict(noise_std=4.0, frames=PROTOCOL["frames"], outlier_rate=0.0, ar_rho=0.0,
                  bias_px=0.0, lr_swap_rate=0.0)
    for name, (param, values, _label, _log) in SWEEPS.items():
        if quick:
            values = [values[0], values[-1]] if name != "frames" else [30, sweep_frames]
        for x in values:
            # the protocol itself is the centre point of most sweeps: reuse it
            if (not quick and name != "angle" and sweep_frames == PROTOCOL["frames"]
                    and center.get(param) == x):
                continue
            for s in range(seeds):
                params = {param: x}
                if param != "frames":
                    params["frames"] = sweep_frames
                if param in PERTURBATIONS:
                    params.setdefault("ar_rho", 0.0)
                cases.append(Case(name, x, s, params))
    if "motion" not in inspect.signature(make_scene).parameters:
        notes.append("real motion (BVH) row skipped: make_scene does not accept `motion` yet")
    elif bvh is None or not Path(bvh).exists():
        notes.append(f"real motion (BVH) row skipped: no take at {bvh}")
    else:
        for s in range(seeds):
            cases.append(Case("bvh", None, s, dict(frames=sweep_frames if quick else
                                                    PROTOCOL["frames"], motion=str(bvh))))
    return cases, notes


def execute(cases, methods_for, jobs: int, log) -> list:
    tasks = [(c, methods_for(c)) for c in cases]
    # longest first for load balance
    order = sorted(range(len(tasks)), key=lambda i: -tasks[i][0].params.get("frames", 1000))
    tasks = [tasks[i] for i in order]
    out = []
    t0 = time.perf_counter()
    if jobs <= 1:
        it = map(run_case, tasks)
        pool = None
    else:
        import multiprocessing as mp
        pool = mp.get_context("spawn").Pool(jobs, maxtasksperchild=None)
        it = pool.imap_unordered(run_case, tasks)
    try:
        for k, res in enumerate(it, 1):
            out.append(res)
            el = time.perf_counter() - t0
            c = res["case"]
            line = " ".join(f"{r['method']}={r['rot_deg']:.2f}" if r.get("ok") else
                            f"{r['method']}=FAIL" for r in res["results"])
            log(f"[{k}/{len(tasks)} {el / 60:5.1f} min, eta {el / k * (len(tasks) - k) / 60:5.1f}]"
                f" {c['sweep']} x={c['x']} seed={c['seed']}: {line}")
    finally:
        if pool is not None:
            pool.close()
            pool.join()
    return out


# =========================================================================== summary
def _vals(rows, method, key):
    v = []
    for r in rows:
        for m in r["results"]:
            if m["method"] != method:
                continue
            v.append(m.get(key, np.nan) if m.get("ok") else np.inf)
    return np.asarray(v, float)


def _stat(v):
    """median, p25, p75 with failures (inf) counted as the worst values; NaN ignored."""
    v = v[~np.isnan(v)]
    if v.size == 0:
        return (np.nan, np.nan, np.nan)
    return tuple(float(np.percentile(v, q)) for q in (50, 25, 75))


def _fmt(x, digits=2):
    if x is None or (isinstance(x, float) and np.isnan(x)):
        return "–"
    if np.isinf(x):
        return "fail"
    if abs(x) >= 100:
        return f"{x:.0f}"
    if abs(x) >= 10:
        return f"{x:.1f}"
    return f"{x:.{digits}f}"


def _cell(v, digits=2):
    m, lo, hi = _stat(v)
    if np.isnan(m):
        return "–"
    return f"{_fmt(m, digits)} [{_fmt(lo, digits)}, {_fmt(hi, digits)}]"


def _rms(v):
    v = v[~np.isnan(v)]
    if v.size == 0:
        return np.nan
    if np.isinf(v).any():
        return np.inf
    return float(np.sqrt(np.mean(v ** 2)))


def _crb(rows, key):
    return np.asarray([r["crb"][key] for r in rows if "crb" in r], float)


def summarise(data: dict) -> str:
    rows = data["rows"]
    meta = data["meta"]
    methods = meta["methods"]
    mem = data.get("memory", {})
    L = []
    L.append("# mirrorgraph vs MirrorCalib vs aniposelib (`bench/compare.py`)\n")
    L.append(f"Generated by `python bench/compare.py {meta.get('argv', '')}`".rstrip() +
             f" on {meta['date']} ({meta['elapsed_min']:.1f} min, {meta['jobs']} parallel "
             f"scene(s), single-threaded BLAS). {meta['seeds']} seeds per point; every cell is "
             "*median [25th, 75th percentile]* over seeds; a failed run counts as the worst "
             "value. Methods, inputs, metrics and the bound are described in the docstring "
             "of `bench/compare.py`; the paper's method and its ambiguities in "
             "`mirrorgraph/baselines/paper.py`.\n")
    for n in meta.get("notes", []):
        L.append(f"> note: {n}\n")
    prot = [r for r in rows if r["case"]["sweep"] == "protocol"]
    if prot:
        T_prot = prot[0]["case"]["params"].get("frames", PROTOCOL["frames"])
        L.append(f"## The paper's protocol ({len(prot)} scenes)\n")
        L.append("![protocol](compare_protocol.png)\n")
        L.append(f"1920x1080, T = {T_prot} frames, COCO-17, Gaussian detector noise mean "
                 "0.076 px, std 4 px, no outliers, no missing joints, mirror normal at a random "
                 "10-60 deg to the optical axis, 2.5-4.5 m away.\n")
        crb_rms = _crb(prot, "rot_rms_deg")
        crb_med = _crb(prot, "rot_median_deg")
        crb_tr = _crb(prot, "trans_rms_mm")
        L.append("| method | rotation (deg) | translation (mm) | PA-MPJPE (mm) | rot. RMS (deg) "
                 "| RMS / bound | time (s) | peak mem (MB) | failed |")
        L.append("|---|---|---|---|---|---|---|---|---|")
        bound_rms = _rms(crb_rms)
        for m in methods + [x for x in HEADLINE_EXTRA if x in meta.get("headline_extra", [])]:
            rot = _vals(prot, m, "rot_deg")
            if rot.size == 0:
                continue
            fails = int(np.sum(np.isinf(rot)))
            rms = _rms(rot)
            mm = mem.get(m, {}).get("peak_mb")
            L.append(f"| {LABELS[m]} | {_cell(rot)} | {_cell(_vals(prot, m, 'trans_mm'), 1)} | "
                     f"{_cell(_vals(prot, m, 'pampjpe_mm'), 1)} | {_fmt(rms)} | "
                     f"{_fmt(rms / bound_rms if np.isfinite(rms) else np.inf)} | "
                     f"{_cell(_vals(prot, m, 'time_s'))} | {_fmt(mm, 1)} | {fails}/{rot.size} |")
        L.append(f"| Cramér-Rao bound (2D joints alone) | {_cell(crb_med, 3)} | "
                 f"{_cell(crb_tr, 1)} | – | {_fmt(bound_rms, 3)} | 1 | – | – | – |\n")
        rep = _vals(prot, "mg_full", "reported_rot_std_deg")
        if rep.size and np.isfinite(rep).any():
            fin = rep[np.isfinite(rep)]
            L.append(f"mirrorgraph's reported uncertainty (calibration.json's headline: the "
                     f"larger of the marginals and the cluster-robust figure): rotation "
                     f"std median {_fmt(float(np.median(fin)), 3)} deg; its actual RMS rotation "
                     f"error is {_fmt(_rms(_vals(prot, 'mg_full', 'rot_deg')), 3)} deg.\n")
        ini = _vals(prot, "paper", "init_rot_deg")
        if ini.size:
            L.append(f"MirrorCalib's own initial estimate (6-unknown eight-point, before "
                     f"refinement and RANSAC): rotation {_cell(ini)} deg.\n")
    bvh = [r for r in rows if r["case"]["sweep"] == "bvh"]
    if bvh:
        L.append(f"## Real motion: CMU motion capture take 01_01 ({len(bvh)} scenes)\n")
        L.append("The protocol with the CMU take (jumps, turning around) instead of the "
                 "procedural exercise motion.\n")
        L.append("| method | rotation (deg) | translation (mm) | PA-MPJPE (mm) | time (s) |")
        L.append("|---|---|---|---|---|")
        for m in methods:
            L.append(f"| {LABELS[m]} | {_cell(_vals(bvh, m, 'rot_deg'))} | "
                     f"{_cell(_vals(bvh, m, 'trans_mm'), 1)} | "
                     f"{_cell(_vals(bvh, m, 'pampjpe_mm'), 1)} | {_cell(_vals(bvh, m, 'time_s'))} |")
        L.append(f"| Cramér-Rao bound | {_cell(_crb(bvh, 'rot_median_deg'), 3)} | "
                 f"{_cell(_crb(bvh, 'trans_rms_mm'), 1)} | – | – |\n")
    for name, (param, values, label, _log) in SWEEPS.items():
        pts = _sweep_points(rows, name, param)
        if not pts:
            continue
        L.append(f"## Sweep: {label}\n")
        L.append(f"![{name}](compare_{name}.png)\n")
        for key, title, dg in (("rot_deg", "rotation error (deg)", 2),
                               ("pampjpe_mm", "PA-MPJPE (mm)", 1)):
            head = "| " + param + " | " + " | ".join(LABELS[m] for m in methods)
            if key == "rot_deg":
                head += " | bound (median) |"
            else:
                head += " |"
            L.append(f"**{title}**\n")
            L.append(head)
            L.append("|" + "---|" * (len(methods) + 1 + (key == "rot_deg")))
            for x, sub in pts:
                cells = [_cell(_vals(sub, m, key), dg) for m in methods]
                if key == "rot_deg":
                    cells.append(_fmt(float(np.median(_crb(sub, "rot_median_deg"))), 3))
                L.append(f"| {x:g} | " + " | ".join(cells) + " |")
            L.append("")
    fails = {}
    for r in rows:
        for m in r["results"]:
            if not m.get("ok"):
                fails.setdefault(m["method"], []).append(
                    f"{r['case']['sweep']} x={r['case']['x']} seed={r['case']['seed']}: "
                    f"{m.get('error', '?')}")
    if fails:
        L.append("## Failures\n")
        for m, lst in fails.items():
            L.append(f"* {LABELS.get(m, m)}: {len(lst)} run(s); first: {lst[0]}")
        L.append("")
    return "\n".join(L) + "\n"


def _sweep_points(rows, name, param):
    """(x, rows) per sweep value; the protocol rows stand in for the omitted centre point."""
    pts = {}
    for r in rows:
        c = r["case"]
        if c["sweep"] == name:
            pts.setdefault(float(c["x"]), []).append(r)
    if name in SWEEPS and name != "angle" and pts:
        param, values, *_ = SWEEPS[name]
        center = dict(noise_std=4.0, frames=PROTOCOL["frames"], outlier_rate=0.0, ar_rho=0.0,
                      bias_px=0.0, lr_swap_rate=0.0).get(param)
        prot = [r for r in rows if r["case"]["sweep"] == "protocol"]
        sweep_T = {r["case"]["params"].get("frames") for r in rows if r["case"]["sweep"] == name}
        same_T = name == "frames" or sweep_T == {PROTOCOL["frames"]}
        if center is not None and float(center) not in pts and prot and same_T:
            pts[float(center)] = prot
    return sorted(pts.items())


def plot(data: dict, out: Path) -> list[Path]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows, methods = data["rows"], data["meta"]["methods"]
    files = []
    for name, (param, _values, label, logx) in SWEEPS.items():
        pts = _sweep_points(rows, name, param)
        if len(pts) < 2:
            continue
        fig, axes = plt.subplots(1, 2, figsize=(12, 4.4))
        xs = np.array([x for x, _ in pts])
        for ax, key, ylab in ((axes[0], "rot_deg", "rotation error of the virtual camera (deg)"),
                              (axes[1], "pampjpe_mm", "PA-MPJPE (mm)")):
            for m in methods:
                st = np.array([_stat(_vals(sub, m, key)) for _, sub in pts])
                if np.all(np.isnan(st[:, 0])):
                    continue
                med = np.where(np.isinf(st), np.nan, st)
                ax.plot(xs, med[:, 0], "o-", color=COLORS[m], label=LABELS[m], lw=1.8, ms=4)
                ax.fill_between(xs, med[:, 1], med[:, 2], color=COLORS[m], alpha=0.15, lw=0)
            if key == "rot_deg":
                b = [float(np.median(_crb(sub, "rot_median_deg"))) for _, sub in pts]
                ax.plot(xs, b, "k--", lw=1.2, label="Cramér-Rao bound (median)")
            ax.set_yscale("log")
            if logx:
                ax.set_xscale("log")
            ax.set_xlabel(label)
            ax.set_ylabel(ylab)
            ax.grid(True, which="both", alpha=0.3)
        axes[0].legend(fontsize=8, loc="best")
        fig.suptitle(f"{label}: median and inter-quartile range over "
                     f"{data['meta']['seeds']} seeds")
        fig.tight_layout()
        path = out / f"compare_{name}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        files.append(path)
    prot = [r for r in rows if r["case"]["sweep"] == "protocol"]
    if prot:
        ms = methods + [x for x in HEADLINE_EXTRA if x in data["meta"].get("headline_extra", [])]
        fig, axes = plt.subplots(1, 2, figsize=(13, 5))
        for ax, key, ylab in ((axes[0], "rot_deg", "rotation error (deg)"),
                              (axes[1], "pampjpe_mm", "PA-MPJPE (mm)")):
            vals = []
            for m in ms:
                v = _vals(prot, m, key)
                vals.append(v[np.isfinite(v)])
            ax.boxplot(vals, showfliers=True)
            ax.set_xticks(range(1, len(ms) + 1),
                          ["\n".join(textwrap.wrap(LABELS[m], 16)) for m in ms], fontsize=7)
            if key == "rot_deg":
                b = float(np.median(_crb(prot, "rot_median_deg")))
                ax.axhline(b, color="k", ls="--", lw=1, label="Cramér-Rao bound (median)")
                ax.legend(fontsize=8)
            ax.set_yscale("log")
            ax.set_ylabel(ylab)
            ax.grid(True, axis="y", which="both", alpha=0.3)
        T_prot = prot[0]["case"]["params"].get("frames", PROTOCOL["frames"])
        fig.suptitle(f"The paper's protocol (1920x1080, T={T_prot}, noise 4 px): "
                     f"{len(prot)} seeds")
        fig.tight_layout()
        path = out / "compare_protocol.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        files.append(path)
    return files


def print_table(data: dict) -> None:
    prot = [r for r in data["rows"] if r["case"]["sweep"] == "protocol"]
    methods = data["meta"]["methods"] + [x for x in HEADLINE_EXTRA
                                         if x in data["meta"].get("headline_extra", [])]
    print(f"\nThe paper's protocol, {len(prot)} seeds: median [p25, p75]")
    print(f"{'method':34s} {'rotation deg':>22s} {'translation mm':>22s} {'PA-MPJPE mm':>22s}"
          f" {'time s':>8s} {'mem MB':>7s}")
    mem = data.get("memory", {})
    for m in methods:
        rot = _vals(prot, m, "rot_deg")
        if rot.size == 0:
            continue
        print(f"{LABELS[m]:34s} {_cell(rot):>22s} {_cell(_vals(prot, m, 'trans_mm'), 1):>22s} "
              f"{_cell(_vals(prot, m, 'pampjpe_mm'), 1):>22s} "
              f"{_fmt(_stat(_vals(prot, m, 'time_s'))[0]):>8s} "
              f"{_fmt(mem.get(m, {}).get('peak_mb'), 1):>7s}")
    if prot:
        print(f"{'Cramér-Rao bound (median)':34s} {_cell(_crb(prot, 'rot_median_deg'), 3):>22s} "
              f"{_cell(_crb(prot, 'trans_rms_mm'), 1):>22s}")


# =========================================================================== paper tuning
def tune_paper(seeds=range(900, 910), grid=(1.0, 3.0, 10.0, 30.0, 100.0), frames=1000,
               log=print):
    """The grid search that chose MirrorCalib's reprojection weight (tuning seeds only)."""
    from mirrorgraph.baselines.paper import DEFAULT_WEIGHTS, PaperOptions, mirrorcalib_paired
    preps = [build_case(Case("tune", None, s, dict(frames=frames))) for s in seeds]
    results = {}
    for label, opts in [("no refinement", dict(refine=False))] + \
            [(f"w_repro={w:g}", dict(weights=dict(DEFAULT_WEIGHTS, repro=w))) for w in grid]:
        errs = []
        for s, prep in zip(seeds, preps):
            try:
                r = mirrorcalib_paired(prep.paired, prep.scene.K,
                                       options=PaperOptions(seed=s, **opts))
                errs.append(metrics.rotation_error_deg(r.rotation, prep.scene.virtual_R))
            except mg.MirrorgraphError:
                errs.append(np.inf)             # refinement diverged: RANSAC found no model
        results[label] = errs
        log(f"{label:16s} median {np.median(errs):.3f} deg  mean {np.mean(errs):.3f}  "
            f"all {np.round(errs, 2).tolist()}")
    return results


# =========================================================================== main
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fast smoke run (2 seeds, 120 frames, "
                    "two points per sweep); written to a temporary folder unless --out is given")
    ap.add_argument("--seeds", type=int, default=None, help="seeds per point (default 10; 2 "
                    "with --quick)")
    ap.add_argument("--out", type=Path, default=None, help="output folder (default bench/)")
    ap.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1),
                    help="scenes run in parallel (default 2)")
    ap.add_argument("--sweep-frames", type=int, default=None,
                    help="frames of the sweep scenes (default 1000, the protocol's; 120 quick)")
    ap.add_argument("--methods", default=",".join(METHODS),
                    help=f"comma-separated subset of {','.join(METHODS)}")
    ap.add_argument("--only", default=None, help="comma-separated subset of sweeps "
                    f"(protocol,bvh,{','.join(SWEEPS)})")
    ap.add_argument("--no-memory", action="store_true", help="skip the peak-memory probes")
    ap.add_argument("--bvh", type=Path, default=BVH_DEFAULT, help="motion-capture take")
    ap.add_argument("--replot", action="store_true",
                    help="rebuild tables and plots from <out>/compare_results.json")
    ap.add_argument("--tune-paper", action="store_true",
                    help="run the weight grid of MirrorCalib on the tuning seeds and exit")
    ap.add_argument("--_memprobe", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--_memframes", type=int, default=1000, help=argparse.SUPPRESS)
    ap.add_argument("--_memseed", type=int, default=0, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)

    if a._memprobe:
        print(json.dumps(memory_probe(a._memprobe, a._memframes, a._memseed)))
        return 0
    if a.tune_paper:
        tune_paper()
        return 0

    out = a.out
    if out is None:
        out = Path(tempfile.mkdtemp(prefix="mirrorgraph-compare-quick-")) if a.quick \
            else ROOT / "bench"
    out.mkdir(parents=True, exist_ok=True)
    results_path = out / "compare_results.json"

    if a.replot:
        data = json.loads(results_path.read_text())
    else:
        seeds = a.seeds or (2 if a.quick else 10)
        sweep_frames = a.sweep_frames or (120 if a.quick else PROTOCOL["frames"])
        methods = [m.strip() for m in a.methods.split(",") if m.strip()]
        bad = [m for m in methods if m not in METHODS]
        if bad:
            ap.error(f"unknown method(s) {bad}")
        cases, notes = plan(seeds, sweep_frames, a.quick, a.bvh)
        if a.quick:
            for c in cases:
                if c.sweep in ("protocol", "bvh"):
                    c.params["frames"] = sweep_frames
        if a.only:
            keep = {s.strip() for s in a.only.split(",")}
            cases = [c for c in cases if c.sweep in keep]
        headline_extra = [m for m in HEADLINE_EXTRA if "anipose" in methods]

        def methods_for(c):
            return methods + (headline_extra if c.sweep == "protocol" else [])

        print(f"{len(cases)} scenes x {len(methods)} methods, {a.jobs} job(s); output in {out}")
        for n in notes:
            print(f"note: {n}")
        t0 = time.perf_counter()
        rows = execute(cases, methods_for, a.jobs, lambda s: print(s, flush=True))
        memory = {}
        if not a.no_memory:
            print("measuring peak memory (one fresh process per method)...", flush=True)
            memory = measure_memory(methods + headline_extra,
                                    sweep_frames if a.quick else PROTOCOL["frames"], 0)
        data = dict(meta=dict(methods=methods, headline_extra=headline_extra, seeds=seeds,
                              sweep_frames=sweep_frames, quick=a.quick, jobs=a.jobs,
                              notes=notes, date=time.strftime("%Y-%m-%d %H:%M"),
                              machine=_report.machine(),
                              elapsed_min=(time.perf_counter() - t0) / 60.0,
                              argv=" ".join(sys.argv[1:] if argv is None else argv),
                              versions=_versions()),
                    rows=rows, memory=memory)
        results_path.write_text(json.dumps(data, indent=1, default=_json_default))
    md = _preface(data) + summarise(data)
    name = "RESULTS.md"
    from results_blocks import keep_blocks       # the other benchmarks' sections stay
    (out / name).write_text(keep_blocks(out / name, md))
    files = plot(data, out)
    print_table(data)
    for n in data["meta"].get("notes", []):
        print(f"note: {n}")
    print(f"\nwrote {out / name}, {results_path.name} and {len(files)} plot(s) in {out}")
    return 0


def _preface(data: dict) -> str:
    """The head of bench/RESULTS.md: the run's date, command and machine
    (:func:`_report.header`, as recorded with the figures), and the other benchmarks'
    files."""
    meta = data["meta"]
    return "\n".join([
        "# Benchmark results",
        "",
        *_report.header(started=meta.get("date") or _report.NOT_RECORDED,
                        cmd=f"python bench/compare.py {meta.get('argv', '')}".rstrip(),
                        machine_line=meta.get("machine") or _report.NOT_RECORDED),
        "",
        "The machine is shared and noisy: compare within one run. Rerun the command, or "
        "`--replot` from `compare_results.json`. The other benchmarks write their own "
        "files, each with its date, command and machine:",
        "",
        "* [RESULTS_ablation.md](RESULTS_ablation.md): `python bench/bench_ablation.py` — "
        "end-to-end time split on 1000 frames, and the graph with each prior switched off "
        "on a realistic detector;",
        "* [RESULTS_graph.md](RESULTS_graph.md): `python bench/bench_graph.py` — the graph's "
        "time and peak memory at 1k, 10k and 54k frames, accuracy against the bound per scene;",
        "* [RESULTS_scale.md](RESULTS_scale.md): `python bench/bench_scale.py` — end to end "
        "from an OpenPose folder at 1k, 10k and 54k frames: time split and peak memory;",
        "* [RESULTS_bound.md](RESULTS_bound.md): `python bench/bench_bound.py` — the "
        "Cramer-Rao bound across scene geometries;",
        "* [RESULTS_stature.md](RESULTS_stature.md): `python bench/bench_stature.py` — the "
        "metric scale from the measured stature against limb proportions;",
        "* [RESULTS_rig.md](RESULTS_rig.md): `python bench/bench_rig.py` — rigs of several "
        "cameras and mirrors; its comparison with aniposelib is also the last section here.",
        "",
        "",
    ])


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    return str(o)


def _versions() -> dict:
    import platform
    v = dict(python=platform.python_version(), numpy=np.__version__,
             mirrorgraph=getattr(mg, "__version__", "?"))
    for mod in ("torch", "aniposelib", "cv2", "gtsam", "jax"):
        try:
            m = __import__(mod)
            v[mod] = getattr(m, "__version__", "?")
        except Exception:  # noqa: BLE001
            v[mod] = None
    return v


if __name__ == "__main__":
    try:
        sys.exit(main())
    except KeyboardInterrupt:
        traceback.print_exc()
        sys.exit(130)
