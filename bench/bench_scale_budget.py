"""The metric scale's error under the realistic detector, part by part, and its bound.

``bench_joints.py``'s ``realistic`` wide scenes (AR(1) noise, a per-label pixel bias of
2-4 px shared by both views, epipolar outliers, left/right swaps; the subject's height as
a user reports it) carry a metric scale error of several percent, which alone puts most
of their joints more than 0.3 m off. Each scene is calibrated once
(:func:`mirrorgraph.calibrate`, as ``bench_joints`` runs it) and the run's scale error
(its joints over the truth: the least-squares factor about the camera, as
``bench_joints`` measures it) is factored into five parts that multiply to it:

    1 + scale error = a x b x c x d x e

* **a, the height given**: the reported height over the true one (data, not ours);
* **b, the stature model**: the true height over the stature chain
  (:func:`mirrorgraph.stature.estimate_stature`) measured on the true joints;
* **c, the detector**: the chain on the true joints over the chain on the scene's own
  observations triangulated with the TRUE mirror (its true normal and distance, the
  outliers removed with the truth, :func:`mirrorgraph.geometry.triangulate`): what an
  estimator that does not know the detector's bias cannot avoid. ``c`` is split into
  ``c bias``, the same with each label's mean pixel offset over the clip on the true
  projections (the detector's systematic part on this clip), and the rest (the noise);
* **d, the mirror**: the run's distance error beyond ``a b c``;
* **e, the joints against the run's own mirror**: the run's joint scale over its
  distance's ``d_run / d_true``. ``e`` is read in three factors (they multiply to it up
  to the masks): ``e det``, the true-mirror triangulation's own joint scale (the
  detector's bias moves the triangulated depth, not only the lengths); ``e normal``, the
  triangulation with the run's normal at the true distance over the true mirror's;
  ``e graph``, the run's joints over the triangulation with the run's own mirror (what
  the graph's priors make of the observations).

The share of joints more than 0.3 m off is shown as run, with the joints rescaled as if
``a``, then ``a`` and ``c``, were absent, at the **bound** (the run's shape at the scale
``a b c e_det``: the true mirror, the user's height and the detector's keypoints, the
chain on them), and with the scale fitted to the truth. The iid scenes are the control
(no bias: ``c`` the noise alone).

Usage::

    python bench/bench_scale_budget.py              # realistic 0-7, iid 0-3: 2 min idle, ~10 busy
    python bench/bench_scale_budget.py --seeds 0-19 --iid-seeds 0-7 \
        --json bench/RESULTS_scale_budget.json     # the results file's run, ~3-15 min
    python bench/bench_scale_budget.py --from-json bench/RESULTS_scale_budget.json

Writes ``--out`` (default ``bench/RESULTS_scale_budget.md``) unless ``--no-write``; the
Reading section reads apart the scenes whose run's own scale std exceeds
:data:`UNSCALED_REL_STD` (no scale in their data, and the run says so).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _report  # noqa: E402
import bench_joints as bj  # noqa: E402


def _ls_scale(X: np.ndarray, T: np.ndarray, ok: np.ndarray) -> float:
    """``X``'s scale over ``T`` about the camera on the joints ``ok``: ``1 / f`` of the
    least-squares ``T ~ f X`` (``bench_joints``' scale error plus one)."""
    Xg, Tg = X[ok], T[ok]
    return float((Xg * Xg).sum() / (Xg * Tg).sum())


def _triangulate(tr, real, mirror, normal, distance, masks):
    from mirrorgraph.geometry import camera_projection, mirror_projection, triangulate

    eye = np.eye(4)
    P = [camera_projection(tr.intrinsics.K, eye),
         mirror_projection(tr.intrinsics.K, eye, np.asarray(normal, float), float(distance))]
    return triangulate(P, [real, mirror], masks)


def _bias_only(tr, clean):
    """The true joints' projections plus each label's mean offset of the clean
    observations over the clip: ``(real, mirror)`` ``(T, J, 2)``."""
    from mirrorgraph.geometry import project, reflect_points

    T, J = tr.joints3d.shape[:2]
    K = tr.intrinsics.K
    pr = project(K, tr.joints3d.reshape(-1, 3)).reshape(T, J, 2)
    pm = project(K, reflect_points(tr.joints3d.reshape(-1, 3), tr.normal,
                                   tr.distance)).reshape(T, J, 2)
    out = []
    for obs, proj, ok in ((tr.real, pr, clean[0]), (tr.mirror, pm, clean[1])):
        off = np.where(ok[..., None], obs - proj, np.nan)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            mean = np.nan_to_num(np.nanmean(off, axis=0))                  # (J, 2)
        out.append(np.where(ok[..., None], proj + mean, np.nan))
    return out


def scene_row(case: tuple) -> dict:
    """One scene calibrated, its scale error in parts."""
    warnings.filterwarnings("ignore")
    import mirrorgraph as mg
    from mirrorgraph.stature import estimate_stature

    kind, seed, frames = case
    tr = bj.make_truth(kind, seed, frames, Path("/nonexistent"))
    sk = tr.detections.skeleton
    finite = np.isfinite(tr.joints3d).all(-1)
    st_true = estimate_stature(tr.joints3d, finite, sk).height
    clean = (np.isfinite(tr.real).all(-1) & ~tr.out_real,
             np.isfinite(tr.mirror).all(-1) & ~tr.out_mirror)
    # c: the detector's keypoints triangulated with the true mirror
    Xo, oko = _triangulate(tr, tr.real, tr.mirror, tr.normal, tr.distance, list(clean))
    st_obs = estimate_stature(Xo, oko, sk).height
    br, bm = _bias_only(tr, clean)
    Xb, okb = _triangulate(tr, br, bm, tr.normal, tr.distance, list(clean))
    st_bias = estimate_stature(Xb, okb, sk).height

    wall = time.perf_counter()
    run = mg.calibrate(tr.detections, tr.intrinsics,
                       mg.CalibrateOptions(subject_height=tr.height_given, fps=bj.FPS))
    wall = time.perf_counter() - wall
    cal = run.calibration
    X, given, _, _ = bj.on_truth_frames(run, tr)
    g = given & np.isfinite(X).all(-1)
    scale = _ls_scale(X, tr.joints3d, g)
    dist = float(cal.distance) / tr.distance
    n_run = np.asarray(cal.normal, float)
    a = tr.height_given / tr.height
    b = tr.height / st_true
    c = st_true / st_obs
    c_bias = st_true / st_bias
    d = dist / (a * b * c)
    e = scale / dist
    # e in factors: the detector's depth, the run's normal, the graph against the data
    e_det = _ls_scale(Xo, tr.joints3d, oko)
    Xn, okn = _triangulate(tr, tr.real, tr.mirror, n_run, tr.distance, list(clean))
    e_normal = _ls_scale(Xn, tr.joints3d, okn) / e_det
    Xr, okr = _triangulate(tr, tr.real, tr.mirror, n_run, float(cal.distance), list(clean))
    both = g & okr
    e_graph = _ls_scale(X, Xr, both)
    # the normal's part by another statistic: the median of the joints' distances from
    # the camera over the truth's (no weight on the far joints)
    with np.errstate(invalid="ignore", divide="ignore"):
        e_normal_med = float(np.median(np.linalg.norm(Xn[okn], axis=-1)
                                       / np.linalg.norm(Xo[okn], axis=-1)))
    Xg, Tg = X[g], tr.joints3d[g]

    def gross(factor: float) -> float:
        return float((np.linalg.norm(Xg * factor - Tg, axis=-1) > bj.GROSS_M).mean())

    std = float(run.scale_rel_std) if run.scale_rel_std is not None else float("nan")
    dstd = (cal.uncertainty or {}).get("distance_std")
    angle = _angle_deg(n_run, tr.normal)
    bound = a * b * c * e_det
    rot_std = float((cal.uncertainty or {}).get("rotation_std_deg") or np.nan)
    unbiased = _unbiased_run(tr, frames) if kind == "realistic" else {}
    return dict(kind=kind, seed=seed, wall_s=wall, normal_z=angle / rot_std, **unbiased,
                depth=float(np.median(np.linalg.norm(Tg, axis=-1))), rays=_rays_deg(tr),
                scale=scale - 1.0, std=std, z=abs(scale - 1.0) / std,
                dist=dist - 1.0, dist_z=(abs(float(cal.distance) - tr.distance) / dstd
                                         if dstd else float("nan")),
                normal_deg=angle,
                a=a - 1.0, b=b - 1.0, c=c - 1.0, c_bias=c_bias - 1.0,
                c_noise=c / c_bias - 1.0, d=d - 1.0, e=e - 1.0,
                e_det=e_det - 1.0, e_normal_median=e_normal_med - 1.0, e_normal=e_normal - 1.0,
                e_graph=e_graph - 1.0, bound=bound - 1.0,
                gross=gross(1.0), gross_no_a=gross(1.0 / a), gross_no_ac=gross(1.0 / (a * c)),
                gross_bound=gross(bound / scale),
                gross_ac_truth=float((abs(a * c - 1.0) * np.linalg.norm(Tg, axis=-1)
                                      > bj.GROSS_M).mean()), gross_fitted=gross(1.0 / scale))


def _rays_deg(tr) -> float:
    """The median angle (deg) between a true joint's two rays, from the camera and from
    the virtual camera (``2 d n``), folded to at most 90: near 0 the rays are near
    parallel and the depth is poorly fixed."""
    X = tr.joints3d[np.isfinite(tr.joints3d).all(-1)]
    u, v = -X, 2.0 * tr.distance * np.asarray(tr.normal, float) - X
    cos = np.abs((u * v).sum(1)) / np.linalg.norm(u, axis=1) / np.linalg.norm(v, axis=1)
    return float(np.degrees(np.median(np.arccos(np.clip(cos, 0.0, 1.0)))))


def _angle_deg(n: np.ndarray, m: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(abs(np.asarray(n, float) @ m), -1.0, 1.0))))


