"""The stature on real detections against the synthetic detectors': segment by segment.

:func:`mirrorgraph.stature.estimate_stature` sums the chain's segments (shank, thigh,
trunk, head) measured on 3D keypoints and divides by Winter's measured fraction. Its
error on a detector's keypoints is the keypoints' placement against the anatomical
landmarks Winter measured between. This script measures that placement on a real
trial and on the project's synthetic scenes, with the geometry known in both:

* **real**: the Pose2Sim demo trial ``Demo_SinglePerson`` (the ``pose2sim`` wheel: 4
  cameras, 100 frames at 60 fps, Qualisys calibration ``Calib.qca.txt``), its subject's
  keypoints triangulated with the four Qualisys cameras
  (:func:`mirrorgraph.geometry.triangulate`, undistorted with Qualisys' distortion; a
  view more than ``--max-px`` px off the other views' point dropped and the point solved
  again). Two detectors: OpenPose BODY_25B (the JSON published in Pose2Sim's git history,
  commit ``a4d38da``, read as ``bench_agreement.py`` reads them) and BlazePose
  (``mirrorgraph.video.detect_video``, defaults, the detection cache). Each camera's
  subject: the tallest person of the frame. The subject's height: Pose2Sim's demo
  configuration gives 1.70 m at that commit and 1.72 m later (``participant_height``,
  "only used for marker augmentation"; no measurement protocol is published: a witness
  of a few percent, not a ground truth).
* **synthetic**: ``bench_joints.py``'s wide scenes (``make_wide_scene``, population
  bodies), the realistic and the iid detector, the keypoints triangulated with the TRUE
  mirror (:func:`mirrorgraph.live.frame_prior.triangulate_two_rays`, outliers kept), and
  the generator's own true 3D keypoints (what the body model puts where, before any
  detector); against the scene's true height.

Per case: the stature's error against the height, the std the scale is given
(``height_sigma`` 2 % and :func:`mirrorgraph.stature.measurement_rel_std` in
quadrature), with and without its end keypoints' term
(:func:`mirrorgraph.stature.keypoint_rel_std`), their ratio, and per segment its median length over Winter's fraction of
the height (``shank`` knee-ankle 0.246, ``thigh`` hip-knee 0.245, ``trunk`` mid-hip to
mid-shoulder 0.288, ``head`` mid-shoulder to the eyes 0.118 or the head top 0.182, along
the trunk).

Writes ``--out`` (default ``bench/RESULTS_stature_real.md``) unless ``--no-write``.

Run:  python bench/bench_stature_real.py                       # ~2 min (BlazePose cached)
      python bench/bench_stature_real.py --scenes 0-3 --detectors openpose  # ~20 s
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _report  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: Pose2Sim's demo configuration's ``participant_height`` (m) at the OpenPose files'
#: commit ``a4d38da`` and in later releases.
CONFIG_HEIGHTS = (1.70, 1.72)
HEIGHT_SIGMA = 0.02         # RefineOptions.height_sigma's default
SEGMENTS = ("shank", "thigh", "trunk", "head")


def winter_fraction(segment: str, top: str) -> float:
    """The fraction of the height a chain segment spans between Winter's landmarks."""
    from mirrorgraph.anthropometry import LANDMARK_HEIGHT as L
    return {"shank": L["knee"] - L["ankle"], "thigh": L["hip"] - L["knee"],
            "trunk": L["shoulder"] - L["hip"],
            "head": (L["vertex"] if top == "head_top" else L["eye"]) - L["shoulder"]}[segment]


# =========================================================================== real trial
def _tallest(people: np.ndarray, min_conf: float = 0.3) -> np.ndarray | None:
    """``(J, 2)`` the tallest person's pixels (NaN below ``min_conf``), or ``None``."""
    if len(people) == 0:
        return None
    ok = people[..., 2] > min_conf
    h = [np.ptp(p[k, 1]) if k.sum() >= 4 else 0.0 for p, k in zip(people, ok)]
    s = np.array(people[int(np.argmax(h))][:, :2], float)
    s[~ok[int(np.argmax(h))]] = np.nan
    return s


def _undistorted(xy: np.ndarray, cam) -> np.ndarray:
    """Distorted pixels ``(..., 2)`` -> normalised image coordinates (NaN kept)."""
    import cv2
    out = np.full(xy.shape, np.nan)
    ok = np.isfinite(xy).all(-1)
    if ok.any():
        out[ok] = cv2.undistortPoints(xy[ok].reshape(-1, 1, 2).astype(np.float64), cam.K,
                                      np.r_[np.asarray(cam.dist, float)[:4], 0.0]).reshape(-1, 2)
    return out


