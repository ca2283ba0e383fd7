"""The live run's metric scale window by window, against the truth (``bench/bench_joints.py``'s scenes).

Each scene (``make_wide_scene(seed, 'wide', noise, frames)``, the camera matrix and the
subject's height as a user reports it: :func:`bench_joints.make_truth`) is replayed
through :class:`mirrorgraph.live.LiveCalibrator` (windows solved in the calling thread)
and, for every window the live run solved:

* the window: its frames, its size, what the fusion did with it, its distance's error
  against the true distance, its stature's sampling std and measured spread
  (``scale_sampling``, ``scale_side``: :class:`mirrorgraph.live.estimator.WindowEstimate`);
* the fused distance's error after it, and the live metric scale's relative std
  (:attr:`mirrorgraph.live.LiveMirror.scale_rel_std`);
* the output joints of the frames it served (the frames until the next window): their
  scale's error (each frame's least-squares factor about the camera, truth ~ f X: the
  median over the frames of ``1 / f - 1``, and its 10th and 90th percentiles), the share
  of joints more than 0.3 m off, and the same with each frame's scale taken out;
* the parts of that scale: the same frames' keypoints (in the true labels, outliers
  kept) triangulated from their two rays with the mirror the frame had, before any
  prior, filter or lag (``two rays``), and the height the window's bone lengths make
  (Winter's fractions: what the per-frame prior holds) against the height given, and
  the scale's std from the first block's restarts after it
  (:attr:`mirrorgraph.live.estimator.MirrorFusion.scale_step_std`).

Per window against its stated std: each output frame's scale error over the
``scale_rel_std`` it came out with (``z``), the window's own distance error over its total
std, the range of the served joints (a joint at ``|X|`` m is beyond 0.3 m once the scale is
off by ``0.3 / |X|``), the share of them a normal scale error of the stated std would put
beyond 0.3 m, and the window's data bound: its own frames' keypoints triangulated with the
TRUE mirror (the planted outliers out), their stature made the height given, the scale
error left (the stature measured on those frames' keypoints with a perfect mirror) and the
joints it puts beyond 0.3 m; the same by kind and window size (RMS z), and every output joint by its frame's
``|z|`` (beyond 0.3 m, and still after the frame's own scale).

Per scene, the joints' scale against the mirror: the output's, the final mirror's
distance error, the frames' own mirrors' distance errors (mean over the frames) and the
two rays' scale (means over the frames).

Per scene: the stature measured on the detector's keypoints triangulated with the TRUE
mirror (two rays a joint, :func:`mirrorgraph.live.frame_prior.triangulate_two_rays`,
outliers kept): what the observations themselves say about the height, without any
calibration's error; and, with ``--offline``, ``mirrorgraph.calibrate`` on every frame
(its joints' scale error, its distance's error).

Writes ``--out`` (default ``bench/RESULTS_live_scale.md``) unless ``--no-write``.

Run:  python bench/bench_live_scale.py                     # realistic 0-1, iid 0, ~2 min
      python bench/bench_live_scale.py --scenes realistic:0-3,iid:0-3 --offline
      python bench/bench_live_scale.py --window-frames 150   # several fused windows
      python bench/bench_live_scale.py --scenes iid:0-5+13,realistic:0-9+13,cmu:0-3+8,lowpar:0-6,fixtures:scene_900+scene_901 --fixtures /work/shared/fixtures --out bench/RESULTS_live_scale_z.md
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _report  # noqa: E402
import bench_joints as bj  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FPS = 30.0


def _frame_scale(X: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """``(T,)`` each frame's scale error ``1 / f - 1``, ``f`` its least-squares factor
    about the camera (truth ~ f X); NaN without joints."""
    given = np.isfinite(X).all(-1)
    Xz = np.where(given[..., None], X, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        f = (Xz * truth).sum((1, 2)) / (Xz * Xz).sum((1, 2))
        return 1.0 / f - 1.0


def run_scene(case: tuple) -> dict:
    import warnings
    warnings.filterwarnings("ignore")
    import mirrorgraph.live.calibrator as lc
    from mirrorgraph.live import LiveCalibrator, LiveOptions
    from mirrorgraph.anthropometry import height_from_bone_lengths
    from mirrorgraph.live.frame_prior import triangulate_two_rays
    from mirrorgraph.stature import estimate_stature

    kind, seed, frames, offline, window, fixtures = case
    tr = bj.make_truth(kind, seed, frames, Path(fixtures), "population", "reported")
    T, J = tr.joints3d.shape[:2]
    out = dict(name=tr.name, distance=tr.distance, height=tr.height,
               height_err=tr.height_given / tr.height - 1.0)
    # what the keypoints say about the height: triangulated with the true mirror
    u, um = tr.real.reshape(-1, 2), tr.mirror.reshape(-1, 2)
    Xo = triangulate_two_rays(tr.intrinsics.K, tr.normal, tr.distance, u, um).reshape(T, J, 3)
    st = estimate_stature(Xo, np.isfinite(Xo).all(-1), tr.detections.skeleton)
    out["true_mirror_stature_err"] = None if st is None else st.height / tr.height - 1.0
    windows = []
    solve = lc.solve_window

    def recorded(raw, intr, opts):
        est = solve(raw, intr, opts)
        windows.append(est)
        return est

    lc.solve_window = recorded
    extra = {} if window is None else dict(window_frames=window)
    live = LiveCalibrator(tr.detections.skeleton, tr.intrinsics,
                          LiveOptions.of(subject_height=tr.height_given, **extra))
    X = np.full((T, J, 3), np.nan)
    stated = np.full(T, np.nan)          # the scale_rel_std each output frame came with
    served = np.full(T, -1)
    mirror_d = np.full(T, np.nan)
    rays = np.full(T, np.nan)
    K = tr.intrinsics.K
    fused = {}
    where = {int(f): i for i, f in enumerate(tr.frame_ids)}
    truth_of = tr.joints3d
    det = tr.detections
    clock = time.perf_counter()
    try:
        for k, people in enumerate(det.people):
            fid = int(det.frame_ids[k])
            f = live.update(people, frame_id=fid, time_s=fid / FPS)
            t = where[fid]
            served[t] = len(windows) - 1
            if f.mirror.normal is not None and f.paired:
                mirror_d[t] = f.mirror.distance / tr.distance - 1.0
                Xr = triangulate_two_rays(K, f.mirror.normal, f.mirror.distance, tr.real[t],
                                          tr.mirror[t])
                rays[t] = _frame_scale(Xr[None], truth_of[t][None])[0]
            if windows and len(windows) - 1 not in fused:
                m = live.mirror
                fused[len(windows) - 1] = (m.distance, m.scale_rel_std,
                                           live.fusion.scale_step_std)
            if f.settled is not None:
                X[where[int(f.settled.frame_id)]] = f.settled.joints3d
                stated[where[int(f.settled.frame_id)]] = f.settled.mirror.scale_rel_std or np.nan
        live.finish()
        for f in live.flush():
            X[where[int(f.frame_id)]] = f.joints3d
            stated[where[int(f.frame_id)]] = f.mirror.scale_rel_std or np.nan
    finally:
        live.close()
        lc.solve_window = solve
    out["seconds"] = time.perf_counter() - clock
    truth = tr.joints3d
    s_err = _frame_scale(X, truth)
    e = np.linalg.norm(np.where(np.isfinite(X), X, 0.0) - truth, axis=-1)
    given = np.isfinite(X).all(-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        fit = 1.0 / (1.0 + s_err)
    es = np.linalg.norm(np.where(np.isfinite(X), X, 0.0) * np.nan_to_num(fit)[:, None, None]
                        - truth, axis=-1)
    # each output frame's scale error against the scale std it was given out with, and
    # the share of its joints a scale error as large as the stated std's draws would put
    # beyond 0.3 m (the scale alone: a joint at |X| m is gross once |err| > 0.3 / |X|)
    from scipy.stats import norm

    with np.errstate(invalid="ignore", divide="ignore"):
        z = s_err / stated
        r = np.linalg.norm(truth, axis=-1)
        expect = 2.0 * norm.sf(bj.GROSS_M / (r * stated[:, None]))
    zj = np.broadcast_to(np.abs(z)[:, None], e.shape)
    out["z_joints"] = {"n": int(given.sum()), "gross": int((given & (e > bj.GROSS_M)).sum()),
                       "expected": float(np.nansum(np.where(given, expect, 0.0)))}
    for lo, hi in ((0, 1), (1, 2), (2, 3), (3, np.inf)):
        b = given & (zj >= lo) & (zj < hi)
        out["z_joints"][f"{lo}-{hi}"] = (int(b.sum()), int((b & (e > bj.GROSS_M)).sum()),
                                         int((b & (es > bj.GROSS_M)).sum()))
    rows = []
    log = live.window_log
    fids = np.asarray(tr.frame_ids)
    inlier = np.isfinite(Xo).all(-1) & ~tr.out_real & ~tr.out_mirror   # the planted outliers out
    for i, w in enumerate(windows):
        sel = (served == i) & np.isfinite(s_err)
        g = given & sel[:, None]
        d_f, s_f, step = fused.get(i, (None, None, None))
        # the data's bound: the window's own frames triangulated with the TRUE mirror,
        # their stature made the height given (the scale error a perfect mirror leaves)
        span = (fids >= w.first_frame) & (fids <= w.last_frame)
        st_w = (estimate_stature(Xo[span], inlier[span], tr.detections.skeleton)
                if span.any() else None)
        bound = None if st_w is None else tr.height_given / st_w.height - 1.0
        with np.errstate(invalid="ignore"):
            gross_bound = (float((np.abs(bound) * r[g] > bj.GROSS_M).mean())
                           if bound is not None and g.any() else None)
        rows.append(dict(
            frames=f"{w.first_frame}-{w.last_frame}", size=int(log[i]["size"]) if i < len(log)
            else w.frames, result=log[i]["result"] if i < len(log) else "?",
            distance_err=(w.distance / tr.distance - 1.0) if w.ok else None,
            sampling=getattr(w, "scale_sampling", None), side=w.scale_side,
            fused_err=None if d_f is None else d_f / tr.distance - 1.0, fused_std=s_f,
            served=int(sel.sum()),
            scale_med=float(np.median(s_err[sel])) if sel.any() else None,
            scale_p10=float(np.percentile(s_err[sel], 10)) if sel.any() else None,
            scale_p90=float(np.percentile(s_err[sel], 90)) if sel.any() else None,
            gross=float((e[g] > bj.GROSS_M).mean()) if g.any() else None,
            gross_scaled=float((es[g] > bj.GROSS_M).mean()) if g.any() else None,
            rays_med=float(np.nanmedian(rays[sel])) if sel.any() else None,
            step=None if step is None or not np.isfinite(step) else float(step),
            bound=bound, gross_bound=gross_bound,
            z_med=float(np.nanmedian(z[sel])) if sel.any() else None,
            stated_med=float(np.nanmedian(stated[sel])) if sel.any() else None,
            expected=(float(np.nanmean(expect[g])) if g.any() else None),
            gross_n=int((e[g] > bj.GROSS_M).sum()) if g.any() else 0,
            radius=float(np.median(r[g])) if g.any() else None,
            window_std=(float(np.sqrt((w.distance_std / w.distance) ** 2
                                      + live.fusion.height_sigma ** 2 + w.scale_side ** 2
                                      + np.nan_to_num(w.scale_sampling) ** 2))
                        if w.ok else None),
            bones_height_err=(height_from_bone_lengths(w.bone_lengths, tr.detections.skeleton)
                              / tr.height_given - 1.0) if w.ok and w.bone_lengths else None))
    out["windows"] = rows
    final = live.mirror
    out["final_distance_err"] = final.distance / tr.distance - 1.0
    out["served_distance_err"] = float(np.nanmean(mirror_d))
    out["rays_scale_err"] = float(np.nanmean(rays))
    out["scale_err_mean"] = float(np.nanmean(s_err))
    ok = np.isfinite(s_err)
    out["scale_err"] = float(np.median(s_err[ok])) if ok.any() else None
    out["gross"] = float((e[given] > bj.GROSS_M).mean()) if given.any() else None
    out["gross_scaled"] = float((es[given] > bj.GROSS_M).mean()) if given.any() else None
    if offline:
        import mirrorgraph as mg

        run = mg.calibrate(tr.detections, tr.intrinsics,
                           mg.CalibrateOptions(subject_height=tr.height_given, fps=FPS))
        rows_of = np.array([where[int(f)] for f in run.paired.frame_ids])
        Xc = np.where(run.valid3d[..., None], run.joints3d, np.nan)
        sc = _frame_scale(Xc, truth[rows_of])
        out["offline_scale_err"] = float(np.nanmedian(sc))
        out["offline_distance_err"] = float(run.calibration.distance / tr.distance - 1.0)
    return out


def _pct(v, spec="+.2f") -> str:
    return "-" if v is None else format(100.0 * v, spec)


def _num(v, spec="+.2f") -> str:
    return "-" if v is None or not np.isfinite(v) else format(v, spec)


def _zrow(name: str, zj: dict) -> str:
    n = max(zj["n"], 1)
    bins = " | ".join("{} / {} / {}".format(*zj[k]) for k in ("0-1", "1-2", "2-3", "3-inf"))
    return (f"| {name} | {zj['n']} | {zj['gross']} ({100 * zj['gross'] / n:.2f} %) "
            f"| {zj['expected']:.0f} ({100 * zj['expected'] / n:.2f} %) | {bins} |")


def tables(scenes: list[dict]) -> list[str]:
    lines = ["## Per window", "",
             "`served`: the frames whose joints the window's mirror gave (until the next "
             "window); `output scale err`: the median over them of each frame's joints' "
             "scale error (p10 / p90); `> 0.3 m, frame's scale out`: after each frame's "
             "least-squares scale about the camera.", "",
             "| scene | window frames | size | result | window distance err % | sampling std % "
             "| spread % | fused distance err % | scale std % | served | output scale err % "
             "| p10 / p90 % | > 0.3 m % | > 0.3 m, frame's scale out % | two rays scale err % "
             "| bones' height err % | restart steps std % |",
             "|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|"]
    for s in scenes:
        for w in s["windows"]:
            lines.append(
                f"| {s['name']} | {w['frames']} | {w['size']} | {w['result']} "
                f"| {_pct(w['distance_err'])} | {_pct(w['sampling'], '.2f')} "
                f"| {_pct(w['side'], '.2f')} | {_pct(w['fused_err'])} "
                f"| {_pct(w['fused_std'], '.2f')} | {w['served']} | {_pct(w['scale_med'])} "
                f"| {_pct(w['scale_p10'], '+.1f')} / {_pct(w['scale_p90'], '+.1f')} "
                f"| {_pct(w['gross'], '.1f')} | {_pct(w['gross_scaled'], '.2f')} "
                f"| {_pct(w.get('rays_med'))} | {_pct(w.get('bones_height_err'))} "
                f"| {_pct(w.get('step'), '.2f')} |")
    lines += ["", "## The scale's error against its stated std, window by window", "",
              "`window z`: the window's own distance error over its total relative std "
              "(its data's, the height's prior, its stature's spread and sampling); "
              "`stated`: the median over the frames served of the scale_rel_std each came "
              "out with; `output z`: the median over them of each frame's scale error over "
              "its stated std; `true mirror's scale err`: the scale error the window's own "
              "frames leave with the TRUE mirror (their keypoints triangulated with it, two "
              "rays a joint, the planted outliers out, their stature made the height given: "
              "what the window's data allow), and `> 0.3 m at it` the share of the served joints that error puts "
              "beyond 0.3 m (the scale's share alone); `0.3 m at`: the scale error that puts a joint at the served "
              "joints' median range |X| beyond 0.3 m; `expected > 0.3 m`: the mean over the "
              "served joints of P(|scale error| > 0.3 m / |X|) for a normal scale error of "
              "the stated std (the scale's share alone); `gross`: joints beyond 0.3 m.", "",
              "| scene | window frames | size | result | window distance err % | window std % "
              "| window z | served | stated % | output scale err % | output z | range m "
              "| 0.3 m at % | > 0.3 m % | expected > 0.3 m % | gross | true mirror's scale err % "
              "| > 0.3 m at it % |",
              "|---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for s in scenes:
        for w in s["windows"]:
            wz = (None if w["distance_err"] is None or not w.get("window_std")
                  else w["distance_err"] / w["window_std"])
            rad = w.get("radius")
            lines.append(
                f"| {s['name']} | {w['frames']} | {w['size']} | {w['result']} "
                f"| {_pct(w['distance_err'])} | {_pct(w.get('window_std'), '.2f')} "
                f"| {_num(wz)} | {w['served']} | {_pct(w.get('stated_med'), '.2f')} "
                f"| {_pct(w['scale_med'])} | {_num(w.get('z_med'))} "
                f"| {'-' if rad is None else format(rad, '.1f')} "
                f"| {'-' if rad is None else format(100 * 0.3 / rad, '.1f')} "
                f"| {_pct(w['gross'], '.1f')} | {_pct(w.get('expected'), '.1f')} "
                f"| {w.get('gross_n', 0)} | {_pct(w.get('bound'))} "
                f"| {_pct(w.get('gross_bound'), '.1f')} |")
    lines += ["", "### By kind and window size", "",
              "Over the windows of each kind and size (first block: 60, 120, ... frames): "
              "`RMS z`, `max |z|`: the output z's; `output`, `true mirror`, `output - true "
              "mirror`: RMS of the output scale error, of the true mirror's (the window's "
              "data) and of their difference; `> 0.3 m`: the served joints beyond 0.3 m, "
              "live and at the true mirror's scale error (the scale's share alone).", "",
              "| kind | size | windows | RMS z | max abs z | output RMS % | true mirror RMS % "
              "| output - true mirror RMS % | > 0.3 m % | > 0.3 m at the true mirror's % |",
              "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    groups: dict = {}
    for s in scenes:
        for w in s["windows"]:
            if w.get("z_med") is None or w.get("bound") is None or not w["served"]:
                continue
            groups.setdefault((s["name"].split()[0], w["size"]), []).append(w)
    for (kind, size), ws in sorted(groups.items()):
        z = np.array([w["z_med"] for w in ws])
        o = np.array([w["scale_med"] for w in ws])
        b = np.array([w["bound"] for w in ws])
        n = np.array([w["served"] for w in ws], float)

        def rms(v):
            return float(np.sqrt(np.mean(v ** 2)))
        gl = float(np.sum(n * [w["gross"] or 0 for w in ws]) / n.sum())
        gb = float(np.sum(n * [w["gross_bound"] or 0 for w in ws]) / n.sum())
        lines.append(f"| {kind} | {size} | {len(ws)} | {rms(z):.2f} | {np.abs(z).max():.2f} "
                     f"| {100 * rms(o):.2f} | {100 * rms(b):.2f} | {100 * rms(o - b):.2f} "
                     f"| {100 * gl:.1f} | {100 * gb:.1f} |")
    lines += ["", "### Every output joint by its frame's |scale error| / stated std", "",
              "`> 0.3 m, scale out`: after each frame's least-squares scale; `expected`: the "
              "gross joints a normal scale error of the stated std gives (sum over the "
              "joints of P(|err| > 0.3 m / |X|)).", "",
              "| scene | joints | > 0.3 m | expected | |z| < 1: joints / > 0.3 m / scale out "
              "| 1-2 | 2-3 | >= 3 |", "|---|---:|---:|---:|---|---|---|---|"]
    tot = {}
    for s in scenes:
        zj = s["z_joints"]
        for k, v in zj.items():
            tot[k] = (tot.get(k, 0) + v if not isinstance(v, tuple)
                      else tuple(a + b for a, b in zip(tot.get(k, (0, 0, 0)), v)))
        lines.append(_zrow(s["name"], zj))
    if len(scenes) > 1:
        lines.append(_zrow("**all**", tot))
    lines += ["", "## Per scene", "",
              "`true-mirror stature err`: the stature measured on the keypoints triangulated "
              "with the TRUE mirror (two rays a joint, outliers kept) against the true height; "
              "`height given err`: the reported height's.", "",
              "| scene | true distance m | height given err % | true-mirror stature err % "
              "| live output scale err % | live > 0.3 m % | live > 0.3 m, frame's scale out % "
              "| offline scale err % | offline distance err % | live s |",
              "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for s in scenes:
        lines.append(
            f"| {s['name']} | {s['distance']:.2f} | {_pct(s['height_err'])} "
            f"| {_pct(s['true_mirror_stature_err'])} | {_pct(s['scale_err'])} "
            f"| {_pct(s['gross'], '.2f')} | {_pct(s['gross_scaled'], '.2f')} "
            f"| {_pct(s.get('offline_scale_err'))} | {_pct(s.get('offline_distance_err'))} "
            f"| {s['seconds']:.0f} |")
    lines += ["", "## The joints' scale against the mirror", "",
              "Means over the frames. `output`: the live joints' scale error; `final "
              "distance`: the last mirror's distance error; `frames' distance`: each "
              "frame's own mirror's distance error; `two rays`: each frame's keypoints "
              "triangulated with its own mirror before any prior. output - final distance = (frames' distance - "
              "final distance) + (two rays - frames' distance) + (output - two rays).", "",
              "| scene | output % | final distance % | frames' distance % | two rays % "
              "| windows' part | rays' part | per-frame path's part |",
              "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for s in scenes:
        o, f, m, r = (s["scale_err_mean"], s["final_distance_err"], s["served_distance_err"],
                      s["rays_scale_err"])
        lines.append(f"| {s['name']} | {_pct(o)} | {_pct(f)} | {_pct(m)} | {_pct(r)} "
                     f"| {_pct(m - f)} | {_pct(r - m)} | {_pct(o - r)} |")
    return lines


def _cases(text: str, frames: int, offline: bool, window: int | None,
           fixtures: str) -> list[tuple]:
    cases = []
    for part in text.split(","):
        kind, seeds = part.split(":")
        names = (seeds.split("+") if kind == "fixtures"
                 else bj._seeds(seeds.replace("+", ",")))
        cases += [(kind, s, frames, offline, window, fixtures) for s in names]
    return cases


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="realistic:0-1,iid:0",
                    help="kind:seeds, comma-separated (kinds iid, realistic, cmu, lowpar, "
                         "paper; seeds joined by '+': realistic:0-9+13; fixtures:scene_900+scene_901)")
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--window-frames", type=int, default=None,
                    help="the live windows' size (LiveOptions.window_frames; default the "
                         "live run's): smaller windows fuse more of them")
    ap.add_argument("--offline", action="store_true",
                    help="also mirrorgraph.calibrate on every frame of each scene")
    ap.add_argument("--fixtures", default=str(bj.default_fixtures()),
                    help="folder of fixture scenes (bench_joints.py's)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=str(ROOT / "bench" / "RESULTS_live_scale.md"))
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    cases = _cases(args.scenes, args.frames, args.offline, args.window_frames, args.fixtures)
    clock = time.perf_counter()
    with ProcessPoolExecutor(max(1, args.workers)) as pool:
        scenes = list(pool.map(run_scene, cases))
    lines = ["# The live run's metric scale window by window (`bench/bench_live_scale.py`)", "",
             *_report.header(code=True), f"- wall: {time.perf_counter() - clock:.0f} s", "",
             *tables(scenes)]
    print("\n".join(lines))
    if not args.no_write:
        Path(args.out).write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