def _unbiased_run(tr, frames: int) -> dict:
    """The same scene without the detector's per-label bias (its noise, outliers and
    swaps drawn alike: the bias is the detector's last draw) calibrated as ``tr``: its
    normal's error (deg), distance and scale errors, share > 0.3 m."""
    import mirrorgraph as mg
    from mirrorgraph.synth import make_wide_scene

    sc = make_wide_scene(int(tr.seed), "wide", "realistic", frames,
                         body_variation="population", joint_bias_px=0.0)
    run = mg.calibrate(sc.detections, sc.intrinsics,
                       mg.CalibrateOptions(subject_height=tr.height_given, fps=bj.FPS))
    X, given, _, _ = bj.on_truth_frames(run, tr)
    g = given & np.isfinite(X).all(-1)
    scale = _ls_scale(X, tr.joints3d, g)
    err = np.linalg.norm(X[g] - tr.joints3d[g], axis=-1)
    return dict(nb_normal_deg=_angle_deg(run.calibration.normal, tr.normal),
                nb_dist=float(run.calibration.distance) / tr.distance - 1.0,
                nb_scale=scale - 1.0, nb_gross=float((err > bj.GROSS_M).mean()))


def pct(v: float | None, spec: str = "+.2f") -> str:
    return "-" if v is None or not np.isfinite(v) else format(100.0 * v, spec)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", default="0-7", help="the realistic scenes (bench_joints' seeds)")
    ap.add_argument("--iid-seeds", default="0-3", help="the iid scenes, the control ('' none)")
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--jobs", type=int, default=2, help="scenes at once (at most 2 here)")
    ap.add_argument("--nice", type=int, default=10)
    ap.add_argument("--out", default=str(bj.ROOT / "bench" / "RESULTS_scale_budget.md"))
    ap.add_argument("--json", help="also write every scene's figures to this file")
    ap.add_argument("--from-json", help="write the report again from such a file (no runs)")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    if args.from_json:
        saved = json.loads(Path(args.from_json).read_text())
        text = report(saved["rows"], None, saved["date"], saved["seconds"], saved["jobs"],
                      saved["command"], saved["machine"], saved["code"])
        print(text)
        if not args.no_write:
            Path(args.out).write_text(text)
        return 0
    if args.nice:
        os.nice(args.nice)
    started = _report.now()
    clock = time.perf_counter()
    cases = [("realistic", s, args.frames) for s in bj._seeds(args.seeds)]
    if args.iid_seeds:
        cases += [("iid", s, args.frames) for s in bj._seeds(args.iid_seeds)]
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as ex:
            rows = list(ex.map(scene_row, cases))
    else:
        rows = [scene_row(c) for c in cases]
    seconds = time.perf_counter() - clock
    rec = _report.record(argv=argv, code=True)
    text = report(rows, argv, started, seconds, args.jobs, rec["command"], rec["machine"],
                  rec["code"])
    if args.json:
        Path(args.json).write_text(json.dumps(dict(rec, rows=rows, date=started, seconds=seconds,
                                                   jobs=args.jobs), indent=1))
    print(text)
    if not args.no_write:
        Path(args.out).write_text(text)
    return 0


def report(rows: list[dict], argv, started: str, seconds: float, jobs: int,
           command: str, machine: str, code: str) -> str:
    L = ["# The metric scale under the realistic detector, part by part, and its bound "
         "(`bench/bench_scale_budget.py`)", "",
         *_report.header(started=started, cmd=command, machine_line=machine, code=code,
                         note=f"{seconds / 60:.1f} min, {jobs} scenes at once"), "",
         "`scale`: the run's joints over the truth's (least squares about the camera), "
         "`std` its `scale_rel_std`; the parts multiply to it: `a` the height given "
         "(reported / true), `b` the stature model on the true joints, `c` the detector "
         "(the chain on the true joints over the chain on the observations triangulated "
         "with the true mirror, outliers removed with the truth; `c bias`: each label's "
         "mean offset over the clip alone), `d` the mirror (the distance's error beyond "
         "`a b c`), `e` the joints against the run's own distance (`e det`: the true-mirror "
         "triangulation's joint scale, `e normal`: the run's normal's, `e graph`: the "
         "run's joints over the triangulation with its own mirror). `dist`: the run's "
         "distance error, `z` its error/std; `depth`: the joints' median distance from the "
         "camera, `rays`: the median angle between a joint's two rays (0: parallel); `normal`: the normal's error (deg), `z` its "
         "error over `rotation_std_deg`.", "",
         "| scene | depth m | rays deg | scale % | std % | err/std | dist % | dist z | "
         "normal deg | normal z | a % | b % | c % | c bias % | d % | e % | e det % | e normal % | e graph % |",
         "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
         "---:|---:|"]
    for r in rows:
        L.append(f"| {r['kind']} {r['seed']} | {r['depth']:.1f} | {r['rays']:.0f} | "
                 f"{pct(r['scale'])} | "
                 f"{pct(r['std'], '.2f')} | {r['z']:.2f} | {pct(r['dist'])} | "
                 f"{r['dist_z']:.2f} | {r['normal_deg']:.2f} | {r['normal_z']:.2f} | "
                 f"{pct(r['a'])} | {pct(r['b'])} | "
                 f"{pct(r['c'])} | {pct(r['c_bias'])} | {pct(r['d'])} | {pct(r['e'])} | "
                 f"{pct(r['e_det'])} | {pct(r['e_normal'])} | {pct(r['e_graph'])} |")
    L += ["", "`> 0.3 m`: the share of the run's joints that far off as run, rescaled as if "
          "`a`, then `a` and `c`, were absent, at the bound (the scale `a b c e det`: the "
          "true mirror, the user's height, the detector's keypoints), and with the scale "
          "fitted to the truth; `a c alone`: the true joints scaled by `a c` (a perfect "
          "shape and mirror, the scale's error the height's and the detector's only).", "",
          "| scene | scale % | bound's scale % | > 0.3 m % | without a % | without a, c % | "
          "at the bound % | scale fitted % | a c alone % |",
          "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        L.append(f"| {r['kind']} {r['seed']} | {pct(r['scale'])} | {pct(r['bound'])} | "
                 f"{pct(r['gross'], '.2f')} | {pct(r['gross_no_a'], '.2f')} | "
                 f"{pct(r['gross_no_ac'], '.2f')} | {pct(r['gross_bound'], '.2f')} | "
                 f"{pct(r['gross_fitted'], '.2f')} | {pct(r['gross_ac_truth'], '.2f')} |")
    nb = [r for r in rows if "nb_scale" in r]
    if nb:
        L += ["", "The same realistic scenes without the detector's per-label bias (its noise, "
              "outliers and swaps drawn alike), calibrated alike:", "",
              "| scene | normal deg | dist % | scale % | > 0.3 m % | with the bias: normal deg | "
              "dist % | scale % | > 0.3 m % |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for r in nb:
            L.append(f"| {r['kind']} {r['seed']} | {r['nb_normal_deg']:.2f} | {pct(r['nb_dist'])} | "
                     f"{pct(r['nb_scale'])} | {pct(r['nb_gross'], '.2f')} | "
                     f"{r['normal_deg']:.2f} | {pct(r['dist'])} | {pct(r['scale'])} | "
                     f"{pct(r['gross'], '.2f')} |")
    L += ["", *summary(rows), "", *reading(rows)]
    return "\n".join(L) + "\n"


#: A run whose metric scale's relative std exceeds this has no scale to speak of (its
#: rays near parallel); the Reading names it and reads the others.
UNSCALED_REL_STD = 0.10


def reading(rows: list[dict]) -> list[str]:
    """The Reading section, from the rows."""
    every = [r for r in rows if r["kind"] == "realistic"]
    # a run whose own scale std says it has no scale (the rays near parallel) is read apart
    apart = [r for r in every if not r["std"] <= UNSCALED_REL_STD]
    re = [r for r in every if r not in apart]
    ii = [r for r in rows if r["kind"] == "iid"]
    if not re:
        return []

    def col(rs, k):
        return np.array([r[k] for r in rs], float)

    def rms(rs, k):
        return float(np.sqrt(np.mean(col(rs, k) ** 2)))

    def names(rs):
        return ", ".join(str(r["seed"]) for r in rs) or "none"

    n = len(re)
    de = np.array([(1 + r["d"]) * (1 + r["e"]) - 1 for r in re])
    parts = {"a (the height given)": rms(re, "a"), "b (the model)": rms(re, "b"),
             "c (the detector)": rms(re, "c"),
             "d e (the mirror, both)": float(np.sqrt(np.mean(de ** 2)))}
    top = max(parts, key=parts.get)
    largest = np.array([max(("a", "b", "c", "d e"), key=lambda k, r=r: abs(
        r[k] if k != "d e" else (1 + r["d"]) * (1 + r["e"]) - 1)) for r in re])
    over = [r for r in re if r["gross"] > 0.02]
    ac_over = [r for r in re if r["gross_ac_truth"] > 0.02]
    bound_over = [r for r in re if r["gross_bound"] > 0.02]
    nb = [r for r in re if "nb_normal_deg" in r]
    lines = ["## Reading", "",
             *([f"- Read apart: realistic {names(apart)}, whose run gives its scale a std of "
                + ", ".join(f"{pct(r['std'], '.0f')} %" for r in apart)
                + " (scale error " + ", ".join(f"{pct(r['scale'], '+.1f')} %" for r in apart)
                + ", the chain on the true-mirror triangulation "
                + ", ".join(f"{pct(r['c'], '+.1f')} %" for r in apart)
                + "; > 0.3 m " + ", ".join(f"{pct(r['gross'], '.1f')} %" for r in apart)
                + "; the rays " + ", ".join(f"{r['rays']:.0f} deg" for r in apart)
                + " apart against a median of "
                + f"{np.median([r['rays'] for r in every]):.0f} deg): near-parallel rays, "
                "no scale in these data, and the run says so. "
                "The figures below leave them out."] if apart else []),
             f"- What dominates: over the {n} realistic scenes the parts' RMS are "
             + ", ".join(f"{k} {pct(v, '.2f')} %" for k, v in parts.items())
             + f": the largest is {top}; the largest part of a scene is "
             + ", ".join(f"{k} on {int((largest == k).sum())}" for k in ("c", "d e", "a", "b")
                         if (largest == k).any())
             + f" of {n}. d and e apart are {pct(rms(re, 'd'), '.2f')} % and "
             f"{pct(rms(re, 'e'), '.2f')} % RMS, of opposite signs on most scenes "
             f"({int((col(re, 'd') * col(re, 'e') < 0).sum())} of {n}): they are one cause, "
             f"the run's normal ({col(re, 'normal_deg').min():.2f}-"
             f"{col(re, 'normal_deg').max():.2f} deg off; within its std: error over "
             f"`rotation_std_deg` {col(re, 'normal_z').max():.2f} at most)"
             + (f", and without the detector's bias the same scenes' normals are "
                f"{col(nb, 'nb_normal_deg').min():.2f}-{col(nb, 'nb_normal_deg').max():.2f} deg off, "
                f"their scale {pct(rms(nb, 'nb_scale'), '.2f')} % RMS against "
                f"{pct(rms(re, 'scale'), '.2f')} %, > 0.3 m above 2 % on "
                f"{int((col(nb, 'nb_gross') > 0.02).sum())} of {len(nb)} scenes" if nb else "")
             + ". So the detector's bias makes both c (on the chain's lengths) and, through "
             "the normal, d and e; the height given (a) is the same size on the iid control "
             f"(RMS {pct(rms(ii, 'a'), '.2f')} %), where c is {pct(rms(ii, 'c'), '.2f')} % "
             f"RMS and the scale {pct(rms(ii, 'scale'), '.2f')} %." if ii else ".",
             f"- Part (e): the run's joints against its own mirror, {pct(col(re, 'e').min())} "
             f"to {pct(col(re, 'e').max())} %, is the run's normal's (`e normal` "
             f"{pct(col(re, 'e_normal').min())} to {pct(col(re, 'e_normal').max())} %; by the "
             "median of the joints' distances from the camera, no weight on far joints: "
             f"{pct(col(re, 'e_normal_median').min())} to {pct(col(re, 'e_normal_median').max())} %), "
             "not the graph's: its joints lie on the triangulation with its own mirror to "
             f"{pct(np.abs(col(re, 'e_graph')).max(), '.2f')} % (`e graph`), the detector's "
             f"depth to {pct(np.abs(col(re, 'e_det')).max(), '.2f')} % (`e det`). A change "
             "of the normal at a fixed distance is no similarity of the scene: it moves the "
             "joints' distances from the camera (e) and the chain's lengths (d) apart, so "
             "d and e of one scene need not cancel. The bone-length and stature priors do "
             "not pull the joints off their observations' depth, and the far joints' "
             "weight in the scale fit is not the cause (the median agrees): no defect.",
             f"- The bound (the true mirror, the user's height, the detector's keypoints, "
             "the chain on them: the scale `a b c e det`, the run's shape): > 0.3 m median "
             f"{pct(np.median(col(re, 'gross_bound')), '.2f')} %, above 2 % on "
             f"{len(bound_over)} of {n} scenes (realistic {names(bound_over)}: "
             + ", ".join(f"{pct(r['gross_bound'], '.1f')} %" for r in bound_over)
             + "). With a perfect shape (the true joints scaled by `a c` alone) above 2 % on "
             f"{len(ac_over)} of {n} (realistic {names(ac_over)}: "
             + ", ".join(f"{pct(r['gross_ac_truth'], '.1f')} % at a c = "
                         f"{pct((1 + r['a']) * (1 + r['c']) - 1)} %, depth {r['depth']:.1f} m"
                         for r in ac_over) + ").",
             f"- calibrate: > 0.3 m median {pct(np.median(col(re, 'gross')), '.2f')} %, above "
             f"2 % on {len(over)} of {n} scenes (realistic {names(over)}"
             + (f"; and realistic {names(apart)} read apart" if apart else "") + "); with the scale "
             f"fitted to the truth at most {pct(col(re, 'gross_fitted').max(), '.2f')} %. Its "
             f"scale's err/std {col(re, 'z').max():.2f} at most (median "
             f"{np.median(col(re, 'z')):.2f}): the std covers the error.",
             f"- c in two: the per-label mean offsets alone (`c bias`) RMS "
             f"{pct(rms(re, 'c_bias'), '.2f')} %, the rest (the noise and its interplay with "
             f"the bias) RMS {pct(rms(re, 'c_noise'), '.2f')} % (iid control: "
             f"{pct(rms(ii, 'c_noise'), '.2f')} %)." if ii else "",
             ("- The target (at most 2 % of joints > 0.3 m under the realistic detector) is "
              "beyond what these data allow for a scale from the stature chain on these "
              "keypoints and the height a user gives: with the true mirror the scale `a b c "
              f"e det` leaves {len(bound_over)} of {n} scenes above 2 % with the run's shape, "
              f"and `a c` alone {len(ac_over)} of {n} with a perfect shape. 0.3 m is a scale "
              f"error of {pct(bj.GROSS_M / col(re, 'depth').max(), '.1f')}-"
              f"{pct(bj.GROSS_M / col(re, 'depth').min(), '.1f')} % at these scenes' median "
              f"depths ({col(re, 'depth').min():.1f}-{col(re, 'depth').max():.1f} m from the "
              "camera)." if bound_over or ac_over else
              "- The height given and the detector (a c) alone keep every scene within 2 %: "
              "the rest is the mirror's (d e).")]
    return lines


def summary(rows: list[dict]) -> list[str]:
    out = ["## Summary", "",
           "| kind | scenes | scale RMS % | a RMS % | c mean % | c RMS % | d RMS % | e mean % | "
           "err/std median | > 0.3 m median % | at the bound median % | "
           "scenes > 2 % as run | at the bound | fitted |",
           "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    groups = []
    for kind in dict.fromkeys(r["kind"] for r in rows):
        rs = [r for r in rows if r["kind"] == kind]
        groups.append((kind, rs))
        kept = [r for r in rs if r["std"] <= UNSCALED_REL_STD]
        if 0 < len(kept) < len(rs):
            groups.append((f"{kind}, own scale std <= {pct(UNSCALED_REL_STD, '.0f')} %", kept))
    for kind, rs in groups:

        def col(k):
            return np.array([r[k] for r in rs], float)

        rms = lambda k: float(np.sqrt(np.mean(col(k) ** 2)))  # noqa: E731
        out.append(f"| {kind} | {len(rs)} | {pct(rms('scale'), '.2f')} | {pct(rms('a'), '.2f')} | "
                   f"{pct(col('c').mean())} | {pct(rms('c'), '.2f')} | {pct(rms('d'), '.2f')} | "
                   f"{pct(col('e').mean())} | {np.median(col('z')):.2f} | "
                   f"{pct(np.median(col('gross')), '.2f')} | "
                   f"{pct(np.median(col('gross_bound')), '.2f')} | "
                   f"{int((col('gross') > 0.02).sum())} | {int((col('gross_bound') > 0.02).sum())} | "
                   f"{int((col('gross_fitted') > 0.02).sum())} |")
    return out


if __name__ == "__main__":
    sys.exit(main())
