#!/usr/bin/env python
"""Stress benchmark: the solver on the whole world of scenes, not only the favourable ones.

    python bench/bench_stress.py                       # 200 scenes x 1000 frames + fixtures
    python bench/bench_stress.py --quick               # 24 scenes x 300 frames, to a temp folder
    python bench/bench_stress.py --scenes 60 --workers 1     # serial: uncontended timings
    python bench/bench_stress.py --slices gym,low_parallax --noise realistic
    python bench/bench_stress.py --compare bench/RESULTS_stress.json --out /tmp/after
                                                       # before/after on the same scenes
    python bench/bench_stress.py --replot bench/RESULTS_stress.json   # tables again

Scenes. ``--scenes N`` random scenes from :func:`mirrorgraph.synth.make_wide_scene`,
split evenly over the slices, a slice being a geometry (``--slices``; presets of
:mod:`mirrorgraph.synth.geometry`) times a noise model (``--noise``; presets of
:mod:`mirrorgraph.synth.detector`):

* geometries: ``favourable`` (the generator's original scenes, the person ~2000 px
  from the epipole), ``gym`` (a typical gym: person 0.8-2.5 m in front of a mirror
  3.5-8 m away), ``wide`` (mirror 2.5-10 m, person 0.5-3.5 m in front of it, focal
  700-2200 px, mirror 5-70 deg off the axis, camera height and tilt varied),
  ``low_parallax`` (the wide ranges with the person near the camera-mirror line);
* noise: ``iid`` (4 px Gaussian) and ``realistic`` (4 px AR(1) noise of correlation
  0.90-0.97, a per-label bias of 2-4 px, 5 % outliers along the epipolar lines,
  3 % left/right swaps in each view).

Seed ``s`` of a slice is ``make_wide_scene(s, slice, noise, frames)``: the same
scenes in every run, so two runs compare solvers. Plus the scenes of an independent
generator in ``--fixtures`` (``../shared/fixtures``: ``keypoints.json``,
``camera.json``, ``truth.json``; skipped with a note when the folder is absent).

Per scene, in a fresh process (so that one scene's memory and crash do not touch
another; ``--workers`` such processes at once):

* ``init``: ``mirrorgraph.calibrate(..., CalibrateOptions(refine=False))`` on the raw
  detections (pairing, left/right fixes and RANSAC included);
* ``full``: ``CalibrateOptions(refine=True, subject_height=<true height>)``, end to
  end as the CLI runs it: the keypoint file read (an MMPose JSON written untimed for
  a synthetic scene), calibrated, ``calibration.json`` written;
* ``full_noheight``: ``CalibrateOptions(refine=True)``, no subject height (scale
  unknown): what ``mirrorgraph calibrate`` does by default;
* ``anipose`` (every ``--anipose-every``-th scene of a slice, and the fixtures):
  aniposelib's ``bundle_adjust_iter`` (:mod:`mirrorgraph.baselines.anipose`) on the
  same data and from the same start as the refinement: the pairs the
  initialisation kept for it and its virtual camera; needs the bench extra, else
  reported as not run.

An outcome is ``ok``, ``refused`` (a clean :class:`mirrorgraph.DegenerateGeometryError`),
``crash`` (any other exception, or a non-finite result, or the process dying) or
``timeout`` (``--timeout`` s for the whole scene; the stages that finished are kept).

Metrics. Rotation error of the virtual camera: twice the angle between the estimated
and the true mirror normals (:func:`mirrorgraph.metrics.mirror_rotation_error_deg`;
for aniposelib, whose pose is not constrained to a reflection, the angle of
``R_est^T R_true`` as in ``compare.py``). It is divided by the scene's Cramer-Rao bound:
``bench/compare.py``'s ``cramer_rao`` (RMS rotation error bound of the reprojection
model, iid noise of the detector's 4 px, at the true plane and joints, outliers left
out; the fixtures' own ``truth.json`` bound, computed the same way). The realistic
noise is not iid: its bound is the iid bound at the same 4 px, which no estimator
reaches (a constant bias is not averaged out). Wall and CPU time of each call;
linear solves = the refinement's Levenberg-Marquardt iterations over all its stages
(``calibration.refinement["iterations"]``); memory = peak resident set of the
scene's process during the call (``VmHWM`` reset before it through
``/proc/self/clear_refs``), as the rise over the process's size before the call and
as the absolute peak. With ``--workers 2`` two scenes run at once on this 2-core
machine (shared with other users): wall times are contended, CPU times less so; run
``--workers 1`` for uncontended timings.

Geometry of every scene (:func:`mirrorgraph.synth.scene_geometry_stats`; for the
fixtures from their keypoints paired with the true mirror,
:func:`mirrorgraph.synth.geometry.pair_by_epipole`): median distance of the person's
joints from the epipole (px), median and 5th percentile of the angle between a
joint's two rays (from the real and from the virtual camera).

Writes ``RESULTS_stress.md`` (machine, command, date, tables) and
``RESULTS_stress.json`` (every scene's row, for ``--compare``) in ``--out``
(default ``bench/``; with ``--quick`` a temporary folder). Progress goes to stderr.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
           "NUMEXPR_NUM_THREADS", "VECLIB_MAXIMUM_THREADS"):
    os.environ.setdefault(_v, "1")
os.environ.setdefault("JAX_PLATFORMS", "cpu")

import argparse  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
import warnings  # noqa: E402
from collections import Counter  # noqa: E402
from concurrent.futures import ThreadPoolExecutor, as_completed  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

BENCH = Path(__file__).resolve().parent
ROOT = BENCH.parent
for _p in (ROOT, BENCH):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

from compare import _json_default, _status_kb  # noqa: E402  (bench/compare.py)

GEOMETRIES = ("favourable", "gym", "wide", "low_parallax")
NOISES = ("iid", "realistic")
FIXTURES = ROOT.parent / "shared" / "fixtures"
STAGES = ("init", "full", "full_noheight", "anipose")


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


# =========================================================================== one scene (child)
def _emit(rec: dict) -> None:
    print(json.dumps(rec, default=_json_default), flush=True)


def _reset_peak() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")                          # VmHWM := the current VmRSS
        return True
    except OSError:
        return False


def _timed(fn) -> dict:
    """Run ``fn()``, classify the outcome, time it and measure its peak memory."""
    import gc

    from mirrorgraph.errors import DegenerateGeometryError

    gc.collect()
    reset = _reset_peak()
    base = _status_kb("VmRSS")
    w0, c0 = time.perf_counter(), time.process_time()
    out = dict(status="ok")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out["value"] = fn()
    except DegenerateGeometryError as exc:
        out.update(status="refused", error=f"{type(exc).__name__}: {exc}"[:300])
    except Exception as exc:  # noqa: BLE001 - a crash is a result
        out.update(status="crash", error=f"{type(exc).__name__}: {exc}"[:300],
                   where=traceback.format_exc(limit=-3)[-600:])
        if isinstance(exc, ImportError) or type(exc).__name__ == "BenchDependencyError":
            out["status"] = "not_run"
    out["wall_s"] = time.perf_counter() - w0
    out["cpu_s"] = time.process_time() - c0
    peak = _status_kb("VmHWM")
    out["peak_mb"] = peak / 1024.0
    out["rise_mb"] = (peak - base) / 1024.0 if reset else None
    return out


def _load_case(case: dict):
    """``(raw detections, intrinsics, truth dict, paired-for-anipose, geometry stats, bound)``."""
    from mirrorgraph.synth import geometry as sgeo

    if case["kind"] == "fixture":
        import mirrorgraph as mg
        from mirrorgraph.io import read_keypoints
        folder = Path(case["path"])
        truth = json.loads((folder / "truth.json").read_text())
        intr = mg.load_intrinsics(folder / "camera.json")
        raw = read_keypoints(folder / "keypoints.json")
        n = np.asarray(truth["normal"], float)
        sk = raw.skeleton
        u, um = sgeo.pair_by_epipole(raw.people, intr.K, n, sk.flip, sk.calibration_joints)
        stats = sgeo.geometry_stats(intr.K, n, u, um)
        info = dict(normal=n, distance=float(truth["distance"]), height=float(truth["height"]),
                    K=intr.K, image_size=tuple(intr.image_size or raw.image_size))
        return raw, intr, info, (u, um), stats, float(truth["cramer_rao_rotation_std_deg_at_4px"])
    import compare
    from mirrorgraph.synth import make_wide_scene
    sc = make_wide_scene(case["seed"], case["geometry"], case["noise"], case["frames"])
    calib = np.zeros(sc.skeleton.num_joints, bool)
    calib[sc.skeleton.calibration_joints] = True
    crb = ~sc.missing_real & ~sc.missing_mirror & calib[None] \
        & ~sc.outlier_mask_real & ~sc.outlier_mask_mirror
    bound = compare.cramer_rao(sc.K, sc.normal, sc.distance, sc.joints3d[crb],
                               float(sc.options["noise_std"]))["rot_rms_deg"]
    stats = sgeo.scene_geometry_stats(sc)
    p = sc.placement
    stats.update(distance=sc.distance, angle_deg=float(np.degrees(np.arccos(sc.normal[2]))),
                 focal_px=p["focal_px"], person_to_mirror=p["person_to_mirror"],
                 camera_height=p["camera_height"], parallax_deg=p["parallax_deg"],
                 subject_height=sc.subject_height, attempts=p["attempts"],
                 noise_correlation=sc.options.get("noise_correlation"),
                 joint_bias_px=sc.options.get("joint_bias_px"))
    info = dict(normal=sc.normal, distance=sc.distance, height=sc.subject_height, K=sc.K,
                image_size=sc.image_size, virtual_R=sc.virtual_R)
    return sc.detections, sc.intrinsics, info, sc.paired(fix_lr=False), stats, bound


def run_scene(case: dict) -> None:
    """Run one scene's stages, printing one JSON line per stage (the parent reads them)."""
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            raw, intr, info, pairs, stats, bound = _load_case(case)
        except Exception as exc:  # noqa: BLE001 - a scene that cannot be made is a result
            _emit(dict(stage="scene", status="crash", error=f"{type(exc).__name__}: {exc}"[:300]))
            return
    _emit(dict(stage="scene", status="ok", geometry=stats, crb_deg=bound,
               build_s=time.perf_counter() - t0))
    import mirrorgraph as mg
    from mirrorgraph.metrics import mirror_rotation_error_deg, rotation_error_deg

    import tempfile
    from mirrorgraph.io import read_keypoints, write_keypoints

    n_true = info["normal"]
    tmp = tempfile.TemporaryDirectory(prefix="bench_stress_")
    if case["kind"] == "fixture":
        source = Path(case["path"]) / "keypoints.json"
    else:                                    # as a detector writes it (not timed)
        source = Path(tmp.name) / "keypoints.json"
        write_keypoints(raw, source, "mmpose")

    def end_to_end(opts):
        """The job as the CLI runs it: read the file, calibrate, write calibration.json."""
        run = mg.calibrate(read_keypoints(source), intr, opts)
        mg.write_calibration(Path(tmp.name) / "calibration.json", run.calibration)
        return run

    init_run = None
    for stage, refine, height in (("init", False, None), ("full", True, info["height"]),
                                  ("full_noheight", True, None)):
        opts = mg.CalibrateOptions(refine=refine, seed=0, subject_height=height)
        res = _timed(lambda: end_to_end(opts) if stage == "full" else mg.calibrate(raw, intr, opts))
        run = res.pop("value", None)
        if stage == "init":
            init_run = run
        elif run is not None:       # the refinement alone (from the initialisation)
            res["refine_s"] = sum(run.timings.get(k, 0.0) for k in ("build", "solve", "marginals"))
        if run is not None:
            c = run.calibration
            n = np.asarray(c.normal, float)
            if not np.all(np.isfinite(n)):
                res.update(status="crash", error="non-finite normal")
            else:
                res["rot_deg"] = mirror_rotation_error_deg(n, n_true)
                res["iterations"] = (c.refinement or {}).get("iterations") if refine else None
                res["rot_std_deg"] = (c.uncertainty or {}).get("rotation_std_deg")
                res["pairs_used"] = int(c.pairs_used)
                if c.distance is not None and info.get("distance"):
                    res["dist_err_pct"] = 100.0 * (c.distance - info["distance"]) / info["distance"]
        _emit(dict(stage=stage, **res))
    if case.get("with_anipose"):
        _emit(dict(stage="anipose", **_run_anipose(init_run, info, rotation_error_deg)))
    tmp.cleanup()