def triangulate_views(uv: np.ndarray, poses: list[np.ndarray], max_px: float, f: float
                      ) -> np.ndarray:
    """``(T, J, 3)`` points from ``(V, T, J, 2)`` normalised coordinates and ``V``
    ``(3, 4)`` ``[R | t]``: all views, then again without the views more than ``max_px``
    (at focal ``f``) off the first point."""
    from mirrorgraph.geometry import triangulate

    views = list(uv)
    X, ok = triangulate(poses, views)
    keep = []
    for P, u in zip(poses, views):
        Xh = np.concatenate([X, np.ones(X.shape[:-1] + (1,))], -1) @ P.T
        with np.errstate(invalid="ignore", divide="ignore"):
            r = f * np.linalg.norm(Xh[..., :2] / Xh[..., 2:] - u, axis=-1)
        keep.append(np.isfinite(u).all(-1) & ~(r > max_px))
    X, ok = triangulate(poses, views, keep)
    X[~ok] = np.nan
    return X


def real_points(detector: str, frames: int, max_px: float, work: Path
                ) -> tuple[np.ndarray, object]:
    """The demo subject's ``(T, J, 3)`` triangulated keypoints (m, Qualisys world) and
    their skeleton."""
    import bench_agreement as ba
    from mirrorgraph.io.qualisys import read_qca

    trial = ba.demo_trial()
    quals = read_qca(trial / "calibration" / "Calib.qca.txt")
    cams = sorted(quals)
    per_cam = []
    if detector == "openpose":
        from mirrorgraph.skeletons import BODY_25B as skel
        args = argparse.Namespace(openpose=None, pose2sim_git=ba.DEFAULT_GIT, work=work)
        root = ba.openpose_folders(args, cams, work)
        for cam in cams:
            subj = ba.openpose_subject(root / cam)
            per_cam.append({t: s[:, :2] for t, s in subj.items() if t <= frames})
    else:
        from mirrorgraph.video import VideoOptions, detect_video
        skel = None
        for cam in cams:
            det = detect_video(trial / "videos" / f"{cam}.mp4", VideoOptions())
            skel = det.skeleton
            subj = {}
            for t, people in zip(det.frame_ids, det.people):
                s = _tallest(np.asarray(people))
                if s is not None and t < frames:
                    subj[int(t)] = s
            per_cam.append(subj)
    ts = sorted(set().union(*[set(s) for s in per_cam]))
    J = len(skel.joints)
    uv = np.full((len(cams), len(ts), J, 2), np.nan)
    for v, (cam, subj) in enumerate(zip(cams, per_cam)):
        for i, t in enumerate(ts):
            if t in subj:
                uv[v, i] = _undistorted(subj[t], quals[cam])
    poses = [np.c_[quals[c].R, quals[c].t] for c in cams]          # world -> camera
    f = float(np.mean([quals[c].K[0, 0] for c in cams]))
    return triangulate_views(uv, poses, max_px, f), skel


# =========================================================================== synthetic
def synthetic_points(kind: str, seed: int, frames: int) -> list[tuple[str, np.ndarray, object, float]]:
    """``[(source, (T, J, 3), skeleton, true height)]``: the keypoints at the true mirror
    and the generator's true keypoints."""
    import bench_joints as bj
    from mirrorgraph.live.frame_prior import triangulate_two_rays

    tr = bj.make_truth(kind, seed, frames, bj.default_fixtures(), "population", "reported")
    T, J = tr.joints3d.shape[:2]
    X = triangulate_two_rays(tr.intrinsics.K, tr.normal, tr.distance, tr.real.reshape(-1, 2),
                             tr.mirror.reshape(-1, 2)).reshape(T, J, 3)
    skel = tr.detections.skeleton
    return [(f"{kind} {seed}, true mirror", X, skel, tr.height),
            (f"{kind} {seed}, generator's true keypoints", np.asarray(tr.joints3d, float), skel,
             tr.height)]


# =========================================================================== scoring
def measure(name: str, X: np.ndarray, skel, height: float | None) -> dict | None:
    from mirrorgraph.stature import estimate_stature, measurement_rel_std

    st = estimate_stature(X, np.isfinite(X).all(-1), skel)
    if st is None:
        return None
    rel_std = float(np.hypot(HEIGHT_SIGMA, measurement_rel_std(st)))
    data_std = float(np.sqrt(HEIGHT_SIGMA ** 2 + st.side_rel_diff ** 2 + st.bones_rel_spread ** 2))
    row = dict(name=name, height=height, stature=st.height, top=st.top, frames=st.frames,
               side=st.side_rel_diff, bones=st.bones_rel_spread, rel_std=rel_std,
               data_std=data_std, bone_ratios=dict(st.bone_ratios))
    ref = height if height is not None else st.height
    row["ratio"] = {k: st.segments[k] / (winter_fraction(k, st.top) * ref) for k in SEGMENTS}
    row["err"] = None if height is None else st.height / height - 1.0
    return row


def _pct(v, fmt="{:+.1f}"):
    return "-" if v is None else fmt.format(100 * v)


