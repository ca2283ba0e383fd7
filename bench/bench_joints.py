"""The 3D joints users take home, against the true joints: offline ``calibrate`` and ``live``.

Every scene is calibrated as a user runs it (the camera matrix and the subject's height
given, the scene's frame rate: 30 fps unless its detections say): ``calibrate`` through the Python API in this process, as the command line
runs it (:func:`mirrorgraph.calibrate`, its ``joints3d`` where ``valid3d``: what
``--joints3d`` writes), and ``live`` (:class:`mirrorgraph.live.LiveCalibrator` fed the
keypoints frame by frame, windows solved in the calling thread: every frame's
``joints3d`` as the JSON lines carry it). Each output joint is scored against the
scene's true joint:

* **MPJPE** (mm, no alignment: the metric scale's error included) and **PA-MPJPE** (mm,
  each frame's similarity alignment, :func:`mirrorgraph.metrics.pa_mpjpe`, the paper's
  Table 2 metric);
* the **oracle**: each frame triangulated with the TRUE mirror from the same 2D
  observations, the outliers removed with the truth
  (:func:`mirrorgraph.geometry.triangulate`), its PA-MPJPE, and the run's over it; the
  same ratio with both on the joints both give (the oracle's mean holds the few joints of
  near-parallel rays, metres off, that a run may leave out);
* the **tail**: the share of the output joints more than 0.3 m and 1 m from the truth,
  the worst joint (m); the share more than 0.3 m off once each frame's common scale
  error is taken out (its joints times the least-squares factor about the camera: what
  is left without the metric scale's error); the share of the scene's joints given;
* the joints' **error / std** (median, 99th percentile: the error's length over the
  joint's std, the RMS length of the error it claims) where the result carries per-joint
  stds (``run.joints_std`` / the npz's ``joints_std``, ``LiveFrame.joints_std``;
  ``n/a`` otherwise), and the same over the std without the metric scale's share
  (``joints_std_shape``) where given, against the error left once the run's scale is
  fitted to the truth (``live``: each fused mirror's own, over the frames it served);
  the metric **distance's** error and error / std;
* **time** per run (wall and CPU seconds of this process).

Over the scenes of each kind: the median and the worst scene of every figure, and the
targets (``PA-MPJPE`` against the oracle's, the gross shares, the stds' honesty, live
against offline) met or not. The gross joints (more than 0.3 m off) are broken down by
joint name and by *mode*, judged against the joint's own 2D observations (in the true
labels) with the run's mirror: ``depth`` (reprojects within ``MODE_PX`` in both views, both observations
clean: on its two rays, off in depth), ``off`` (more than ``MODE_PX`` from a clean
observation: the graph left it), ``swap`` (off, but within ``MODE_PX`` of the
left/right partner's observation in that view: the pair was labelled the wrong way round),
``outlier`` (within ``MODE_PX`` of a planted outlier: it followed one), ``one view`` (at
most one clean observation: the depth is the body's).

Scenes (``--kinds``):

* ``iid``, ``realistic``: :func:`mirrorgraph.synth.make_wide_scene` (slice ``wide``,
  the two detector models);
* ``cmu``: the same wide scenes (iid detector) moved by the CMU motion-capture take the
  package ships (``mirrorgraph/data/cmu_01_01.bvh``);
* ``lowpar``: the ``low_parallax`` slice (the wide ranges with the person near the
  camera-mirror line, rays 2-12 deg apart), iid detector;
* ``paper``: MirrorCalib's protocol on the project's generator (``make_scene``: the
  ``favourable`` geometry, 4 px iid noise of mean 0.076 px, 3 % outliers);
* ``fixtures``: the scenes of an independent generator in ``--fixtures`` (default
  ``shared/fixtures`` in the nearest folder above the repository; none when absent): their
  ``keypoints.json``, ``camera.json``, ``truth.json`` (the subject's height),
  ``joints3d_truth.npz``. Their observations are put in the true labels and pairs with
  the truth (each detection matched to the projection of the true joints, either
  labelling), an observation more than ``FIXTURE_OUTLIER_PX`` from it an outlier.

The subject's height each run is given (``--height-given``) is by default the one a user
reports (:data:`REPORTED_HEIGHT_BIAS_M`, :data:`REPORTED_HEIGHT_STD_M`: one draw a
scene), so that the metric scale's share of every joint's std (``height_sigma``) meets
an error of the kind users make; the synthetic bodies' proportions (``--body``) spread as
adults' do. The metric scale's error is one draw a run: its error / std
(``scale_rel_std``, the share of ``joints_std`` that ``joints_std_shape`` leaves out) is
read over many scenes, the shape's over every joint. ``--keypoint-offset METRES`` states
the keypoints' placement off the anatomical landmarks the runs' metric scale std holds
(``RefineOptions.keypoint_offset``; default the literature's,
:data:`mirrorgraph.anthropometry.KEYPOINT_OFFSET` of the height): ``0`` for keypoints
that sit on the joints, as the synthetic iid ones do. ``--height-sigma FRACTION`` states
the given height's relative std (``RefineOptions.height_sigma``): ``0.013`` the reported
heights' (the 1.1 cm bias and 1.9 cm spread in quadrature over ~1.7 m).

Usage::

    python bench/bench_joints.py                       # 16 scenes, ~8 min on 2 busy cores
    python bench/bench_joints.py --full                # 72 scenes, ~40 min on 2 busy cores
    python bench/bench_joints.py --kinds iid,fixtures --seeds 0-3 --methods calibrate
    python bench/bench_joints.py --json after.json --out /tmp/after.md
    python bench/bench_joints.py --body model --height-given exact   # the true height, 3 % bodies
    python bench/bench_joints.py --methods calibrate --keypoint-offset 0 --out /tmp/k0.md
    python bench/bench_joints.py --methods calibrate --keypoint-offset 0 --height-sigma 0.013
    python bench/bench_joints.py --methods calibrate --refine joints_bone_lengths=integrated \\
        --refine torso_sigma=0.02 --out /tmp/lt.md      # graph options set
    python bench/bench_joints.py --compare bench/RESULTS_joints_before.json after.json
    python bench/bench_joints.py --methods live --offline-from bench/RESULTS_joints.json

Writes ``--out`` (default ``bench/RESULTS_joints.md``: machine, command, date, tables)
unless ``--no-write``, and ``--json`` (every number) where given. ``--compare A.json B.json`` prints
two such runs side by side (each kind's medians and worst scenes with their ratios, the
targets, every scene common to both), the summaries recomputed from the scenes.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import shlex
import subprocess
import sys
import time
import zlib
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _report  # noqa: E402  (the machine line every results file shares)

ROOT = Path(__file__).resolve().parents[1]
FPS = 30.0


def scene_fps(tr) -> float:
    """The scene's frame rate, Hz: its detections', else :data:`FPS`."""
    f = getattr(tr.detections, "fps", None)
    return float(f) if f and np.isfinite(f) and f > 0 else FPS

#: a joint more than this far from the truth is gross (m), and badly gross
GROSS_M, FAR_M = 0.3, 1.0
#: a reprojection within this of its observation (px) is "on" it (the 95 % circle of
#: 4 px iid noise per coordinate is 9.8 px)
MODE_PX = 10.0
#: a fixture observation this far (px) from the true joint's projection is an outlier
#: (their detector: 4 px noise, outliers of 20-200 px)
FIXTURE_OUTLIER_PX = 15.0
MODES = ("depth", "off", "outlier", "one view", "swap")
KINDS = ("iid", "realistic", "cmu", "lowpar", "paper", "fixtures")
#: The height a user gives (``--height-given reported``): their own report, ``true + bias +
#: std z`` (m), ``z`` standard normal, one draw a scene. Adults over-report their height by
#: 1.0-1.6 cm on average (men 1.6, women 1.0: S. Scholes et al., Health Survey for England
#: 2011-16, 38,942 adults, medRxiv 10.1101/2022.01.28.22270014) and 1.07 cm (the Danish
#: Diet, Cancer and Health - Next Generations cohort, 39,514 adults, medRxiv
#: 10.1101/2022.12.20.22283553), where the reported and measured heights correlate at r =
#: 0.98: with an adult height std of ~9.5 cm (both sexes), the difference's std is
#: ``9.5 sqrt(2 (1 - r)) = 1.9`` cm. ``exact``: the true height.
REPORTED_HEIGHT_BIAS_M, REPORTED_HEIGHT_STD_M = 0.011, 0.019
HEIGHT_GIVEN = ("reported", "exact")
#: The synthetic bodies' proportions (``--body``): ``population``, each segment kind's
#: spread among adults (:data:`mirrorgraph.synth.body.POPULATION_VARIATION`); ``model``,
#: 3 % for every kind (the generator's default).
BODIES = ("population", "model")
METHODS = ("calibrate", "live")
#: the default run: (kind, seeds); ``--full``: the wide run
DEFAULT_SEEDS = {"iid": "0-3", "realistic": "0-1", "cmu": "0-1", "lowpar": "0-1", "paper": "0-1"}
FULL_SEEDS = {"iid": "0-19", "realistic": "0-19", "cmu": "0-9", "lowpar": "0-9",
              "paper": "0-9"}


def _seeds(text: str) -> list[int]:
    out = []
    for part in str(text).split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b) + 1)) if b else [int(a)]
    return out


# =========================================================================== scenes
class Truth:
    """One scene's inputs and its truth, in one frame order.

    Attributes:
        name, kind: the scene's label and kind.
        detections: the :class:`~mirrorgraph.keypoints.RawDetections` a user has.
        intrinsics: the camera's.
        height: the subject's height (m).
        joints3d: ``(T, J, 3)`` true joints (m, real camera frame) of ``frame_ids``.
        frame_ids: ``(T,)``.
        names: ``(J,)`` joint names.
        normal, distance: the true mirror.
        flip: ``(J,)`` each joint's left/right partner.
        real, mirror: ``(T, J, 2)`` undistorted observations in the true labels (NaN
            where missing); ``out_real``, ``out_mirror``: ``(T, J)`` planted outliers.
    """

    def __init__(self, **kw):
        self.__dict__.update(kw)


def _synthetic(kind: str, seed: int, frames: int, body: str = "population",
               scene: tuple = ()) -> Truth:
    from mirrorgraph.synth import make_scene, make_wide_scene
    from mirrorgraph.synth.mocap import cmu_example_path

    # the generator's default bodies without the argument (a package before it runs too)
    body_kw = dict(body_variation="population") if body == "population" else {}
    body_kw.update(dict(scene))     # --scene: make_scene arguments that win over the drawn
    if kind in ("iid", "realistic"):
        sc = make_wide_scene(seed, "wide", kind, frames, **body_kw)
    elif kind == "lowpar":
        sc = make_wide_scene(seed, "low_parallax", "iid", frames, **body_kw)
    elif kind == "cmu":       # the take's own body
        sc = make_wide_scene(seed, "wide", "iid", frames, motion=str(cmu_example_path()),
                             **dict(scene))
    elif kind == "paper":
        sc = make_scene(frames=frames, seed=seed, noise_std=4.0, noise_mean=0.076,
                        outlier_rate=0.03, **body_kw)
    else:
        raise ValueError(kind)
    intr = sc.intrinsics

    def obs(o, missing):
        uv = np.where(missing[..., None], np.nan, o[..., :2].astype(float))
        if intr.has_distortion:
            flat = uv.reshape(-1, 2)
            ok = np.isfinite(flat).all(1)
            flat[ok] = intr.undistort_points(flat[ok])
            uv = flat.reshape(uv.shape)
        return uv

    out_r = np.asarray(sc.outlier_mask_real, bool).copy()
    out_m = np.asarray(sc.outlier_mask_mirror, bool).copy()
    return Truth(name=f"{kind} {seed}", kind=kind, seed=seed, detections=sc.detections,
                 intrinsics=intr, height=float(sc.subject_height), joints3d=sc.joints3d,
                 frame_ids=np.asarray(sc.frame_ids), names=list(sc.skeleton.joints),
                 normal=np.asarray(sc.normal, float), distance=float(sc.distance),
                 flip=np.asarray(sc.skeleton.flip),
                 real=obs(sc.real_observed, sc.missing_real),
                 mirror=obs(sc.mirror_observed, sc.missing_mirror),
                 out_real=out_r, out_mirror=out_m)


def default_fixtures() -> Path:
    """``shared/fixtures`` in the nearest folder above the repository that has one."""
    for up in ROOT.parents:
        if (up / "shared" / "fixtures").is_dir():
            return up / "shared" / "fixtures"
    return ROOT.parent / "shared" / "fixtures"


def add_scene_args(ap: argparse.ArgumentParser, kinds: str, seeds: str,
                   frames: int = 1000) -> None:
    """Add the scene choice the live bench scripts share to ``ap``: ``--kinds``
    (comma-separated, of :data:`KINDS`), ``--seeds`` (the synthetic kinds'), ``--frames``
    and ``--fixtures`` (the fixture scenes' folder), with these defaults
    (:func:`scene_list` reads them back)."""
    ap.add_argument("--kinds", default=kinds, help=f"comma-separated, of {', '.join(KINDS)}")
    ap.add_argument("--seeds", default=seeds,
                    help="seeds of every synthetic kind, e.g. 0-5 or 0,3,7")
    ap.add_argument("--frames", type=int, default=frames)
    ap.add_argument("--fixtures", type=Path, default=default_fixtures(),
                    help="folder of fixture scenes (default: shared/fixtures in a folder "
                         "above the repository)")


def scene_list(args: argparse.Namespace) -> list[tuple[str, int | str]]:
    """``(kind, seed)`` of each scene :func:`add_scene_args`' arguments choose, for
    :func:`make_truth` (the fixtures: their folders' names)."""
    out: list[tuple[str, int | str]] = []
    for kind in (k.strip() for k in args.kinds.split(",") if k.strip()):
        names = ([p.name for p in fixture_dirs(Path(args.fixtures))] if kind == "fixtures"
                 else _seeds(args.seeds))
        out += [(kind, s) for s in names]
    return out


def fixture_dirs(root: Path) -> list[Path]:
    if not root.is_dir():
        return []
    return sorted(p for p in root.iterdir()
                  if (p / "keypoints.json").is_file() and (p / "joints3d_truth.npz").is_file())


def _fixture(path: Path) -> Truth:
    """A fixture scene, its observations matched to the truth's projections."""
    from mirrorgraph.geometry import project, reflect_points
    from mirrorgraph.intrinsics import load_intrinsics
    from mirrorgraph.io import read_keypoints

    det = read_keypoints(str(path / "keypoints.json"))
    intr = load_intrinsics(str(path / "camera.json"))
    truth = json.loads((path / "truth.json").read_text())
    z = np.load(path / "joints3d_truth.npz")
    ids = list(np.asarray(z["frame_ids"]))
    where = {int(f): i for i, f in enumerate(ids)}
    n = np.asarray(truth["normal"], float)
    d = float(truth["distance"])
    X = np.asarray(z["joints3d"], float)
    names = [str(s) for s in z["joint_names"]]
    skel = det.skeleton
    if list(skel.joints) != names:
        raise ValueError(f"{path}: joint names differ from the keypoints' skeleton")
    flip = np.asarray(skel.flip)
    T, J = X.shape[:2]
    pr = project(intr.K, X.reshape(-1, 3)).reshape(T, J, 2)
    pm = project(intr.K, reflect_points(X.reshape(-1, 3), n, d)).reshape(T, J, 2)
    real = np.full((T, J, 2), np.nan)
    mirror = np.full((T, J, 2), np.nan)
    for k, fid in enumerate(det.frame_ids):
        t = where.get(int(fid))
        if t is None:
            continue
        for target, proj in ((real, pr[t]), (mirror, pm[t])):
            best = (np.inf, None)
            for p in det.people[k]:
                uv = np.asarray(p[:, :2], float)
                ok = np.isfinite(uv).all(1) & (p[:, 2] > 0)
                if intr.has_distortion and ok.any():
                    uv = uv.copy()
                    uv[ok] = intr.undistort_points(uv[ok])
                for labels in (uv, uv[flip]):
                    okl = ok if labels is uv else ok[flip]
                    if okl.sum() < 3:
                        continue
                    cost = float(np.median(np.linalg.norm(labels[okl] - proj[okl], axis=1)))
                    if cost < best[0]:
                        best = (cost, np.where(okl[:, None], labels, np.nan))
            if best[1] is not None and best[0] < 4 * FIXTURE_OUTLIER_PX:
                target[t] = best[1]
    with np.errstate(invalid="ignore"):
        out_r = np.linalg.norm(real - pr, axis=-1) > FIXTURE_OUTLIER_PX
        out_m = np.linalg.norm(mirror - pm, axis=-1) > FIXTURE_OUTLIER_PX
    return Truth(name=f"fixture {path.name}", kind="fixtures", seed=path.name, detections=det,
                 intrinsics=intr, height=float(truth["height"]), joints3d=X,
                 frame_ids=np.asarray(ids), names=names, normal=n, distance=d, flip=flip,
                 real=real, mirror=mirror, out_real=out_r, out_mirror=out_m)


def make_truth(kind: str, seed, frames: int, fixtures: Path, body: str = "population",
               height_given: str = "reported", scene: tuple = ()) -> Truth:
    """The scene and its truth, with ``height_given`` the height the run is given
    (:data:`HEIGHT_GIVEN`: a user's report drawn from the scene's own generator, or the
    true height) and ``scene``'s ``(name, value)`` pairs ``make_scene`` arguments of the
    synthetic kinds (``--scene``)."""
    tr = (_fixture(fixtures / str(seed)) if kind == "fixtures"
          else _synthetic(kind, int(seed), frames, body, scene))
    tr.height_given = tr.height
    if height_given == "reported":
        key = zlib.crc32(f"{kind} {seed}".encode())
        z = float(np.random.default_rng([key, 2718]).standard_normal())
        tr.height_given = tr.height + REPORTED_HEIGHT_BIAS_M + REPORTED_HEIGHT_STD_M * z
    return tr


# =========================================================================== scoring
def oracle(tr: Truth) -> dict:
    """Each frame triangulated with the true mirror from the clean observations."""
    from mirrorgraph.geometry import camera_projection, mirror_projection, triangulate
    from mirrorgraph.metrics import pa_mpjpe

    eye = np.eye(4)
    P = [camera_projection(tr.intrinsics.K, eye),
         mirror_projection(tr.intrinsics.K, eye, tr.normal, tr.distance)]
    X, ok = triangulate(P, [tr.real, tr.mirror], [~tr.out_real, ~tr.out_mirror])
    err = np.linalg.norm(X - tr.joints3d, axis=-1)[ok]
    return dict(pa_mpjpe_mm=1e3 * pa_mpjpe(X, tr.joints3d, ok),
                mpjpe_mm=1e3 * float(err.mean()) if err.size else float("nan"),
                median_error_mm=1e3 * float(np.median(err)) if err.size else float("nan"),
                given=float(ok.mean()), _X=X, _ok=ok)


def _modes(tr: Truth, X: np.ndarray, gross: np.ndarray, normal: np.ndarray,
           distance: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The mode index (:data:`MODES`) of each gross joint, ``(G,)``; its largest
    reprojection residual against a clean observation (px, NaN: none), and where an
    ``off`` joint is off (0 the real view, 1 the reflection, 2 both).

    ``normal`` ``(T, 3)`` and ``distance`` ``(T,)``: the run's mirror at each frame.
    """
    from mirrorgraph.geometry import project

    t, j = np.nonzero(gross)
    K = tr.intrinsics.K
    P = X[t, j]
    n, d = normal[t], distance[t]
    S = P - 2.0 * ((P * n).sum(1) - d)[:, None] * n
    res = []
    for pts, obs, bad in ((P, tr.real, tr.out_real), (S, tr.mirror, tr.out_mirror)):
        with np.errstate(invalid="ignore", divide="ignore"):
            uv = project(K, pts)
            r = np.linalg.norm(uv - obs[t, j], axis=1)
            flipped = np.linalg.norm(uv - obs[t, tr.flip[j]], axis=1) <= MODE_PX
        seen = np.isfinite(r)
        res.append((r, seen & ~bad[t, j], seen & bad[t, j], flipped & (tr.flip[j] != j)))
    (r1, c1, o1, f1), (r2, c2, o2, f2) = res
    off1, off2 = c1 & (r1 > MODE_PX), c2 & (r2 > MODE_PX)
    swap = (off1 & f1) | (off2 & f2)
    off = off1 | off2
    follow = (o1 & (r1 <= MODE_PX)) | (o2 & (r2 <= MODE_PX))
    both = c1 & c2
    mode = np.where(swap, 4, np.where(off, 1, np.where(follow, 2, np.where(both, 0, 3))))
    with np.errstate(invalid="ignore"):
        resid = np.fmax(np.where(c1, r1, np.nan), np.where(c2, r2, np.nan))
    view = np.where(off1 & off2, 2, np.where(off2, 1, 0))
    return mode, resid, view


def score(tr: Truth, X: np.ndarray, given: np.ndarray, std: np.ndarray | None,
          normal: np.ndarray, distance: np.ndarray, extra: dict,
          std_shape: np.ndarray | None = None, scale_rel_std: float | None = None,
          epochs: np.ndarray | None = None) -> dict:
    """The figures of one run's joints ``X`` ``(T, J, 3)`` (aligned with the truth).

    ``std``, ``std_shape``: ``(T, J)`` the joints' stds with and without the metric
    scale's share (``None``: the run gives none); ``scale_rel_std``: that share, the
    run's metric scale's relative std, against the scale's error (the run's joints over
    the truth's: the one factor about the camera that fits them best, least squares).
    ``epochs``: ``(T,)`` labels of the frames that share one metric scale (``live``: the
    frames one fused mirror served); ``None``: the whole run shares one. The shape's
    error takes out each epoch's own factor, as ``std_shape`` leaves out the scale the
    frame was given at.
    """
    from mirrorgraph.metrics import pa_mpjpe

    truth = tr.joints3d
    given = given & np.isfinite(X).all(-1)
    e = np.linalg.norm(np.where(given[..., None], X, 0.0) - truth, axis=-1)
    eg = e[given]
    out = dict(given=float(given.mean()), n_given=int(given.sum()),
               mpjpe_mm=1e3 * float(eg.mean()) if eg.size else float("nan"),
               pa_mpjpe_mm=1e3 * pa_mpjpe(X, truth, given),
               gross=float((eg > GROSS_M).mean()) if eg.size else float("nan"),
               far=float((eg > FAR_M).mean()) if eg.size else float("nan"),
               worst_m=float(eg.max()) if eg.size else float("nan"))
    # the metric scale: one factor about the camera, truth ~ fit X (least squares); the
    # shape's error is what is left of each joint's once the scale is taken out
    fit = 1.0
    if given.any():
        Xg, Tg = X[given], truth[given]
        fit = float((Xg * Tg).sum() / (Xg * Xg).sum())
        out["scale_err"] = 1.0 / fit - 1.0
        out["scale_rel_std"] = scale_rel_std
        out["scale_z"] = (abs(out["scale_err"]) / scale_rel_std
                          if scale_rel_std and scale_rel_std > 0 else None)
    fits = np.full(len(X), fit)
    if epochs is not None:
        Xz, Tz = np.where(given[..., None], X, 0.0), np.where(given[..., None], truth, 0.0)
        lab = np.unique(np.asarray(epochs), return_inverse=True)[1].ravel()
        num = np.bincount(lab, (Xz * Tz).sum((1, 2)))
        den = np.bincount(lab, (Xz * Xz).sum((1, 2)))
        with np.errstate(invalid="ignore", divide="ignore"):
            fits = np.where(den > 0, num / den, fit)[lab]
    e_shape = np.linalg.norm(np.where(given[..., None], fits[:, None, None] * X, 0.0) - truth,
                             axis=-1)
    es = e_shape[given]
    out["gross_shape"] = float((es > GROSS_M).mean()) if es.size else float("nan")
    # the same with each frame's common scale error taken out (its joints times the
    # least-squares factor about the camera, sum X . T / sum X . X): the frame's shape and
    # place without the metric scale's error, whatever made it (the distance, the normal)
    Xz = np.where(given[..., None], X, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        f = (Xz * truth).sum((1, 2)) / (Xz * Xz).sum((1, 2))
    es = np.linalg.norm(Xz * np.nan_to_num(f)[:, None, None] - truth, axis=-1)[given]
    out["gross_scaled"] = float((es > GROSS_M).mean()) if es.size else float("nan")
    for tag, sd, err in (("z", std, e), ("z_shape", std_shape, e_shape)):
        out[f"{tag}_median"] = out[f"{tag}_p99"] = None
        if sd is None:
            continue
        sd = np.asarray(sd, float)
        ok = given & np.isfinite(sd) & (sd > 0)
        if ok.any():
            z = err[ok] / sd[ok]
            out[f"{tag}_median"] = float(np.median(z))
            out[f"{tag}_p99"] = float(np.percentile(z, 99))
            out[f"{tag}_share"] = float(ok.sum() / max(given.sum(), 1))
            g = err[ok] > GROSS_M
            out[f"{tag}_gross_median"] = float(np.median(z[g])) if g.any() else None
    gross = given & (e > GROSS_M)
    out["gross_by_joint"] = {tr.names[j]: [int(gross[:, j].sum()), int(given[:, j].sum())]
                             for j in range(len(tr.names))}
    if gross.any():
        modes, resid, view = _modes(tr, X, gross, normal, distance)
    else:
        modes, resid, view = np.zeros(0, int), np.zeros(0), np.zeros(0, int)
    out["gross_by_mode"] = {m: int((modes == i).sum()) for i, m in enumerate(MODES)}
    jt = np.nonzero(gross)[1]
    out["gross_by_joint_mode"] = {
        tr.names[j]: {m: int(((jt == j) & (modes == i)).sum())
                      for i, m in enumerate(MODES) if ((jt == j) & (modes == i)).any()}
        for j in np.unique(jt)}
    off = modes == 1
    out["off_views"] = {v: int((off & (view == i)).sum())
                        for i, v in enumerate(("real", "mirror", "both"))}
    out["off_residual_px"] = (np.percentile(resid[off], [50, 90]).tolist()
                              if off.any() else None)
    out["depth_error_m"] = (float(np.median(np.linalg.norm(X[gross] - truth[gross], axis=1)[
        modes == 0])) if (modes == 0).any() else None)
    frames = np.flatnonzero(gross.any(1))
    out["_X"], out["_given"] = X, given
    out["gross_frames"] = int(frames.size)
    out["longest_gross_run"] = _longest_run(frames)
    out.update(extra)
    return out


def _longest_run(frames: np.ndarray) -> int:
    if frames.size == 0:
        return 0
    breaks = np.flatnonzero(np.diff(frames) != 1)
    lengths = np.diff(np.concatenate([[-1], breaks, [frames.size - 1]]))
    return int(lengths.max())


def _distance_figures(tr: Truth, distance: float | None, std: float | None) -> dict:
    if distance is None:
        return dict(distance_err=None, distance_z=None)
    err = distance / tr.distance - 1.0
    z = abs(distance - tr.distance) / std if std else None
    return dict(distance_err=float(err), distance_z=None if z is None else float(z),
                distance_rel_std=None if not std else float(std / distance))


# =========================================================================== runs
def _rms_length(std: np.ndarray) -> np.ndarray:
    """``(T, J)`` RMS error lengths from ``(T, J)`` stds, ``(T, J, 3)`` per-axis stds or
    ``(T, J, 3, 3)`` covariances."""
    if std.ndim == 4:
        return np.sqrt(np.einsum("...ii->...", std))
    if std.ndim == 3:
        return np.sqrt((std ** 2).sum(-1))
    return std


def on_truth_frames(run, tr: Truth) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A calibration run's joints on the truth's frames: ``(X (T, J, 3), given (T, J),
    rows, keep)``, ``rows`` each of the run's frames' row of the truth (``-1``: none),
    ``keep`` ``rows >= 0``; NaN / ``False`` where the run gives no joint."""
    T, J = tr.joints3d.shape[:2]
    X = np.full((T, J, 3), np.nan)
    given = np.zeros((T, J), bool)
    where = {int(f): i for i, f in enumerate(tr.frame_ids)}
    rows = np.array([where.get(int(f), -1) for f in run.paired.frame_ids])
    keep = rows >= 0
    if run.joints3d is not None:
        X[rows[keep]] = run.joints3d[keep]
        valid = run.valid3d if run.valid3d is not None else np.isfinite(run.joints3d).all(-1)
        given[rows[keep]] = valid[keep]
    return X, given, rows, keep


def _refine_options(keypoint_offset: float | None, height_sigma: float | None = None,
                    refine: tuple = ()):
    """The runs' graph options: the defaults, with the keypoints' placement, the
    height's relative std and ``refine``'s ``(name, value)`` pairs (``--refine``) stated
    where given."""
    from mirrorgraph.graph import RefineOptions

    stated = {k: v for k, v in (("keypoint_offset", keypoint_offset),
                                ("height_sigma", height_sigma)) if v is not None}
    stated.update(dict(refine))
    return RefineOptions(**stated) if stated else None


def _refine_pair(text: str) -> tuple[str, object]:
    """``--refine NAME=VALUE``: a :class:`~mirrorgraph.graph.RefineOptions` field and its
    value (a number, ``none``, or a word)."""
    name, eq, value = text.partition("=")
    if not eq or not name.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    v: object = value.strip()
    if v.lower() == "none":
        v = None
    else:
        try:
            v = float(v) if any(c in v for c in ".eE") else int(v)
        except ValueError:
            pass
    return name.strip(), v


def run_calibrate(tr: Truth, keypoint_offset: float | None = None,
                  height_sigma: float | None = None, refine: tuple = ()) -> dict:
    import mirrorgraph as mg

    opts = mg.CalibrateOptions(subject_height=tr.height_given, fps=scene_fps(tr),
                               refine_options=_refine_options(keypoint_offset, height_sigma,
                                                              refine))
    wall, cpu = time.perf_counter(), time.process_time()
    run = mg.calibrate(tr.detections, tr.intrinsics, opts)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    cal = run.calibration
    T, J = tr.joints3d.shape[:2]
    X, given, rows, keep = on_truth_frames(run, tr)
    stds = []
    for name in ("joints_std", "joints_std_shape"):
        js = getattr(run, name, None)
        if js is not None:
            js_full = np.full((T, J), np.nan)
            js_full[rows[keep]] = _rms_length(np.asarray(js, float))[keep]
            js = js_full
        stds.append(js)
    std, std_shape = stds
    completed = np.zeros((T, J), bool)
    if run.completed is not None:
        completed[rows[keep]] = run.completed[keep]
    normal = np.broadcast_to(np.asarray(cal.normal, float), (T, 3))
    dist = np.full(T, float(cal.distance if cal.distance is not None else 1.0))
    dstd = (cal.uncertainty or {}).get("distance_std")
    out = score(tr, X, given, std, normal, dist,
                dict(wall_s=wall, cpu_s=cpu, **_distance_figures(tr, cal.distance, dstd)),
                std_shape, getattr(run, "scale_rel_std", None))
    e = np.linalg.norm(np.nan_to_num(X) - tr.joints3d, axis=-1)
    gross = given & (e > GROSS_M)
    out["gross_completed"] = int((gross & completed).sum())
    out["completed"] = int((given & completed).sum())
    return out


def replay_live(tr: Truth, options) -> dict:
    """Replay ``tr``'s detections through :class:`~mirrorgraph.live.LiveCalibrator` with
    ``options`` (:class:`~mirrorgraph.live.LiveOptions`), frame by frame in the calling
    thread, and keep what ``mirrorgraph live`` writes: each frame's settled joints
    (:attr:`~mirrorgraph.live.LiveFrame.settled`, the frame itself without a lag), the
    remaining ones flushed after :meth:`~mirrorgraph.live.LiveCalibrator.finish`.

    Returns a dict on the truth's ``T`` frames (``J`` joints): ``X`` ``(T, J, 3)`` the
    joints, metres, camera frame (NaN: not given); ``std``, ``std_shape`` ``(T, J)`` their
    stds with and without the metric scale's share, metres (NaN: none given); ``normal``
    ``(T, 3)``, ``distance`` ``(T,)`` metres, ``rotation_std_deg`` ``(T,)``: the mirror the
    frame was given with (NaN: none, or no distance); ``status`` ``(T,)`` the mirror's
    status (``"initialising"``, ``"calibrated"``; ``""``: the frame not given); ``final``:
    the final :class:`~mirrorgraph.live.LiveMirror`; ``windows``: the calibrator's window
    log; ``wall_s``, ``cpu_s``: the replay's wall and process CPU seconds (the
    calibrator's construction not counted).
    """
    from mirrorgraph.live import LiveCalibrator

    det = tr.detections
    live = LiveCalibrator(det.skeleton, tr.intrinsics, options)
    T, J = tr.joints3d.shape[:2]
    X = np.full((T, J, 3), np.nan)
    std = np.full((T, J), np.nan)
    std_shape = np.full((T, J), np.nan)
    normal, dist = np.full((T, 3), np.nan), np.full(T, np.nan)
    rot_std, status = np.full(T, np.nan), np.full(T, "", object)
    where = {int(f): i for i, f in enumerate(tr.frame_ids)}
    wall, cpu = time.perf_counter(), time.process_time()
    lagged = getattr(live.options, "lag_frames", 0) > 0

    def take(f) -> None:
        t = where.get(int(f.frame_id))
        if t is None:
            return
        X[t] = f.joints3d
        status[t] = f.mirror.status
        if f.joints_std is not None:
            std[t] = f.joints_std
        if getattr(f, "joints_std_shape", None) is not None:
            std_shape[t] = f.joints_std_shape
        if f.mirror.normal is not None:
            normal[t] = f.mirror.normal
            dist[t] = f.mirror.distance if f.mirror.distance is not None else np.nan
            rot_std[t] = f.mirror.rotation_std_deg

    try:
        for k, people in enumerate(det.people):
            f = live.update(people, frame_id=int(det.frame_ids[k]),
                            time_s=float(det.frame_ids[k]) / live.options.fps)
            # what the JSON lines carry: with a lag, each frame as it is given again
            if not lagged:
                take(f)
            elif f.settled is not None:
                take(f.settled)
        final = live.finish()
        for f in (live.flush() if lagged else []):
            take(f)
    finally:
        live.close()
    return dict(X=X, std=std, std_shape=std_shape, normal=normal, distance=dist,
                rotation_std_deg=rot_std, status=status, final=final,
                windows=list(live.window_log), wall_s=time.perf_counter() - wall,
                cpu_s=time.process_time() - cpu)


#: the live mirror's statuses (:attr:`mirrorgraph.live.LiveMirror.status`)
STATUSES = ("calibrated", "initialising")


def run_live(tr: Truth, keypoint_offset: float | None = None,
             height_sigma: float | None = None, refine: tuple = (), live: tuple = ()) -> dict:
    """The live run of ``tr`` (``live``: ``(name, value)`` pairs of
    :class:`~mirrorgraph.live.LiveOptions` fields, ``--live``): :func:`score`'s figures,
    and ``by_status``: the share of the scored frames the mirror gave as ``calibrated``
    (``calibrated_share``) and per status, :func:`score`'s figures on those frames alone."""
    from mirrorgraph.live import LiveOptions

    r = replay_live(tr, LiveOptions.of(subject_height=tr.height_given, fps=scene_fps(tr),
                                       refine_options=_refine_options(keypoint_offset,
                                                                      height_sigma, refine),
                                       **dict(live)))
    X, final = r["X"], r["final"]
    # no mirror yet: the camera's axis at the unit distance (no joint is given there)
    normal = np.where(np.isfinite(r["normal"]).all(1, keepdims=True), r["normal"],
                      np.array([0.0, 0.0, 1.0]))
    dist = np.where(np.isfinite(r["distance"]), r["distance"], 1.0)
    given = np.isfinite(X).all(-1)
    out = score(tr, X, given, r["std"], normal, dist,
                dict(wall_s=r["wall_s"], cpu_s=r["cpu_s"],
                     **_distance_figures(tr, final.distance, final.distance_std)),
                r["std_shape"], getattr(final, "scale_rel_std", None), epochs=dist)
    scored = given.any(1)
    by = dict(frames=int(scored.sum()),
              calibrated_share=float((r["status"][scored] == "calibrated").mean())
              if scored.any() else float("nan"))
    for st in STATUSES:
        on = given & (r["status"] == st)[:, None]
        s = score(tr, X, on, None, normal, dist, {}, epochs=dist)
        by[st] = dict(frames=int(on.any(1).sum()), n_given=s["n_given"],
                      pa_mpjpe_mm=s["pa_mpjpe_mm"], gross=s["gross"],
                      gross_scaled=s["gross_scaled"])
    out["by_status"] = by
    return out


def run_scene(case: tuple) -> dict:
    import warnings
    warnings.filterwarnings("ignore")
    from mirrorgraph.metrics import pa_mpjpe

    (kind, seed, frames, methods, fixtures, body, height_given, keypoint_offset, height_sigma,
     refine, scene, live) = case
    clock = time.perf_counter()
    tr = make_truth(kind, seed, frames, Path(fixtures), body, height_given, scene)
    orc = oracle(tr)
    Xo, oko = orc.pop("_X"), orc.pop("_ok")
    out = dict(kind=kind, seed=seed, name=tr.name, frames=int(len(tr.frame_ids)),
               joints=int(tr.joints3d.shape[1]), oracle=orc,
               truth=dict(distance=tr.distance, height=tr.height,
                          height_given=tr.height_given))
    for m in methods:
        try:
            out[m] = (run_calibrate(tr, keypoint_offset, height_sigma, refine)
                      if m == "calibrate"
                      else run_live(tr, keypoint_offset, height_sigma, refine, live))
        except Exception as exc:  # noqa: BLE001 - a failure is a result here
            out[m] = dict(error=f"{type(exc).__name__}: {exc}")
        r = out[m]
        X, given = r.pop("_X", None), r.pop("_given", None)
        if "pa_mpjpe_mm" in r:
            r["oracle_ratio"] = r["pa_mpjpe_mm"] / out["oracle"]["pa_mpjpe_mm"]
            # both on the joints both give (the oracle's few joints of near-parallel rays,
            # metres off, weigh in its mean over all of its own)
            both = given & oko
            r["common_pa_mpjpe_mm"] = 1e3 * pa_mpjpe(X, tr.joints3d, both)
            r["common_oracle_pa_mm"] = 1e3 * pa_mpjpe(Xo, tr.joints3d, both)
            r["common_oracle_ratio"] = r["common_pa_mpjpe_mm"] / r["common_oracle_pa_mm"]
    out["seconds"] = time.perf_counter() - clock
    return out


# =========================================================================== summary
#: (key, label, direction of "worst": max or min, format)
FIGURES = (("mpjpe_mm", "MPJPE mm", max, ".1f"), ("pa_mpjpe_mm", "PA-MPJPE mm", max, ".1f"),
           ("oracle_pa_mm", "oracle PA mm", max, ".1f"), ("oracle_ratio", "/ oracle", max, ".2f"),
           ("common_oracle_ratio", "/ oracle, same joints", max, ".2f"),
           ("vs_offline", "/ calibrate", max, ".2f"),
           ("gross_pct", "> 0.3 m %", max, ".2f"),
           ("gross_shape_pct", "> 0.3 m, run's scale out %", max, ".2f"),
           ("gross_scaled_pct", "> 0.3 m, frame's scale out %", max, ".2f"),
           ("far_pct", "> 1 m %", max, ".2f"),
           ("worst_m", "worst m", max, ".2f"), ("given_pct", "given %", min, ".1f"),
           ("z_median", "err/std med", None, ".2f"), ("z_p99", "err/std p99", max, ".1f"),
           ("z_shape_median", "shape err/std med", None, ".2f"),
           ("z_shape_p99", "shape err/std p99", max, ".1f"),
           ("distance_err_pct", "distance err %", None, "+.1f"),
           ("distance_z", "distance err/std", max, ".1f"),
           ("scale_err_pct", "scale err %", None, "+.1f"),
           ("scale_z", "scale err/std", max, ".2f"), ("wall_s", "wall s", max, ".1f"),
           ("cpu_s", "CPU s", max, ".1f"))


def flat(scene: dict, method: str) -> dict | None:
    """One scene's figures of one method under the :data:`FIGURES` keys."""
    r = scene.get(method)
    if not r or "error" in r:
        return None
    pct = lambda v: None if v is None else 100.0 * v  # noqa: E731
    off = scene.get("calibrate") or {}
    vs = (r["pa_mpjpe_mm"] / off["pa_mpjpe_mm"]
          if method != "calibrate" and _num(off.get("pa_mpjpe_mm")) else None)
    return dict(mpjpe_mm=r["mpjpe_mm"], pa_mpjpe_mm=r["pa_mpjpe_mm"],
                oracle_pa_mm=scene["oracle"]["pa_mpjpe_mm"], oracle_ratio=r.get("oracle_ratio"),
                common_oracle_ratio=r.get("common_oracle_ratio"), vs_offline=vs,
                gross_pct=pct(r["gross"]), gross_shape_pct=pct(r.get("gross_shape")),
                gross_scaled_pct=pct(r.get("gross_scaled")),
                far_pct=pct(r["far"]), worst_m=r["worst_m"],
                given_pct=pct(r["given"]), z_median=r.get("z_median"), z_p99=r.get("z_p99"),
                z_shape_median=r.get("z_shape_median"), z_shape_p99=r.get("z_shape_p99"),
                distance_err_pct=pct(r.get("distance_err")), distance_z=r.get("distance_z"),
                scale_err_pct=pct(r.get("scale_err")), scale_z=r.get("scale_z"),
                wall_s=r["wall_s"], cpu_s=r["cpu_s"])


#: live's figures by the mirror's status (:func:`flat_status`): (key, label, worst, format)
STATUS_FIGURES = (("calibrated_pct", "calibrated frames %", min, ".1f"),
                  ("calibrated_pa_mm", "PA mm calibrated", max, ".1f"),
                  ("initialising_pa_mm", "PA mm initialising", max, ".1f"),
                  ("calibrated_gross_pct", "> 0.3 m % calibrated", max, ".2f"),
                  ("initialising_gross_pct", "> 0.3 m % initialising", max, ".2f"),
                  ("calibrated_gross_scaled_pct", "> 0.3 m, frame's scale out % calibrated",
                   max, ".2f"),
                  ("initialising_gross_scaled_pct",
                   "> 0.3 m, frame's scale out % initialising", max, ".2f"))


def flat_status(scene: dict) -> dict | None:
    """One scene's live figures by the mirror's status under the :data:`STATUS_FIGURES`
    keys (``None``: no live run, or one without them)."""
    by = (scene.get("live") or {}).get("by_status")
    if not by:
        return None
    pct = lambda v: None if v is None else 100.0 * v  # noqa: E731
    out = dict(calibrated_pct=pct(by["calibrated_share"]))
    for st in STATUSES:
        out[f"{st}_pa_mm"] = by[st]["pa_mpjpe_mm"]
        out[f"{st}_gross_pct"] = pct(by[st]["gross"])
        out[f"{st}_gross_scaled_pct"] = pct(by[st]["gross_scaled"])
    return out


def pooled_status(scenes: list[dict]) -> dict:
    """Live's figures by the mirror's status pooled over ``scenes`` (every scored frame
    and given joint of them together, under the :data:`STATUS_FIGURES` keys; the
    PA-MPJPEs left ``None``: means over scenes are the tables' medians)."""
    by = [s["live"]["by_status"] for s in scenes
          if "by_status" in (s.get("live") or {})]
    out: dict = dict(calibrated_pct=None)
    if not by:
        return out
    n = sum(b["frames"] for b in by)
    cal = sum(b["calibrated"]["frames"] for b in by)
    out["calibrated_pct"] = 100.0 * cal / n if n else None
    for st in STATUSES:
        given = sum(b[st]["n_given"] for b in by)
        out[f"{st}_pa_mm"] = None
        for key in ("gross", "gross_scaled"):
            bad = sum(b[st][key] * b[st]["n_given"] for b in by if b[st]["n_given"])
            out[f"{st}_{key}_pct"] = 100.0 * bad / given if given else None
    return out


def _median_worst(rows: list[dict], figures: tuple) -> dict:
    out = {}
    for key, _, worst, _ in figures:
        vals = [r[key] for r in rows if _num(r.get(key))]
        out[key] = (dict(median=float(np.median(vals)), worst=float(worst(vals))) if vals
                    else dict(median=None, worst=None))
    return out


def _num(v) -> bool:
    return v is not None and isinstance(v, (int, float)) and np.isfinite(v)


def aggregate(scenes: list[dict], kinds: list[str], methods: list[str]) -> dict:
    """Per kind and method: the median over scenes and the worst scene of each figure."""
    out = {}
    for kind in kinds:
        for m in methods:
            sel = [s for s in scenes if s["kind"] == kind and m in s]
            rows = [flat(s, m) for s in sel]
            good = [r for r in rows if r is not None]
            if not sel:
                continue
            agg = dict(scenes=len(sel), failed=len(sel) - len(good))
            for key, _, worst, _ in FIGURES:
                vals = [r[key] for r in good if _num(r.get(key))]
                if not vals:
                    agg[key] = dict(median=None, worst=None)
                    continue
                if key in ("distance_err_pct", "scale_err_pct"):
                    w = max(vals, key=abs)
                elif key in ("z_median", "z_shape_median"):
                    w = max(vals, key=lambda v: abs(np.log(max(v, 1e-9))))
                else:
                    w = worst(vals)
                agg[key] = dict(median=float(np.median(vals)), worst=float(w))
            by_joint: dict = {}
            by_joint_mode: dict = {}
            by_mode = {k: 0 for k in MODES}
            views = {"real": 0, "mirror": 0, "both": 0}
            completed, resid, longest = 0, [], 0
            for s in sel:
                r = s[m]
                for name, (g, n) in r.get("gross_by_joint", {}).items():
                    a = by_joint.setdefault(name, [0, 0])
                    a[0] += g
                    a[1] += n
                for name, md in r.get("gross_by_joint_mode", {}).items():
                    d = by_joint_mode.setdefault(name, {})
                    for k, v in md.items():
                        d[k] = d.get(k, 0) + v
                for k, v in r.get("gross_by_mode", {}).items():
                    by_mode[k] += v
                for k, v in (r.get("off_views") or {}).items():
                    views[k] += v
                if r.get("off_residual_px"):
                    resid.append(r["off_residual_px"][0])
                completed += r.get("gross_completed", 0)
                longest = max(longest, r.get("longest_gross_run", 0))
            agg["gross_joints"] = sum(by_mode.values())
            agg["gross_by_joint"] = dict(sorted(by_joint.items(), key=lambda kv: -kv[1][0]))
            agg["gross_by_joint_mode"] = by_joint_mode
            agg["gross_by_mode"] = by_mode
            agg["off_views"] = views
            agg["off_residual_px"] = [float(np.median(resid))] if resid else None
            agg["gross_completed"] = completed if m == "calibrate" else None
            agg["longest_gross_run"] = longest
            if m == "live":
                agg["by_status"] = _median_worst(
                    [r for r in map(flat_status, sel) if r is not None], STATUS_FIGURES)
                agg["by_status_pooled"] = pooled_status(sel)
            out[f"{kind}/{m}"] = agg
    return out


def _f(v, spec: str) -> str:
    return "n/a" if not _num(v) else format(v, spec)


def tables(scenes: list[dict], agg: dict, methods: list[str]) -> list[str]:
    heads = [label for _, label, _, _ in FIGURES]
    L = ["## Per scene", "",
         "| scene | run | " + " | ".join(heads) + " |",
         "|---|---|" + "---:|" * len(heads)]
    for s in scenes:
        for m in methods:
            if m not in s:
                continue
            r = flat(s, m)
            if r is None:
                L.append(f"| {s['name']} | {m} | failed: {s[m].get('error', '?')} |")
                continue
            L.append(f"| {s['name']} | {m} | " + " | ".join(
                _f(r[k], spec) for k, _, _, spec in FIGURES) + " |")
    L += ["", "## Over scenes: median / worst scene", "",
          "| scenes | run | n | " + " | ".join(heads) + " |",
          "|---|---|---:|" + "---:|" * len(heads)]
    for key, a in agg.items():
        kind, m = key.split("/")
        cells = [f"{_f(a[k]['median'], spec)} / {_f(a[k]['worst'], spec)}"
                 for k, _, _, spec in FIGURES]
        n = f"{a['scenes']}" + (f" ({a['failed']} failed)" if a["failed"] else "")
        L.append(f"| {kind} | {m} | {n} | " + " | ".join(cells) + " |")
    rows = [(s["name"], s["live"]["by_status"]["frames"] if flat_status(s) else "",
             flat_status(s)) for s in scenes]
    rows = [r for r in rows if r[2] is not None]
    if rows:
        sh = [label for _, label, _, _ in STATUS_FIGURES]
        L += ["", "## Live by the mirror's status", "",
              "The live run's scored frames split by their mirror's status (`initialising` "
              "until the fused rotation std is at most `LiveOptions.calibrated_std_deg`, 2 deg "
              "by default, then "
              "`calibrated`): the share calibrated and the PA-MPJPE and gross shares on each "
              "part (`n/a`: no frame of that status); `n`: the frames scored (a scene), the "
              "scenes (over scenes: median / worst scene; pooled: every scored frame and "
              "given joint of the kind's scenes together, no PA-MPJPE).", "",
              "| scene | n | " + " | ".join(sh) + " |", "|---|---:|" + "---:|" * len(sh)]
        for name, n, r in rows:
            L.append(f"| {name} | {n} | " + " | ".join(
                _f(r[k], spec) for k, _, _, spec in STATUS_FIGURES) + " |")
        for key, a in agg.items():
            if "by_status" not in a:
                continue
            L.append(f"| {key.split('/')[0]} (over scenes) | {a['scenes']} | " + " | ".join(
                f"{_f(a['by_status'][k]['median'], spec)} / "
                f"{_f(a['by_status'][k]['worst'], spec)}"
                for k, _, _, spec in STATUS_FIGURES) + " |")
            p = a["by_status_pooled"]
            L.append(f"| {key.split('/')[0]} (pooled) | {a['scenes']} | " + " | ".join(
                "-" if p[k] is None else _f(p[k], spec)
                for k, _, _, spec in STATUS_FIGURES) + " |")
    kinds = list(dict.fromkeys(s["kind"] for s in scenes))
    T = targets(scenes, kinds)
    if T:
        L += ["", "## Against the targets", "",
              f"The iid targets on {', '.join(IID_KINDS)}; the detector-with-structure ones on "
              f"{', '.join(HARD_KINDS)}; `-`: not applied. Cells: the measured figure, **no** "
              "where the target is missed. The live latency target is `bench/bench_live.py`'s.",
              "", "| target | " + " | ".join(kinds) + " |", "|---|" + "---:|" * len(kinds)]
        for label, cells in T:
            L.append(f"| {label} | " + " | ".join(
                "-" if k not in cells else cells[k][0] + ("" if cells[k][1] is not False
                                                           else " **no**") for k in kinds) + " |")
    L += ["", "## The gross joints (> 0.3 m off)", "",
          "By mode (see the script's docstring): `depth` on both rays within "
          f"{MODE_PX:g} px, off in depth; `off` more than {MODE_PX:g} px from a clean "
          "observation (`off in`: the view(s), real / reflection / both; `px`: the median "
          "largest residual); `swap` off but on the left/right partner's observation; "
          "`outlier` on a planted outlier; `one view` at most one clean observation. "
          "`completed`: of them, the joints triangulated after the graph (calibrate only); "
          "`run`: the longest run of consecutive frames holding one.", "",
          "| scene | run | gross | " + " | ".join(MODES) + " | off in | px | completed | "
          "run | by joint name: count (share of that joint given) |",
          "|---|---|---:|" + "---:|" * len(MODES) + "---|---:|---:|---:|---|"]
    rows = [(key.replace("/", " (all) | "), a) for key, a in agg.items()]
    rows += [(f"{s['name']} | {m}", s[m]) for s in scenes for m in methods
             if m in s and "gross_by_mode" in s[m] and sum(s[m]["gross_by_mode"].values())]
    for label, a in rows:
        g = sum(a["gross_by_mode"].values())
        modes = " | ".join(f"{a['gross_by_mode'][k]}" + (
            f" ({100 * a['gross_by_mode'][k] / g:.0f} %)" if g and a["gross_by_mode"][k]
            else "") for k in MODES)
        names = ", ".join(f"{n} {c[0]} ({100 * c[0] / max(c[1], 1):.1f} %)" for n, c in sorted(
            a["gross_by_joint"].items(), key=lambda kv: -kv[1][0])[:8] if c[0])
        comp = a.get("gross_completed")
        ov = a.get("off_views") or {}
        px = a.get("off_residual_px")
        L.append(f"| {label} | {g} | {modes} | "
                 f"{ov.get('real', 0)} / {ov.get('mirror', 0)} / {ov.get('both', 0)} | "
                 f"{_f(px[0] if px else None, '.0f')} | {'-' if comp is None else comp} | "
                 f"{a.get('longest_gross_run', '-')} | {names or '-'} |")
    return L


# =========================================================================== targets
#: the kinds each set of targets applies to: iid detectors (the paper's protocol and the
#: CMU motion included) and the detectors with structure (the realistic model, the
#: independent generator's swaps and outliers)
IID_KINDS = ("iid", "cmu", "lowpar", "paper")
HARD_KINDS = ("realistic", "fixtures")


def targets(scenes: list[dict], kinds: list[str]) -> list[tuple[str, dict]]:
    """``(target, {kind: (measured, met)})`` rows; a kind the target does not apply to, or
    with nothing measured (no stds), is left out of the row's dict or has ``met`` None."""
    def measure(kind, m, key, test, how):
        v = [f[key] for s in scenes if s["kind"] == kind and m in s
             for f in [flat(s, m)] if f is not None and _num(f.get(key))]
        if not any(s["kind"] == kind and m in s for s in scenes):
            return None
        if not v:
            return ("n/a", None)
        x = {"median": float(np.median(v)), "max": max(v)}[how]
        return (f"{x:.3g}", bool(test(x)))

    spec = (  # label, method, key, test, over scenes, applies to iid / hard kinds
        ("calibrate PA-MPJPE / oracle's, median <= 0.6", "calibrate", "oracle_ratio",
         lambda x: x <= 0.6, "median", True, False),
        ("calibrate PA-MPJPE / oracle's, median < 1", "calibrate", "oracle_ratio",
         lambda x: x < 1.0, "median", False, True),
        ("the same on the joints both give, median <= 0.6", "calibrate",
         "common_oracle_ratio", lambda x: x <= 0.6, "median", True, False),
        ("the same on the joints both give, median < 1", "calibrate",
         "common_oracle_ratio", lambda x: x < 1.0, "median", False, True),
        ("calibrate > 0.3 m, worst scene <= 0.5 %", "calibrate", "gross_pct",
         lambda x: x <= 0.5, "max", True, False),
        ("calibrate > 0.3 m, worst scene <= 2 %", "calibrate", "gross_pct",
         lambda x: x <= 2.0, "max", False, True),
        ("calibrate > 0.3 m after the scale's fit, worst scene <= 0.5 %", "calibrate",
         "gross_shape_pct", lambda x: x <= 0.5, "max", True, False),
        ("calibrate > 0.3 m after the scale's fit, worst scene <= 2 %", "calibrate",
         "gross_shape_pct", lambda x: x <= 2.0, "max", False, True),
        ("calibrate > 1 m, worst scene = 0 %", "calibrate", "far_pct",
         lambda x: x == 0, "max", True, False),
        ("calibrate err/std, median of the scenes' in [0.5, 1.5]", "calibrate", "z_median",
         lambda x: 0.5 <= x <= 1.5, "median", True, True),
        ("calibrate err/std 99th percentile, worst scene < 3", "calibrate", "z_p99",
         lambda x: x < 3, "max", True, True),
        ("calibrate shape err/std, median of the scenes' in [0.5, 1.5]", "calibrate",
         "z_shape_median", lambda x: 0.5 <= x <= 1.5, "median", True, True),
        ("calibrate shape err/std 99th percentile, worst scene < 3", "calibrate",
         "z_shape_p99", lambda x: x < 3, "max", True, True),
        ("calibrate distance err/std, worst scene < 3", "calibrate", "distance_z",
         lambda x: x < 3, "max", True, True),
        ("calibrate scale err/std, median of the scenes' in [0.5, 1.5]", "calibrate",
         "scale_z", lambda x: 0.5 <= x <= 1.5, "median", True, True),
        ("calibrate scale err/std, worst scene < 3", "calibrate", "scale_z",
         lambda x: x < 3, "max", True, True),
        ("live PA-MPJPE / calibrate's, median <= 1.1", "live", "vs_offline",
         lambda x: x <= 1.1, "median", True, True),
        ("live > 0.3 m, worst scene <= 1 %", "live", "gross_pct",
         lambda x: x <= 1.0, "max", True, True),
        ("live err/std, median of the scenes' in [0.5, 1.5]", "live", "z_median",
         lambda x: 0.5 <= x <= 1.5, "median", True, True),
        ("live err/std 99th percentile, worst scene < 3", "live", "z_p99",
         lambda x: x < 3, "max", True, True),
    )
    rows = []
    for label, m, key, test, how, on_iid, on_hard in spec:
        cells = {}
        for k in kinds:
            if (k in IID_KINDS and on_iid) or (k in HARD_KINDS and on_hard):
                r = measure(k, m, key, test, how)
                if r is not None:
                    cells[k] = r
        if cells:
            rows.append((label, cells))
    return rows


# =========================================================================== compare
def compare(a_path: str, b_path: str) -> list[str]:
    """Side by side: each kind and run's medians and worst scenes in two JSON files."""
    A = json.loads(Path(a_path).read_text())
    B = json.loads(Path(b_path).read_text())
    common = ({s["name"] for s in A["scenes"]} & {s["name"] for s in B["scenes"]})
    dropped = len(A["scenes"]) + len(B["scenes"]) - 2 * len(common)
    for D in (A, B):        # the summaries recomputed on the common scenes, this version's figures
        D["scenes"] = [s for s in D["scenes"] if s["name"] in common]
        D["summary"] = aggregate(D["scenes"], D["meta"]["kinds"], D["meta"]["methods"])
    L = [f"# `{a_path}` (A) against `{b_path}` (B)", "",
         f"A: {A['meta'].get('date')} `{A['meta'].get('code')}`; "
         f"B: {B['meta'].get('date')} `{B['meta'].get('code')}`. Cells: A -> B (B / A), over "
         f"the {len(common)} scenes in both" + (f" ({dropped} in one file only left out)"
                                                 if dropped else "") + ".", ""]
    for key in [k for k in A["summary"] if k in B["summary"]]:
        a, b = A["summary"][key], B["summary"][key]
        L += [f"## {key} ({a['scenes']} / {b['scenes']} scenes)", "",
              "| figure | median A -> B | ratio | worst A -> B | ratio |",
              "|---|---:|---:|---:|---:|"]
        for k, label, _, spec in FIGURES:
            cells = []
            for part in ("median", "worst"):
                va, vb = a[k][part], b[k][part]
                ratio = (f"{vb / va:.2f}" if _num(va) and _num(vb) and va != 0 else "-")
                cells += [f"{_f(va, spec)} -> {_f(vb, spec)}", ratio]
            L.append(f"| {label} | " + " | ".join(cells) + " |")
        L += ["", f"gross joints {a['gross_joints']} -> {b['gross_joints']}; by mode: "
              + ", ".join(f"{m} {a['gross_by_mode'][m]} -> {b['gross_by_mode'][m]}"
                          for m in MODES), ""]
    kinds = [k for k in dict.fromkeys(s["kind"] for s in B["scenes"])
             if any(x["kind"] == k for x in A["scenes"])]
    ta = dict(targets(A["scenes"], kinds))
    tb = targets(B["scenes"], kinds)
    if tb:
        L += ["## Against the targets (A -> B)", "", "| target | " + " | ".join(kinds) + " |",
              "|---|" + "---:|" * len(kinds)]
        for label, cells in tb:
            row = []
            for k in kinds:
                if k not in cells:
                    row.append("-")
                    continue
                a = ta.get(label, {}).get(k, ("n/a", None))
                row.append(f"{a[0]} -> {cells[k][0]}"
                           + ("" if cells[k][1] is not False else " **no**"))
            L.append(f"| {label} | " + " | ".join(row) + " |")
        L.append("")
    L += ["## Per scene", "", "| scene | run | PA-MPJPE mm A -> B | > 0.3 m % A -> B | "
          "> 1 m % A -> B | worst m A -> B | err/std med A -> B | distance err % A -> B |",
          "|---|---|---:|---:|---:|---:|---:|---:|"]
    before = {(s["name"], m): flat(s, m) for s in A["scenes"] for m in METHODS if m in s}
    for s in B["scenes"]:
        for m in METHODS:
            if (s["name"], m) not in before or m not in s:
                continue
            a, b = before[(s["name"], m)], flat(s, m)
            if a is None or b is None:
                L.append(f"| {s['name']} | {m} | {'failed' if a is None else 'ok'} -> "
                         f"{'failed' if b is None else 'ok'} |")
                continue
            L.append(f"| {s['name']} | {m} | " + " | ".join(
                f"{_f(a[k], spec)} -> {_f(b[k], spec)}" for k, spec in (
                    ("pa_mpjpe_mm", ".1f"), ("gross_pct", ".2f"), ("far_pct", ".2f"),
                    ("worst_m", ".2f"), ("z_median", ".2f"), ("distance_err_pct", "+.1f")))
                + " |")
    L.append("")
    only = sorted(set(A["summary"]) ^ set(B["summary"]))
    if only:
        L.append("Scenes and runs in one file only: " + ", ".join(only))
    return L


# =========================================================================== main
def code_version() -> str:
    """The measured code: the imported package's repository commit (its last commit of
    ``mirrorgraph/`` beside HEAD, ``modified`` with uncommitted changes), else its path."""
    import mirrorgraph

    pkg = Path(mirrorgraph.__file__).resolve().parent

    def git(*a):
        return subprocess.run(["git", "-C", str(pkg.parent), *a], capture_output=True,
                              text=True).stdout.strip()

    head = git("rev-parse", "--short", "HEAD")
    if not head or not (pkg.parent / ".git").exists():
        return f"mirrorgraph from {pkg}"
    last = git("log", "-1", "--format=%h", "--", "mirrorgraph")
    dirty = git("status", "--porcelain", "mirrorgraph")
    code = f"{head}, mirrorgraph/ at {last}" if last and last != head else head
    where = "" if pkg.parent == ROOT else f" ({pkg.parent})"
    return code + where + (" (modified)" if dirty else "")



def _default_height_sigma() -> float:
    """``RefineOptions.height_sigma``'s default (a fraction)."""
    from mirrorgraph.graph import RefineOptions

    return float(RefineOptions().height_sigma)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", default="iid,realistic,cmu,lowpar,paper,fixtures",
                    help=f"comma-separated, of {', '.join(KINDS)}")
    ap.add_argument("--methods", default="calibrate,live", help="calibrate, live")
    ap.add_argument("--seeds", default=None,
                    help="seeds of every synthetic kind, e.g. 0-5 or 0,3,7 (default: "
                         + ", ".join(f"{k} {v}" for k, v in DEFAULT_SEEDS.items()) + ")")
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--height-given", choices=HEIGHT_GIVEN, default="reported",
                    help="the subject height the runs are given: 'reported' (default), a "
                         "user's own report (the true height + 1.1 cm + 1.9 cm x a normal "
                         "draw of the scene), or 'exact'")
    ap.add_argument("--body", choices=BODIES, default="population",
                    help="the synthetic bodies' proportions: 'population' (default; each "
                         "segment's spread among adults) or 'model' (3 %% each)")
    ap.add_argument("--keypoint-offset", type=float, default=None, metavar="METRES",
                    help="the keypoints' placement off the landmarks the runs' metric scale "
                         "std holds (RefineOptions.keypoint_offset; default: the literature's "
                         "1.7 %% of the height); 0 for keypoints on the joints")
    ap.add_argument("--height-sigma", type=float, default=None, metavar="FRACTION",
                    help="the relative std of the height the runs are given "
                         "(RefineOptions.height_sigma; default: the option's), e.g. 0.013 for "
                         "the reported heights' 1.1 cm bias and 1.9 cm spread")
    ap.add_argument("--refine", type=_refine_pair, action="append", default=[],
                    metavar="NAME=VALUE",
                    help="a RefineOptions field the runs set (repeatable), e.g. "
                         "joints_bone_lengths=integrated torso_sigma=0.02")
    ap.add_argument("--live", type=_refine_pair, action="append", default=[],
                    metavar="NAME=VALUE",
                    help="a LiveOptions field the live runs set (repeatable), e.g. "
                         "window_graph_frames=0 lag_frames=5")
    ap.add_argument("--scene", type=_refine_pair, action="append", default=[],
                    metavar="NAME=VALUE",
                    help="a make_scene argument of the synthetic scenes (repeatable; it wins "
                         "over the drawn one), e.g. noise_correlation=0 joint_bias_px=0: "
                         "ablations of the detector models")
    ap.add_argument("--full", action="store_true",
                    help="the wide run: " + ", ".join(f"{k} {v}" for k, v in FULL_SEEDS.items()))
    ap.add_argument("--fixtures", type=Path, default=default_fixtures(),
                    help="folder of fixture scenes (default: shared/fixtures in a folder "
                         "above the repository)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--nice", type=int, default=10,
                    help="niceness added to this process and its workers (default 10: the "
                         "benchmark shares the machine)")
    ap.add_argument("--json", metavar="OUT", default=None, help="every number, as JSON")
    ap.add_argument("--out", default=str(ROOT / "bench" / "RESULTS_joints.md"))
    ap.add_argument("--no-write", action="store_true",
                    help="print the tables without writing --out (an explicit --json is written)")
    ap.add_argument("--offline-from", metavar="JSON", default=None,
                    help="with --methods live: the calibrate figures of the same scenes taken "
                         "from this earlier --json (its code named in the header), for the "
                         "live / calibrate ratios")
    ap.add_argument("--compare", nargs=2, metavar=("A.json", "B.json"),
                    help="print A and B side by side (ratios B / A) and exit")
    args = ap.parse_args(argv)
    if args.compare:
        print("\n".join(compare(*args.compare)))
        return 0
    if args.nice:
        os.nice(args.nice)
    kinds = [k for k in args.kinds.split(",") if k]
    methods = [m for m in args.methods.split(",") if m]
    for k in kinds:
        if k not in KINDS:
            ap.error(f"--kinds: unknown {k!r}; known: {', '.join(KINDS)}")
    for m in methods:
        if m not in METHODS:
            ap.error(f"--methods: unknown {m!r}; known: {', '.join(METHODS)}")
    if args.refine:
        from mirrorgraph.graph import RefineOptions
        try:
            _refine_options(args.keypoint_offset, args.height_sigma, tuple(args.refine))
        except (TypeError, ValueError) as exc:
            ap.error(f"--refine: {exc} (fields: RefineOptions, "
                     f"{', '.join(sorted(RefineOptions.__dataclass_fields__))})")
    if args.live:
        from mirrorgraph.live import LiveOptions
        unknown = [k for k, _ in args.live if k not in LiveOptions.__dataclass_fields__]
        if unknown:
            ap.error(f"--live: unknown {', '.join(unknown)} (fields: "
                     f"{', '.join(sorted(LiveOptions.__dataclass_fields__))})")
    cases = []
    for k in kinds:
        if k == "fixtures":
            found = fixture_dirs(Path(args.fixtures))
            if not found:
                print(f"fixtures: no scene in {args.fixtures}; left out", file=sys.stderr)
            cases += [(k, p.name, args.frames, methods, str(args.fixtures), args.body,
                       args.height_given, args.keypoint_offset, args.height_sigma,
                       tuple(args.refine), tuple(args.scene), tuple(args.live))
                      for p in found]
        else:
            seeds = args.seeds or (FULL_SEEDS if args.full else DEFAULT_SEEDS)[k]
            cases += [(k, s, args.frames, methods, str(args.fixtures), args.body,
                       args.height_given, args.keypoint_offset, args.height_sigma,
                       tuple(args.refine), tuple(args.scene), tuple(args.live))
                      for s in _seeds(seeds)]
    if not cases:
        print("no scene to run", file=sys.stderr)
        return 2
    started = _dt.datetime.now(_dt.timezone.utc)
    clock = time.perf_counter()
    with ProcessPoolExecutor(max(1, args.workers)) as pool:
        scenes = []
        for s in pool.map(run_scene, cases):
            scenes.append(s)
            brief = "; ".join(
                f"{m} PA {s[m].get('pa_mpjpe_mm', float('nan')):.1f} mm, "
                f">0.3 m {100 * s[m].get('gross', float('nan')):.2f} %"
                if "error" not in s[m] else f"{m} failed" for m in methods)
            print(f"{s['name']}: oracle PA {s['oracle']['pa_mpjpe_mm']:.1f} mm; {brief} "
                  f"({s['seconds']:.0f} s)", file=sys.stderr, flush=True)
    offline_note = []
    if args.offline_from and "calibrate" not in methods:
        earlier = json.loads(Path(args.offline_from).read_text())
        by_name = {sc["name"]: sc.get("calibrate") for sc in earlier["scenes"]}
        for sc in scenes:
            if by_name.get(sc["name"]):
                sc["calibrate"] = by_name[sc["name"]]
        methods = ["calibrate"] + methods
        offline_note = [f"- calibrate: figures of `{args.offline_from}` (code "
                        f"`{earlier['meta'].get('code')}`, {earlier['meta'].get('date')}), "
                        "not rerun"]
    agg = aggregate(scenes, kinds, methods)
    code = code_version()
    meta = dict(date=f"{started:%Y-%m-%d %H:%M} UTC", code=code,
                command="python bench/bench_joints.py " + shlex.join(argv),
                machine=_report.machine(), load=os.getloadavg()[0], minutes=(time.perf_counter() - clock) / 60.0,
                frames=args.frames, kinds=kinds, methods=methods, gross_m=GROSS_M, far_m=FAR_M,
                height_given=args.height_given, body=args.body,
                keypoint_offset=args.keypoint_offset, height_sigma=args.height_sigma,
                refine=dict(args.refine), scene=dict(args.scene), live=dict(args.live),
                mode_px=MODE_PX)
    L = ["# The 3D joints against the truth (`bench/bench_joints.py`)", "",
         f"- date: {meta['date']}; code `{meta['code']}`",
         f"- machine: {meta['machine']}; {meta['minutes']:.1f} min with {args.workers} "
         "workers",
         f"- command: `{meta['command'].rstrip()}`", *offline_note,
         *([] if "live" in methods else
           ["- live: not run here; its figures are `bench/RESULTS_joints_live.md`'s "
            "(`--methods live --offline-from` this file's JSON)"]),
         "- scenes: `iid`, `realistic`: `make_wide_scene(seed, 'wide', noise, frames)`; `cmu`: "
         "the same (iid) moved by the CMU take 01_01; `paper`: `make_scene` with 4 px iid "
         "noise, 3 % outliers; `fixtures`: the independent generator's scenes; "
         f"{args.frames} frames, the camera matrix and the subject's height given"
         + ({"reported": " as a user reports it (the true height + 1.1 cm + 1.9 cm x a "
                         "normal draw of the scene: `REPORTED_HEIGHT_*`)",
             "exact": " exactly"}[args.height_given])
         + ({"population": "; the synthetic bodies' proportions drawn with each segment's "
                           "spread among adults (`POPULATION_VARIATION`), CMU's the take's",
             "model": "; the synthetic bodies' segments 3 % apart"}[args.body]),
         "- keypoint placement the metric scale's std holds (`--keypoint-offset`): "
         + ("the default, `anthropometry.KEYPOINT_OFFSET` = 1.7 % of the height (Needham et "
            "al. 2021)" if args.keypoint_offset is None
            else f"{args.keypoint_offset:g} m, stated (`RefineOptions.keypoint_offset`)"),
         "- the given height's relative std (`--height-sigma`): "
         + (f"the default, `RefineOptions.height_sigma` = {100 * _default_height_sigma():g} %"
            if args.height_sigma is None
            else f"{100 * args.height_sigma:g} %, stated (`RefineOptions.height_sigma`)"),
         *(["- graph options set (`--refine`): "
            + ", ".join(f"`{k}={v}`" for k, v in args.refine)] if args.refine else []),
         *(["- live options set (`--live`): "
            + ", ".join(f"`{k}={v}`" for k, v in args.live)] if args.live else []),
         *(["- scene arguments set (`--scene`, the synthetic kinds): "
            + ", ".join(f"`{k}={v}`" for k, v in args.scene)] if args.scene else []),
         "- figures: MPJPE (no alignment) and PA-MPJPE (per-frame similarity) over the joints "
         "given; `oracle PA`: each frame triangulated with the true mirror from the same "
         "observations, outliers removed with the truth; `> 0.3 m`, `> 1 m`: shares of the "
         "joints given; `given`: share of the scene's joints; `err/std`: the error's length "
         "over the joint's std (`n/a`: the run carries none), `shape`: the error left once the "
         "run's scale is fitted to the truth (one factor about the camera; live: each fused "
         "mirror's over the frames it served) over the std "
         "without the metric scale's share (`joints_std_shape`); `> 0.3 m scaled`: the "
         "share of joints that far off after that fit; `distance`: the metric mirror "
         "distance's error and error / std; `scale`: the run's metric scale's error (its "
         "joints over the truth's, least squares about the camera) and error over its "
         "`scale_rel_std`; time: wall and CPU s of the run in its process; "
         "`/ oracle, same joints`: both PA-MPJPEs over the joints both give (the oracle's few "
         "joints of near-parallel rays, metres off, and the run's left-out ones out of the "
         "ratio); `/ calibrate`: live's PA-MPJPE over the offline run's",
         ""] + tables(scenes, agg, methods)
    text = "\n".join(L) + "\n"
    print(text)
    if not args.no_write:
        Path(args.out).write_text(text)
    if args.json:                  # asked for by name: written with --no-write too
        Path(args.json).write_text(json.dumps(dict(meta=meta, summary=agg, scenes=scenes),
                                              indent=1, default=float) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