def _run_anipose(init_run, info, rotation_error_deg) -> dict:
    """aniposelib's bundle adjustment on the same data and from the same start as the
    refinement: the pairs the initialisation kept for it and its virtual camera."""
    from mirrorgraph import geometry as geo
    from mirrorgraph.baselines.anipose import AniposeOptions, calibrate_anipose
    if init_run is None:
        return dict(status="not_run", error="no initialisation to start from")
    try:
        import compare
        compare._warm_up(["anipose"])              # JIT compilation outside the timed call
    except Exception as exc:  # noqa: BLE001
        return dict(status="not_run", error=f"{type(exc).__name__}: {exc}"[:300])
    c = init_run.calibration
    p = init_run.paired
    start = geo.virtual_camera_from_mirror(c.normal, 0.5)
    opts = AniposeOptions(initial_pose=start, seed=0)
    res = _timed(lambda: calibrate_anipose(p.real, p.mirror, c.intrinsics.K, c.intrinsics.image_size
                                           or p.image_size, valid=init_run.candidates,
                                           joints=init_run.joints, options=opts))
    out = res.pop("value", None)
    if out is not None:
        res["bundle_adjust_s"] = out.timings.get("bundle_adjust")
    if out is not None:
        R = np.asarray(out.rotation, float)
        if not np.all(np.isfinite(R)):
            res.update(status="crash", error="non-finite rotation")
        else:
            R_true = info.get("virtual_R")
            if R_true is None:
                R_true = geo.virtual_camera_from_mirror(info["normal"], 1.0)[0]
            res["rot_deg"] = rotation_error_deg(R, R_true)
    return res