def table(rows: list[dict]) -> list[str]:
    out = ["| case | height m | stature m | err % | std % without / with keypoints "
           "| err/std without / with | side % | bones % | shank | thigh | trunk | head | top |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        es = ("-" if r["err"] is None else f"{abs(r['err']) / r['data_std']:.2f} / "
              f"{abs(r['err']) / r['rel_std']:.2f}")
        h = "-" if r["height"] is None else f"{r['height']:.3f}"
        out.append(f"| {r['name']} | {h} | {r['stature']:.3f} | {_pct(r['err'])} "
                   f"| {100 * r['data_std']:.1f} / {100 * r['rel_std']:.1f} | {es} "
                   f"| {100 * r['side']:.1f} "
                   f"| {100 * r['bones']:.1f} | "
                   + " | ".join(f"{r['ratio'][k]:.3f}" for k in SEGMENTS) + f" | {r['top']} |")
    return out


def summary(real: list[dict], synth: list[dict]) -> list[str]:
    """Largest |err| and err/std (without / with the keypoints' term) per group."""
    groups = {"real (both heights)": real,
              **{f"{k}, {w}": [r for r in synth if r["name"].startswith(k) and w in r["name"]]
                 for k in ("realistic", "iid") for w in ("true mirror", "generator's")}}
    out = ["| group | n | RMS err % | largest abs err % | largest err/std without / with |",
           "|---|---|---|---|---|"]
    for name, rows in groups.items():
        rows = [r for r in rows if r["err"] is not None]
        if not rows:
            continue
        e = np.array([r["err"] for r in rows])
        out.append(f"| {name} | {len(rows)} | {100 * np.sqrt(np.mean(e ** 2)):.1f} "
                   f"| {100 * np.max(np.abs(e)):.1f} "
                   f"| {max(abs(r['err']) / r['data_std'] for r in rows):.2f} / "
                   f"{max(abs(r['err']) / r['rel_std'] for r in rows):.2f} |")
    out += ["", "Segments over Winter's fraction of the height, median (min - max) of the group:",
            "", "| group | " + " | ".join(SEGMENTS) + " |", "|---|" + "---|" * len(SEGMENTS)]
    for name, rows in groups.items():
        if rows:
            cells = []
            for k in SEGMENTS:
                v = np.array([r["ratio"][k] for r in rows])
                cells.append(f"{np.median(v):.3f} ({v.min():.3f} - {v.max():.3f})")
            out.append(f"| {name} | " + " | ".join(cells) + " |")
    by_det = {}
    for r in real:
        by_det.setdefault(r["name"].split(", ")[1], r["stature"])
    if len(by_det) == 2:
        (a, ha), (b, hb) = by_det.items()
        out += ["", f"The two detectors' statures on the same cameras: {a} {ha:.3f} m, "
                f"{b} {hb:.3f} m, {100 * (ha / hb - 1):+.1f} % apart (no height needed)."]
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="0-7", help="synthetic seeds, a-b (default 0-7)")
    ap.add_argument("--frames", type=int, default=1000, help="synthetic frames a scene")
    ap.add_argument("--kinds", default="realistic,iid")
    ap.add_argument("--detectors", default="openpose,blazepose")
    ap.add_argument("--max-px", type=float, default=20.0,
                    help="real trial: a view farther than this from the point is dropped")
    ap.add_argument("--work", type=Path, default=Path("/tmp") / f"stature-real-{os.getuid()}")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "RESULTS_stature_real.md")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    warnings.filterwarnings("ignore")
    args.work.mkdir(parents=True, exist_ok=True)

    real = []
    for det in filter(None, args.detectors.split(",")):
        X, skel = real_points(det, 100, args.max_px, args.work)
        for h in CONFIG_HEIGHTS:
            r = measure(f"Demo_SinglePerson, {det}, Qualisys (height {h:.2f})", X, skel, h)
            if r is not None:
                real.append(r)
        print(*table(real[-len(CONFIG_HEIGHTS):]), sep="\n", flush=True)
    a, b = (int(v) for v in args.scenes.split("-"))
    synth = []
    for kind in filter(None, args.kinds.split(",")):
        for seed in range(a, b + 1):
            for name, X, skel, h in synthetic_points(kind, seed, args.frames):
                r = measure(name, X, skel, h)
                if r is not None:
                    synth.append(r)
                    print(*table([r])[2:], sep="\n", flush=True)
    lines = ["# The stature on real and synthetic detections, segment by segment "
             "(`bench/bench_stature_real.py`)", "", *_report.header(code=True), "",
             "`err`: the stature over the height, `std`: the scale's relative std "
             "(`height_sigma` 2 % and `measurement_rel_std`: `side`, the legs apart, "
             "`bones`, the segments' disagreement, and, `with keypoints`, the chain's end "
             "keypoints' placement `keypoint_rel_std`, 2.7 % with the eyes as top, 2.5 % "
             "with the head top, in quadrature); `shank`..`head`: the segment's median "
             "length over Winter's fraction of the height (1 = Winter's proportion).", "",
             *summary(real, synth), "",
             "## Real: Pose2Sim Demo_SinglePerson, 4 Qualisys cameras", "", *table(real), "",
             f"## Synthetic: wide scenes {args.scenes}, {args.frames} frames, population bodies",
             "", *table(synth)]
    if not args.no_write:
        args.out.write_text("\n".join(lines) + "\n")
        print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