# =========================================================================== parent
def plan(scenes: int, frames: int, geometries, noises, anipose_every: int, fixtures: Path | None
         ) -> tuple[list[dict], list[str]]:
    """The cases to run and notes about what is left out."""
    slices = [(g, n) for g in geometries for n in noises]
    per = -(-scenes // len(slices)) if slices else 0
    cases = []
    for g, n in slices:
        for s in range(per):
            cases.append(dict(kind="synthetic", key=f"{g}/{n}/{s}", slice=f"{g}/{n}",
                              geometry=g, noise=n, seed=s, frames=frames,
                              with_anipose=anipose_every > 0 and s % anipose_every == 0))
    notes = []
    if fixtures is None:
        notes.append("fixtures left out (--no-fixtures)")
    elif not fixtures.is_dir():
        notes.append(f"fixtures folder {fixtures} absent: the independent scenes were skipped")
    else:
        found = sorted(p for p in fixtures.iterdir()
                       if (p / "keypoints.json").is_file() and (p / "truth.json").is_file())
        if not found:
            notes.append(f"no fixture (keypoints.json + truth.json) in {fixtures}")
        for p in found:
            cases.append(dict(kind="fixture", key=f"fixtures/{p.name}", slice="fixtures",
                              path=str(p), with_anipose=anipose_every > 0))
    return cases, notes


def run_child(case: dict, timeout: float) -> dict:
    """Run one case in a fresh process; its stage records, whatever became of it."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--_scene", json.dumps(case)]
    t0 = time.perf_counter()
    timed_out, rc, err = False, None, ""
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        out, rc, err = p.stdout, p.returncode, p.stderr
    except subprocess.TimeoutExpired as exc:
        timed_out = True
        out = exc.stdout.decode() if isinstance(exc.stdout, bytes) else (exc.stdout or "")
    row = dict(case, elapsed_s=time.perf_counter() - t0, returncode=rc)
    for line in out.splitlines():
        if line.startswith("{"):
            rec = json.loads(line)
            row[rec.pop("stage")] = rec
    wanted = ["scene", "init", "full", "full_noheight"] \
        + (["anipose"] if case.get("with_anipose") else [])
    if "scene" in row and row["scene"]["status"] != "ok":
        wanted = ["scene"]
    first = True
    for stage in wanted:
        if stage in row:
            continue
        if first:            # the stage that was running when the process ended
            why = (f"timeout after {timeout:g} s" if timed_out else
                   f"process died (exit status {rc}): {err.strip()[-300:]}")
            row[stage] = dict(status="timeout" if timed_out else "crash", error=why)
            first = False
        else:
            row[stage] = dict(status="skipped", error="not reached")
    return row


def execute(cases: list[dict], workers: int, timeout: float) -> list[dict]:
    """Every case in its own process, ``workers`` at a time; rows in the order of ``cases``."""
    rows = {}
    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        futures = {pool.submit(run_child, c, timeout): i for i, c in enumerate(cases)}
        for k, fut in enumerate(as_completed(futures), 1):
            row = rows[futures[fut]] = fut.result()
            el = time.perf_counter() - t0
            parts = []
            for st in STAGES:
                r = row.get(st)
                if r is None:
                    continue
                parts.append(f"{st}=" + (f"{r['rot_deg']:.3f}deg/{r.get('wall_s', 0):.1f}s"
                                         if r["status"] == "ok" and "rot_deg" in r
                                         else r["status"].upper()))
            sc = row.get("scene", {})
            g = sc.get("geometry", {})
            log(f"[{k}/{len(cases)} {el / 60:5.1f} min, eta "
                f"{el / k * (len(cases) - k) / 60:5.1f}] {row['key']}: "
                f"epi {g.get('epipole_px', float('nan')):.0f}px ray "
                f"{g.get('ray_deg_median', float('nan')):.0f}deg crb "
                f"{sc.get('crb_deg', float('nan')):.3f}: " + " ".join(parts))
    return [rows[i] for i in range(len(cases))]


# =========================================================================== summary
def _pct(v, q):
    v = np.asarray([x for x in v if x is not None and np.isfinite(x)], float)
    return float(np.percentile(v, q)) if len(v) else float("nan")


def _f(x, nd=2):
    return "–" if x is None or not np.isfinite(x) else f"{x:.{nd}f}"


def _ratio(row, stage):
    r, c = row.get(stage, {}), row.get("scene", {}).get("crb_deg")
    if r.get("status") != "ok" or "rot_deg" not in r or not c:
        return None
    return r["rot_deg"] / c


def _slices(rows):
    order = []
    for r in rows:
        if r["slice"] not in order:
            order.append(r["slice"])
    return [(s, [r for r in rows if r["slice"] == s]) for s in order]


def _groups(rows):
    """The slices, then every synthetic scene of a noise model, then every scene."""
    out = _slices(rows)
    for noise in NOISES:
        rs = [r for r in rows if r.get("noise") == noise]
        if rs:
            out.append((f"**all {noise}**", rs))
    out.append(("**all**", list(rows)))
    return out


def _count(rs, stage, status):
    return sum(1 for r in rs if r.get(stage, {}).get("status") == status)


def table_geometry(rows) -> list[str]:
    L = ["| slice | scenes | person-epipole px: median [p10, p90] | ray angle median deg "
         "[p10, p90] | ray angle 5th pct deg [p10, p90] | CRB deg median [p10, p90] | "
         "mirror m | angle deg | focal px | person-mirror m |",
         "|:---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]

    def rng3(vals, nd):
        return f"{_f(_pct(vals, 50), nd)} [{_f(_pct(vals, 10), nd)}, {_f(_pct(vals, 90), nd)}]"

    def span(vals, nd):
        v = [x for x in vals if x is not None]
        return f"{min(v):.{nd}f}-{max(v):.{nd}f}" if v else "–"

    for name, rs in _slices(rows):
        gs = [r["scene"]["geometry"] for r in rs if r.get("scene", {}).get("status") == "ok"]
        cr = [r["scene"].get("crb_deg") for r in rs if r.get("scene", {}).get("status") == "ok"]
        if not gs:
            L.append(f"| {name} | 0 | – | – | – | – | – | – | – | – |")
            continue
        L.append(f"| {name} | {len(gs)} | {rng3([g['epipole_px'] for g in gs], 0)} "
                 f"| {rng3([g['ray_deg_median'] for g in gs], 1)} "
                 f"| {rng3([g['ray_deg_p5'] for g in gs], 1)} | {rng3(cr, 3)} "
                 f"| {span([g.get('distance') for g in gs], 1)} "
                 f"| {span([g.get('angle_deg') for g in gs], 0)} "
                 f"| {span([g.get('focal_px') for g in gs], 0)} "
                 f"| {span([g.get('person_to_mirror') for g in gs], 1)} |")
    return L


def table_robustness(rows) -> list[str]:
    L = ["| slice | scenes | crash / refused / timeout: init, full, full no height "
         "| init err / CRB median, p90 | full err / CRB median, p90 | no height err / CRB "
         "median, p90 | full err deg median | full within 2x CRB | full metric distance error "
         "%, median abs, p90 abs |",
         "|:---|---:|---:|---:|---:|---:|---:|---:|---:|"]

    def crt(rs, st):
        return " / ".join(str(_count(rs, st, k)) for k in ("crash", "refused", "timeout"))

    def med90(rs, st):
        v = [_ratio(r, st) for r in rs]
        return f"{_f(_pct(v, 50))}, {_f(_pct(v, 90))}"

    for name, rs in _groups(rows):
        ok = [x for x in (_ratio(r, "full") for r in rs) if x is not None]
        errs = [r["full"]["rot_deg"] for r in rs if r.get("full", {}).get("status") == "ok"
                and "rot_deg" in r["full"]]
        dist = [abs(r["full"]["dist_err_pct"]) for r in rs if "dist_err_pct" in r.get("full", {})]
        L.append(f"| {name} | {len(rs)} | {crt(rs, 'init')}; {crt(rs, 'full')}; "
                 f"{crt(rs, 'full_noheight')} | {med90(rs, 'init')} | {med90(rs, 'full')} "
                 f"| {med90(rs, 'full_noheight')} | {_f(_pct(errs, 50), 3)} "
                 f"| {sum(x <= 2.0 for x in ok)}/{len(rs)} "
                 f"| {_f(_pct(dist, 50), 2)}, {_f(_pct(dist, 90), 2)} |")
    return L


def table_paired(rows) -> list[str]:
    """The graph against its own initialisation, scene by scene (the same start, the same
    detections): a median over 25 scenes moves by chance, a paired test says whether it did."""
    from scipy.stats import wilcoxon
    L = ["| slice | scenes | full better / worse than init | full err / init err median "
         "| RMS err / CRB init -> full | Wilcoxon signed-rank p (full vs init) |",
         "|:---|---:|---:|---:|---:|---:|"]
    for name, rs in _groups(rows):
        pr = [(_ratio(r, "init"), _ratio(r, "full")) for r in rs]
        pr = np.array([p for p in pr if p[0] is not None and p[1] is not None], dtype=float)
        if len(pr) == 0:
            continue
        i, f = pr[:, 0], pr[:, 1]
        p = wilcoxon(f, i).pvalue if len(pr) >= 6 and np.any(f != i) else float("nan")
        L.append(f"| {name} | {len(pr)} | {int((f < i).sum())} / {int((f > i).sum())} "
                 f"| {_f(float(np.median(f / i)))} "
                 f"| {_f(float(np.sqrt(np.mean(i ** 2))))} -> {_f(float(np.sqrt(np.mean(f ** 2))))} "
                 f"| {'–' if not np.isfinite(p) else f'{p:.3f}'} |")
    return L


def table_cost(rows) -> list[str]:
    L = ["| slice | init wall s median | full end to end wall s median, p95 | full CPU s "
         "median, p95 "
         "| linear solves median, p90, max | full peak rise MB median, max "
         "| full peak RSS MB max |",
         "|:---|---:|---:|---:|---:|---:|---:|"]
    for name, rs in _groups(rows):
        done = [r["full"] for r in rs if r.get("full", {}).get("status") in ("ok", "crash",
                                                                                "refused")
                and "wall_s" in r["full"]]
        ini = [r["init"]["wall_s"] for r in rs if "wall_s" in r.get("init", {})]
        it = [d.get("iterations") for d in done if d.get("iterations") is not None]
        L.append(f"| {name} | {_f(_pct(ini, 50))} "
                 f"| {_f(_pct([d['wall_s'] for d in done], 50))}, "
                 f"{_f(_pct([d['wall_s'] for d in done], 95))} "
                 f"| {_f(_pct([d['cpu_s'] for d in done], 50))}, "
                 f"{_f(_pct([d['cpu_s'] for d in done], 95))} "
                 f"| {_f(_pct(it, 50), 0)}, {_f(_pct(it, 90), 0)}, "
                 f"{max(it) if it else '–'} "
                 f"| {_f(_pct([d.get('rise_mb') for d in done], 50), 0)}, "
                 f"{_f(_pct([d.get('rise_mb') for d in done], 100), 0)} "
                 f"| {_f(_pct([d.get('peak_mb') for d in done], 100), 0)} |")
    return L


def table_anipose(rows) -> list[str]:
    L = ["| slice | scenes | aniposelib ok / crash / refused / not run | aniposelib err / CRB "
         "median, p90 | mirrorgraph full err / CRB median, p90 (same scenes) | aniposelib "
         "bundle adjustment s median | mirrorgraph refinement s median (same scenes) |",
         "|:---|---:|---:|---:|---:|---:|---:|"]
    for name, rs in _groups(rows):
        rs = [r for r in rs if "anipose" in r]
        if not rs:
            continue
        a = [_ratio(r, "anipose") for r in rs]
        m = [_ratio(r, "full") for r in rs]
        L.append(f"| {name} | {len(rs)} | {_count(rs, 'anipose', 'ok')} / "
                 f"{_count(rs, 'anipose', 'crash')} / {_count(rs, 'anipose', 'refused')} / "
                 f"{_count(rs, 'anipose', 'not_run')} "
                 f"| {_f(_pct(a, 50))}, {_f(_pct(a, 90))} | {_f(_pct(m, 50))}, {_f(_pct(m, 90))} "
                 f"| {_f(_pct([r['anipose'].get('bundle_adjust_s') for r in rs], 50))} "
                 f"| {_f(_pct([r['full'].get('refine_s') for r in rs], 50))} |")
    return L


def table_fixtures(rows) -> list[str]:
    fx = [r for r in rows if r["kind"] == "fixture"]
    if not fx:
        return []
    L = ["| fixture | epipole px | ray median / 5th pct deg | CRB deg | init | full | "
         "full, no height | aniposelib |", "|:---|---:|---:|---:|:---|:---|:---|:---|"]

    def cell(r, st):
        s = r.get(st)
        if s is None:
            return "–"
        if s["status"] == "ok" and "rot_deg" in s:
            c = r["scene"]["crb_deg"]
            return f"{s['rot_deg']:.4f} deg = {s['rot_deg'] / c:.2f}x CRB, {s['wall_s']:.1f} s"
        return f"**{s['status']}**: {_md(s.get('error', ''))[:90]}"

    for r in fx:
        g = r.get("scene", {}).get("geometry", {})
        L.append(f"| {r['key']} | {_f(g.get('epipole_px'), 0)} | {_f(g.get('ray_deg_median'), 1)} "
                 f"/ {_f(g.get('ray_deg_p5'), 1)} | {_f(r.get('scene', {}).get('crb_deg'), 4)} "
                 f"| {cell(r, 'init')} | {cell(r, 'full')} | {cell(r, 'full_noheight')} "
                 f"| {cell(r, 'anipose')} |")
    return L


def table_errors(rows) -> list[str]:
    c = Counter()
    where = {}
    for r in rows:
        for st in STAGES:
            s = r.get(st, {})
            if s.get("status") in ("crash", "timeout"):
                msg = s.get("error", "")
                key = (st, msg.split(":")[0] if s["status"] == "crash" else "timeout",
                       _shorten(msg))
                c[key] += 1
                where.setdefault(key, []).append(r["key"])
    if not c:
        return ["No crash and no timeout."]
    L = ["| stage | kind | count | message (first scene's) | scenes |",
         "|:---|:---|---:|:---|:---|"]
    for (st, kind, msg), k in c.most_common():
        keys = where[(st, kind, msg)]
        L.append(f"| {st} | {kind} | {k} | {msg} | {', '.join(keys[:6])}"
                 f"{' ...' if len(keys) > 6 else ''} |")
    return L


def _md(msg: str) -> str:
    """``msg`` on one line, safe in a markdown table cell."""
    return " ".join(msg.replace("|", "/").split())


def _shorten(msg: str) -> str:
    """``msg`` with its numbers masked (messages that differ only in numbers group)."""
    import re
    return re.sub(r"\d+(\.\d+)?", "#", _md(msg))[:140]


def table_compare(rows, old_rows) -> list[str]:
    old = {r["key"]: r for r in old_rows}
    L = ["| slice | scenes in both | full crash+timeout before -> after | no-height crash+"
         "timeout before -> after | init crash before -> after | full err / CRB median before "
         "-> after | full CPU s median before -> after | scenes better / worse (full err) |",
         "|:---|---:|---:|---:|---:|---:|---:|---:|"]
    for name, rs in _slices(rows):
        pairs = [(old[r["key"]], r) for r in rs
                 if r["key"] in old and old[r["key"]].get("frames") == r.get("frames")]
        if not pairs:
            continue
        bad = lambda rr, st: sum(1 for x in rr if x.get(st, {}).get("status") in  # noqa: E731
                                 ("crash", "timeout"))
        b = [p[0] for p in pairs]
        a = [p[1] for p in pairs]
        better = worse = 0
        for o, nw in pairs:
            eo, en = _ratio(o, "full"), _ratio(nw, "full")
            if eo is not None and en is not None:
                better += en < 0.9 * eo
                worse += en > 1.1 * eo
        L.append(f"| {name} | {len(pairs)} | {bad(b, 'full')} -> {bad(a, 'full')} "
                 f"| {bad(b, 'full_noheight')} -> {bad(a, 'full_noheight')} "
                 f"| {bad(b, 'init')} -> {bad(a, 'init')} "
                 f"| {_f(_pct([_ratio(x, 'full') for x in b], 50))} -> "
                 f"{_f(_pct([_ratio(x, 'full') for x in a], 50))} "
                 f"| {_f(_pct([x.get('full', {}).get('cpu_s') for x in b], 50))} -> "
                 f"{_f(_pct([x.get('full', {}).get('cpu_s') for x in a], 50))} "
                 f"| {better} / {worse} |")
    return L


from _report import header, machine, now  # noqa: E402  (one header for every results file)


#: Where the solver lives: the files whose changes a stress run measures.
SOLVER = ("mirrorgraph/graph/", "mirrorgraph/rigs/", "mirrorgraph/factors/",
          "mirrorgraph/pipelines/", "mirrorgraph/initial/", "mirrorgraph/completion.py",
          "mirrorgraph/geometry.py")


def tree_state() -> str:
    """The commit and the uncommitted changes of the tree measured (solver files named)."""
    def git(*a):
        return subprocess.run(["git", *a], cwd=ROOT, capture_output=True, text=True).stdout
    head = git("rev-parse", "--short", "HEAD").strip()
    if not head:
        return f"{ROOT} (not a git checkout)"
    changed = [ln[3:] for ln in git("status", "--porcelain").splitlines()
               if ln[3:].startswith("mirrorgraph/")]
    solver = [c for c in changed if c.startswith(SOLVER)]
    if not changed:
        return f"commit {head} (clean)"
    return (f"commit {head} with uncommitted changes in {len(changed)} file(s) of mirrorgraph/"
            + (f", in the solver: {', '.join(solver)}" if solver else ", none in the solver"))


def report(data: dict, old: dict | None) -> str:
    meta, rows = data["meta"], data["rows"]
    L = ["# Stress benchmark (`bench/bench_stress.py`)", "",
         *header(started=f"{meta['date']} ({meta['elapsed_min']:.1f} min)", cmd=meta["command"],
                 machine_line=meta["machine"]),
         f"* solver: {meta['tree']}",
         f"* scenes: {meta['per_slice']} per slice x {meta['frames']} frames (COCO-17, "
         "1920x1080), `make_wide_scene(seed, geometry, noise, frames)`, seeds 0.."
         f"{meta['per_slice'] - 1}; the fixtures as they are (1000 frames). "
         f"{meta['workers']} scene(s) at a time, each in a fresh process"
         + (" (**wall times contended**: two processes on the 2 shared cores; CPU times are "
            "the steadier figure)" if meta["workers"] > 1 else " (serial timings)") + "; "
         f"timeout {meta['timeout']:g} s a scene.",
         "* outcomes: *crash* = any exception other than a clean `DegenerateGeometryError` "
         "(*refused*), a non-finite result or a dead process; err / CRB = rotation error of "
         "the virtual camera (2x the normal's angle) over the scene's Cramer-Rao bound "
         "(`compare.cramer_rao`: iid 4 px, reprojection only), over the scenes that "
         "returned; *init* = `CalibrateOptions(refine=False)`, *full* = the factor graph "
         "with the true subject height, *no height* = the factor graph without it (the CLI's "
         "default).", ""]
    L += [f"* note: {n}" for n in meta.get("notes", [])]
    L += ["", "## Geometry of the slices", "",
          "Per scene: the median distance of the person's calibration joints from the epipole "
          "and the median and 5th percentile of the angle between each joint's two rays "
          "(`mirrorgraph.synth.geometry`); per slice, the median over its scenes and the "
          "10th-90th percentile band.", ""] + table_geometry(rows)
    L += ["", "## Robustness and accuracy", ""] + table_robustness(rows)
    L += ["", "### The graph against its initialisation, paired", "",
          "Per scene, the full graph's err / CRB beside the initialisation's on the same "
          "detections; *better / worse* count the scenes, the p-value is the two-sided "
          "Wilcoxon signed-rank test of the two columns (a small p: the difference is not "
          "chance).", ""] + table_paired(rows)
    L += ["", "## Cost", "",
          "*init*: wall time of the `calibrate` call on the detections in memory. *full*: the "
          "job end to end as the CLI runs it, from the keypoint file (MMPose JSON, written "
          "untimed for a synthetic scene) to `calibration.json` (reading, pairing, RANSAC, "
          "the graph, the joints pass, the marginals, writing); linear solves = "
          "`refinement['iterations']`; peak rise = VmHWM during the call above the process's "
          "resident size before it. **all** rows: every scene of the run.", ""]
    L += table_cost(rows)
    an = table_anipose(rows)
    if len(an) > 2:
        L += ["", "## aniposelib bundle adjustment on a subsample", "",
              f"Every {meta['anipose_every']}th scene of a slice and the fixtures: "
              "aniposelib's `bundle_adjust_iter` (`mirrorgraph.baselines.anipose`: its defaults, "
              "known intrinsics) on the same data and from the same start as mirrorgraph's "
              "refinement: the pairs the initialisation kept for it (`CalibrationRun.candidates`) "
              "and the initialisation's virtual camera. Rotation error of its virtual camera "
              "(`R_est^T R_true`: not constrained to a reflection) over the same bound; times "
              "without reading on either side: aniposelib's `bundle_adjust_iter` call, "
              "mirrorgraph's graph (build, solve, marginals).", ""] + an
    fx = table_fixtures(rows)
    if fx:
        L += ["", "## The independent fixtures", ""] + fx
    L += ["", "## Crashes and timeouts", ""] + table_errors(rows)
    if old is not None:
        L += ["", f"## Against `{meta.get('compare_to')}` (the same scenes: key and frames)", "",
              f"Before: {old['meta'].get('date')}, {old['meta'].get('tree')}.", ""] \
            + table_compare(rows, old["rows"])
    return "\n".join(L) + "\n"


# =========================================================================== main
def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenes", type=int, default=None,
                    help="random scenes in all, split evenly over the slices (default 200; "
                         "24 with --quick)")
    ap.add_argument("--frames", type=int, default=None, help="frames a scene (default 1000; "
                    "300 with --quick)")
    ap.add_argument("--quick", action="store_true", help="smoke run: 24 scenes of 300 frames, "
                    "written to a temporary folder unless --out is given")
    ap.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1),
                    help="scenes at once, each its own process (default 2; 1 for "
                         "uncontended timings)")
    ap.add_argument("--slices", default=",".join(GEOMETRIES),
                    help=f"comma-separated geometries of {','.join(GEOMETRIES)}")
    ap.add_argument("--noise", default=",".join(NOISES),
                    help=f"comma-separated noise models of {','.join(NOISES)}")
    ap.add_argument("--anipose-every", type=int, default=4,
                    help="run aniposelib on every k-th scene of a slice and on the fixtures "
                         "(default 4; 0: never)")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds a scene (default 600)")
    ap.add_argument("--fixtures", type=Path, default=FIXTURES,
                    help=f"folder of independent scenes (default {FIXTURES})")
    ap.add_argument("--no-fixtures", action="store_true")
    ap.add_argument("--out", type=Path, default=None,
                    help="output folder (default bench/; a temporary folder with --quick)")
    ap.add_argument("--compare", type=Path, default=None, metavar="OLD.json",
                    help="a previous RESULTS_stress.json: adds a before/after table")
    ap.add_argument("--replot", type=Path, default=None, metavar="RESULTS.json",
                    help="only rewrite RESULTS_stress.md (in --out) from a run's JSON")
    ap.add_argument("--label", default=None,
                    help="what solver this run measures, for the report (default: the git "
                         "state of the tree)")
    ap.add_argument("--_scene", default=None, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a._scene:
        run_scene(json.loads(a._scene))
        return 0

    geometries = [s.strip() for s in a.slices.split(",") if s.strip()]
    noises = [s.strip() for s in a.noise.split(",") if s.strip()]
    bad = [s for s in geometries if s not in GEOMETRIES] + [s for s in noises if s not in NOISES]
    if bad:
        ap.error(f"unknown slice(s) or noise model(s): {', '.join(bad)}")
    scenes = a.scenes if a.scenes is not None else (24 if a.quick else 200)
    frames = a.frames or (300 if a.quick else 1000)
    out = a.out or (Path(tempfile.mkdtemp(prefix="mirrorgraph-stress-")) if a.quick else BENCH)
    out.mkdir(parents=True, exist_ok=True)
    old = json.loads(a.compare.read_text()) if a.compare else None
    if a.replot:
        data = json.loads(a.replot.read_text())
        if a.compare:
            data["meta"]["compare_to"] = str(a.compare)
        (out / "RESULTS_stress.md").write_text(report(data, old))
        log(f"wrote {out / 'RESULTS_stress.md'} from {a.replot}")
        return 0
    cases, notes = plan(scenes, frames, geometries, noises, a.anipose_every,
                        None if a.no_fixtures else a.fixtures)
    per = -(-scenes // max(1, len(geometries) * len(noises)))
    command = "python bench/bench_stress.py " + " ".join(sys.argv[1:] if argv is None else argv)
    log(f"{len(cases)} scenes ({per} per slice x {len(geometries) * len(noises)} slices"
        f"{' + fixtures' if any(c['kind'] == 'fixture' for c in cases) else ''}), {frames} "
        f"frames, {a.workers} worker(s); output in {out}")
    for n in notes:
        log(f"note: {n}")
    t0 = time.perf_counter()
    rows = execute(cases, a.workers, a.timeout)
    meta = dict(date=now(),
                elapsed_min=(time.perf_counter() - t0) / 60.0, machine=machine(),
                command=command.strip(), tree=a.label or tree_state(), per_slice=per,
                frames=frames,
                workers=a.workers, timeout=a.timeout, anipose_every=a.anipose_every,
                notes=notes, compare_to=str(a.compare) if a.compare else None)
    data = dict(meta=meta, rows=rows)
    (out / "RESULTS_stress.json").write_text(json.dumps(data, indent=1, default=_json_default))
    text = report(data, old)
    (out / "RESULTS_stress.md").write_text(text)
    print(text)
    log(f"wrote {out / 'RESULTS_stress.md'} and {out / 'RESULTS_stress.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
