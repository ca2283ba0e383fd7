#!/usr/bin/env python
"""The focal length from real detectors: what biases it, measured on real keypoints with a known camera.

    python bench/bench_focal_real.py                   # every clip and variant: ~35 min of runs
    python bench/bench_focal_real.py --pairs cam01-cam04 cam02-cam03 --variants detected truth \
        --no-write                                     # a look in ~3 min
    python bench/bench_focal_real.py --detectors OpenPose --json a.json    # side by side,
    python bench/bench_focal_real.py --detectors BlazePose --json b.json   # then:
    python bench/bench_focal_real.py --merge a.json b.json

**Data.** The Pose2Sim demo trial ``Demo_SinglePerson`` (the ``pose2sim`` 0.10.49 wheel: four
cameras, 100 frames, 1080 x 1920, Qualisys calibration, f ~ 1681 px) and two detectors on
its four videos: OpenPose BODY_25B (the JSON of Pose2Sim's git history, as
``bench_agreement.py``) and BlazePose (:func:`mirrorgraph.video.detect_video`, defaults; the
person nearest OpenPose's in each frame).

**Bones in 3D.** Each detector's joints triangulated with the four Qualisys cameras
(undistorted; a joint where two cameras or more see it): per bone of the graph's set, the
median length and its spread over the frames (robust CV, 1.4826 MAD / median). A bone
whose length changes with the pose is no rigid bone: the focal length, read off the
bones' constancy, is pulled by it.

**Mirror clips.** :class:`bench_agreement.PairClip` makes an exact planar mirror of two
cameras A and B (B's view is what A sees in the mirror bisecting their centres; the
clip's camera f = 840 px at the centre of 1280 x 960), here at the keypoints' level:
each detector's keypoints of A and of B mapped into the clip (the reflection's labels
swapped), every joint inside the frame kept (``--hide``: the joints the composite would
hide left out too, the reflection half behind the person, as in ``bench_agreement.py``'s
videos, where few frames keep both views). The ordered pairs of the four cameras whose
person stands over 0.3 m before the mirror (``--pairs``): A-B and B-A are one mirror seen
from either side, the same 3D data (OpenPose gives them nearly the same figures), but the
detector's keypoints of the reflection come from the other camera. Each clip is calibrated without intrinsics (the image size
only; subject height 1.60 m), once per **variant** of the keypoints or the options:

* ``detected``: as the detector gives them;
* ``oracle``: each camera's mean offset per joint against the Qualisys reprojection of
  the detector's own 4-camera triangulation removed (uses the truth: a measurement of
  the cause, the view-dependent bias between the two views, not a method);
* ``truth``: that reprojection itself, with the detector's visibility (no detector
  error; what 100 frames of this motion allow);
* ``no_symmetry``: the left/right symmetry prior off;
* ``no_neck``: the joints without BODY_25B's upper neck (its scapular bones out);
  BlazePose has none;
* ``no_hips``: the joints without the hips (every bone through them out: femurs,
  the hip width);
* ``widths``: the segments whose definition differs most between Winter's anthropometry
  and a detector's joint centres (the shoulder and hip widths, BODY_25B's neck to
  shoulder: ``anthropometry.HEIGHT_FRACTION``) set to the detector's own, its 4-camera
  median over the 1.60 m stature (the definitions swapped; uses the truth);
* ``pp_off``: every keypoint moved by one std of the principal point's prior in each
  coordinate (1 % of the larger side, 12.8 px): the same clip seen by a camera whose
  principal point lies that far off the centre the estimate assumes (a pinhole image
  moves rigidly with it);
* ``known_K``: the clip's true camera matrix given (the mirror's reference).

Reported per detector and variant: the focal length's error, its reported std, |error| /
std, the verdict (determined or not), the mirror's rotation error and std.

Writes ``bench/RESULTS_focal_real.md`` (and ``.json``) unless ``--no-write``.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import mirrorgraph as mg  # noqa: E402
from mirrorgraph.geometry import triangulate  # noqa: E402
from mirrorgraph.keypoints import RawDetections  # noqa: E402
from mirrorgraph.metrics import mirror_rotation_error_deg  # noqa: E402
from mirrorgraph.anthropometry import bone_kind  # noqa: E402
from mirrorgraph.skeletons import BLAZEPOSE, BODY_25B  # noqa: E402

import bench_agreement as ba  # noqa: E402
from _report import header, now  # noqa: E402

HEIGHT = ba.HEIGHT
VARIANTS = ("detected", "oracle", "truth", "no_symmetry", "no_neck", "no_hips", "widths",
            "pp_off", "known_K")
DETECTORS = {"OpenPose": BODY_25B, "BlazePose": BLAZEPOSE}
CAMS = ("cam01", "cam02", "cam03", "cam04")
#: The clips: the ordered pairs of cameras whose person stands over 0.3 m before the
#: mirror that bisects them (cam01-cam02 and cam03-cam04: 0.11 and 0.0 m, the person
#: in the mirror's plane).
PAIRS = [f"{a}-{b}" for a, b in (("cam01", "cam03"), ("cam01", "cam04"), ("cam02", "cam03"),
                                  ("cam02", "cam04"))] \
    + [f"{b}-{a}" for a, b in (("cam01", "cam03"), ("cam01", "cam04"), ("cam02", "cam03"),
                               ("cam02", "cam04"))]
#: Confidence below which a detector's joint is not used (OpenPose score, BlazePose
#: visibility), as the calibration's own default.
MIN_CONF = 0.3


def blaze_subjects(trial: Path, op: dict[str, dict], frames: int) -> dict[str, dict]:
    """Camera -> frame -> ``(33, 3)`` BlazePose person nearest the OpenPose subject (source
    px, visibility as the confidence)."""
    from mirrorgraph.video import VideoOptions, detect_video
    common = [n for n in BODY_25B.joints if BLAZEPOSE.has(n)]
    io = [BODY_25B.index(n) for n in common]
    ib = [BLAZEPOSE.index(n) for n in common]
    out = {}
    for cam in CAMS:
        det = detect_video(trial / "videos" / f"{cam}.mp4", VideoOptions()).to_raw()
        subj = {}
        for t, people in zip(det.frame_ids, det.people):
            ref = op[cam].get(int(t)) if int(t) < frames else None
            if ref is None or len(people) == 0:
                continue
            d = [np.nanmedian(np.linalg.norm(p[ib, :2] - ref[io, :2], axis=1)) for p in people]
            k = int(np.nanargmin(d))
            if np.isfinite(d[k]) and d[k] < 80:
                subj[int(t)] = np.asarray(people[k], float).copy()
        out[cam] = subj
    return out


def triangulated(subj: dict[str, dict], quals: dict, J: int, frames: list[int]) -> np.ndarray:
    """``(T, J, 3)`` world joints from the four Qualisys cameras (NaN where under two see)."""
    Ps, xs, ms = [], [], []
    for cam in CAMS:
        q = quals[cam]
        Ps.append(np.hstack([np.asarray(q.R, float), np.asarray(q.t, float)[:, None]]))
        uv = np.full((len(frames), J, 2), np.nan)
        ok = np.zeros((len(frames), J), bool)
        for i, t in enumerate(frames):
            s = subj[cam].get(t)
            if s is not None:
                good = np.isfinite(s[:, :2]).all(1) & (s[:, 2] >= MIN_CONF)
                uv[i, good] = s[good, :2]
                ok[i] = good
        xn = np.full(uv.shape, np.nan)
        xn[ok] = ba._undistort(uv[ok], np.asarray(q.K, float), np.asarray(q.dist, float))
        xs.append(xn)
        ms.append(ok & np.isfinite(xn).all(-1))
    X, seen = triangulate(Ps, xs, ms)
    return np.where(seen[..., None], X, np.nan)


def reproject(X: np.ndarray, q) -> np.ndarray:
    """``(T, J, 2)`` source pixels (distorted) of world points."""
    Xc = X @ np.asarray(q.R, float).T + np.asarray(q.t, float)
    xn = Xc[..., :2] / Xc[..., 2:]
    return ba._distort(xn, np.asarray(q.K, float), np.asarray(q.dist, float))


def keypoint_variants(subj: dict[str, dict], quals: dict, J: int) -> dict[str, dict]:
    """``detected``, ``oracle`` and ``truth`` keypoints per camera (frame -> ``(J, 3)``)."""
    frames = sorted(set.intersection(*(set(subj[c]) for c in CAMS)))
    X = triangulated(subj, quals, J, frames)
    out = {"detected": subj, "oracle": {}, "truth": {}}
    for cam in CAMS:
        proj = reproject(X, quals[cam])
        det = np.stack([subj[cam][t] for t in frames])                  # (T, J, 3)
        good = (det[..., 2] >= MIN_CONF) & np.isfinite(det[..., :2]).all(-1)
        res = np.where(good[..., None], proj - det[..., :2], np.nan)
        n = np.isfinite(res).all(-1).sum(0)
        offset = np.where(n[:, None] >= 10, np.nanmean(res, axis=0), 0.0)   # (J, 2)
        orc, tru = {}, {}
        for i, t in enumerate(frames):
            s = det[i].copy()
            s[:, :2] += offset
            orc[t] = s
            r = det[i].copy()
            fin = np.isfinite(proj[i]).all(-1)
            r[:, :2] = np.where(fin[:, None], proj[i], np.nan)
            r[~fin, 2] = 0.0
            tru[t] = r
        out["oracle"][cam], out["truth"][cam] = orc, tru
    return out, X


def bone_table(X: np.ndarray, skeleton) -> list[dict]:
    """Per bone of the mirror graph's set: median length (mm), robust CV over frames."""
    from mirrorgraph.joint_sets import mirror_joints
    keep = set(np.asarray(mirror_joints(skeleton, None), int).tolist())
    rows = []
    for name, (a, b) in zip(skeleton.bone_names, skeleton.bone_index):
        if int(a) not in keep or int(b) not in keep:
            continue
        L = np.linalg.norm(X[:, a] - X[:, b], axis=-1)
        L = L[np.isfinite(L)]
        if len(L) < 10:
            continue
        med = float(np.median(L))
        rows.append({"bone": name, "mm": 1e3 * med, "cv": float(1.4826 * np.median(np.abs(L - med))
                                                                / med), "frames": int(len(L))})
    return rows


def composite(clip, subjA: dict, subjB: dict, skeleton, hide: bool = False) -> RawDetections:
    """``bench_agreement.annotations`` for any layout: A's person and B's reflection in clip
    pixels, the reflection's labels swapped, joints outside the frame at confidence 0;
    ``hide``: also those the clip hides (the person on the mirror's side, the reflection
    behind the person)."""
    flip = np.asarray(skeleton.flip)
    W, H = clip.size
    frames, people = [], []
    for t in sorted(set(subjA) & set(subjB)):
        s, r = subjA[t], subjB[t]
        person = clip.person_xy(s[:, :2])
        refl = clip.reflection_xy(r[:, :2])[flip]
        rconf = r[flip, 2]

        def shown(xy, mirror_side):
            ok = np.isfinite(xy).all(1)
            inside = ok & (xy[:, 0] >= -0.5) & (xy[:, 0] < W - 0.5) & (xy[:, 1] >= -0.5) \
                & (xy[:, 1] < H - 0.5)
            if not hide:
                return inside
            side = np.zeros(len(xy), bool)
            side[ok] = clip.in_mirror(xy[ok], t) == mirror_side
            return inside & side
        kp = np.zeros((2, skeleton.num_joints, 3))
        for i, (xy, c, vis) in enumerate(((person, s[:, 2], shown(person, False)),
                                          (refl, rconf, shown(refl, True)))):
            good = vis & np.isfinite(c) & (c > 0)
            kp[i, good, :2] = xy[good]
            kp[i, good, 2] = c[good]
        frames.append(t)
        people.append(kp)
    return RawDetections(skeleton=skeleton, frame_ids=np.array(frames, np.int64), people=people,
                         image_size=clip.size, fps=ba.FPS)


#: ``pp_off``'s shift of every keypoint, each coordinate, fraction of the larger side:
#: one std of the principal point's prior (``FocalOptions.principal_point_rel_sigma``).
PP_SHIFT = 0.01


def shifted_principal_point(det: RawDetections, px: float) -> RawDetections:
    """``det`` with every shown keypoint moved by ``(px, px)``."""
    people = []
    for p in det.people:
        q = np.array(p, float, copy=True)
        shown = q[..., 2] > 0
        q[..., 0][shown] += px
        q[..., 1][shown] += px
        people.append(q)
    return replace(det, people=people)


def joints_without(skeleton, names: tuple[str, ...]) -> list[str] | None:
    """The mirror joints of ``skeleton`` without ``names`` (``None``: nothing to leave out)."""
    from mirrorgraph.joint_sets import mirror_joints
    idx = np.asarray(mirror_joints(skeleton, None), int)
    kept = [skeleton.joints[i] for i in idx if skeleton.joints[i] not in names]
    return None if len(kept) == len(idx) else kept


def calibrate(det: RawDetections, clip, variant: str, bones: list[dict] | None = None) -> dict:
    if variant == "widths":
        from mirrorgraph import anthropometry
        saved = dict(anthropometry.HEIGHT_FRACTION)
        own = {bone_kind(r["bone"]): r["mm"] / 1e3 / HEIGHT for r in bones or []}
        for kind in ("shoulder_width", "hip_width", "scapular"):
            if kind in own:
                anthropometry.HEIGHT_FRACTION[kind] = own[kind]
        if "hip_width" in own:
            anthropometry.HEIGHT_FRACTION["pelvis"] = own["hip_width"] / 2
        try:
            return calibrate(det, clip, "detected")
        finally:
            anthropometry.HEIGHT_FRACTION.clear()
            anthropometry.HEIGHT_FRACTION.update(saved)
    size = tuple(det.image_size)
    refine = mg.RefineOptions()
    joints = None
    if variant == "no_symmetry":
        refine = replace(refine, use_symmetry=False)
    elif variant == "no_neck":
        joints = joints_without(det.skeleton, ("neck",))
        if joints is None:
            return {"skipped": "no neck in this layout"}
    elif variant == "no_hips":
        joints = joints_without(det.skeleton, ("left_hip", "right_hip"))
    opts = mg.CalibrateOptions(image_size=size, subject_height=HEIGHT, fps=ba.FPS,
                               joints=joints, refine_options=refine)
    intr = (mg.Intrinsics(K=clip.K, image_size=size, source="the clip's matrix")
            if variant == "known_K" else None)
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            run = mg.calibrate(det, intr, opts)
    except (mg.InputError, mg.DegenerateGeometryError) as exc:
        return {"refused": str(exc)[:200], "seconds": time.perf_counter() - t0}
    c = run.calibration
    u = c.uncertainty
    est = c.intrinsics.estimated or {}
    f = float(c.intrinsics.K[0, 0])
    out = {"f": f, "f_err": f / clip.F - 1.0, "f_std": float(u.get("focal_std_px", np.nan)),
           "determined": bool(est.get("determined", True)), "search": est.get("search_px"),
           "marginal_std": est.get("marginal_std_px"),
           "rot_err": mirror_rotation_error_deg(c.normal, np.asarray(clip.truth["normal"])),
           "rot_std": float(u.get("rotation_std_deg", np.nan)),
           "pairs": int(c.pairs_used), "frames": int(c.frames_used),
           "seconds": time.perf_counter() - t0}
    sources = est.get("focal_sources")
    if sources:
        out["sources"] = sources
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pairs", nargs="*", default=PAIRS,
                    help="clips A-B (B as A's mirror); default every ordered pair whose "
                    "person stands over 0.3 m before the mirror")
    ap.add_argument("--hide", action="store_true",
                    help="leave out the joints the composite hides (the reflection half "
                    "behind the person): few frames keep both views")
    ap.add_argument("--json", type=Path, help="write the data here (and no report)")
    ap.add_argument("--merge", nargs="+", type=Path, metavar="JSON",
                    help="report the data of these --json runs together")
    ap.add_argument("--variants", nargs="*", default=list(VARIANTS), choices=VARIANTS)
    ap.add_argument("--detectors", nargs="*", default=list(DETECTORS), choices=list(DETECTORS))
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--openpose", type=Path, help="folder of cam0N OpenPose JSON folders")
    ap.add_argument("--pose2sim-git", type=Path, default=ba.DEFAULT_GIT)
    ap.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "bench_agreement")
    ap.add_argument("--note", default="", help="a line under the header (what was merged)")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    started, t_all = now(), time.perf_counter()
    if args.merge:
        parts = [json.loads(f.read_text()) for f in args.merge]
        data = {"bones": {k: v for d in parts for k, v in d["bones"].items()},
                "clips": _merge_clips(parts), "pairs": parts[0]["pairs"]}
        args.detectors = [d for d in DETECTORS if d in data["bones"]]
        args.variants = [v for v in VARIANTS if any(k.endswith("/" + v) for c in data["clips"]
                                                   for k in c["res"])]
        seconds = sum(d.get("seconds", 0.0) for d in parts)
        return _write(report(data, args, started, seconds, argv), data, args)
    args.work.mkdir(parents=True, exist_ok=True)
    trial, quals, op = ba.demo_subjects(args, list(CAMS))
    subjects = {"OpenPose": op}
    if "BlazePose" in args.detectors:
        subjects["BlazePose"] = blaze_subjects(trial, op, args.frames)
    data = {"bones": {}, "clips": [], "pairs": args.pairs}
    kp = {}
    for name in args.detectors:
        sk = DETECTORS[name]
        kp[name], X = keypoint_variants(subjects[name], quals, sk.num_joints)
        data["bones"][name] = bone_table(X, sk)
    for pair in args.pairs:
        A, B = pair.split("-")
        clip = ba.pair_clip(pair, quals, op)
        row = {"clip": clip.name, "truth": clip.truth, "res": {}}
        for name in args.detectors:
            sk = DETECTORS[name]
            for variant in args.variants:
                src = kp[name][variant if variant in ("oracle", "truth") else "detected"]
                det = composite(clip, src[A], src[B], sk, args.hide)
                if variant == "pp_off":
                    det = shifted_principal_point(det, PP_SHIFT * max(clip.size))
                r = calibrate(det, clip, variant, data["bones"][name])
                row["res"][f"{name}/{variant}"] = r
                print(f"{clip.name} {name} {variant}: "
                      + (f"f {r['f']:.0f} +- {r['f_std']:.0f} ({100 * r['f_err']:+.1f} %), "
                         f"rot {r['rot_err']:.2f} / {r['rot_std']:.2f} deg, "
                         f"{'determined' if r['determined'] else 'undetermined'}, "
                         f"search {r['search']}" if "f" in r else str(r)), flush=True)
        data["clips"].append(row)
    data["seconds"] = time.perf_counter() - t_all
    if args.json:
        args.json.write_text(json.dumps(data, default=float) + "\n")
        return 0
    return _write(report(data, args, started, data["seconds"], argv), data, args)


def _merge_clips(parts: list[dict]) -> list[dict]:
    """The clips of several runs, each clip's results of every run together."""
    out: dict[str, dict] = {}
    for d in parts:
        for c in d["clips"]:
            row = out.setdefault(c["clip"], {k: v for k, v in c.items() if k != "res"} | {"res": {}})
            row["res"].update(c["res"])
    return list(out.values())


def _write(text: str, data: dict, args) -> int:
    print(text)
    if not args.no_write:
        (ROOT / "bench" / "RESULTS_focal_real.md").write_text(text)
        (ROOT / "bench" / "RESULTS_focal_real.json").write_text(json.dumps(data, indent=1,
                                                                           default=float) + "\n")
    return 0


def _z(r: dict) -> float:
    return abs(r["f"] - ba.PairClip.F) / r["f_std"] if r.get("f_std", 0) > 0 else float("inf")


def _signed(data: dict, key: str) -> list[float]:
    return [c["res"][key]["f_err"] for c in data["clips"] if "f" in c["res"].get(key, {})]


def reading(data: dict, args) -> list[str]:
    """The figures the docs quote, computed from the data."""
    out = ["What the table shows:", ""]
    for d in args.detectors:
        det, tru = _signed(data, f"{d}/detected"), _signed(data, f"{d}/truth")
        if not det:
            continue
        runs = [c["res"][f"{d}/detected"] for c in data["clips"]
                if "f" in c["res"].get(f"{d}/detected", {})]
        z = [_z(r) for r in runs]
        rz = [r["rot_err"] / r["rot_std"] for r in runs if r["rot_std"] > 0]
        out.append(
            f"* {d}: signed focal error median {100 * np.median(det):+.1f} % (range "
            f"{100 * min(det):+.0f} to {100 * max(det):+.0f} %), {sum(abs(x) <= 0.1 for x in det)}"
            f" of {len(det)} within 10 %, {sum(x <= 2 for x in z)} of {len(z)} within 2 "
            f"reported std (|error| / std median {np.median(z):.2f}; the mirror's rotation "
            f"error / std median {np.median(rz):.2f}, {sum(x <= 2 for x in rz)} of {len(rz)} "
            "within 2); with the detector's error taken out (`truth`: the reprojection of "
            f"its own 4-camera joints) median {100 * np.median(np.abs(tru)):.1f} % |error| "
            f"(range {100 * min(tru):+.0f} to {100 * max(tru):+.0f} %)." if tru else "")
    return out


def report(data: dict, args, started: str, seconds: float, argv) -> str:
    L = ["# The focal length from real detectors (`bench/bench_focal_real.py`)", "",
         *header(started=f"{started} ({seconds / 60:.1f} min of runs)", argv=argv),
         *([f"* {args.note}"] if getattr(args, "note", "") else []), "",
         "Data: Pose2Sim's Demo_SinglePerson (4 cameras, 100 frames, Qualisys); OpenPose "
         "BODY_25B (Pose2Sim's git history) and BlazePose (mirrorgraph.video) on the same "
         "videos. See the script's docstring for the clips and the variants.", ""]
    L += ["## Bones in 3D (four Qualisys cameras)", "",
          "Each detector's joints triangulated with the four calibrated cameras; the bones "
          "the mirror graph uses (its joints `auto`). CV: 1.4826 MAD / median over the "
          "frames (a rigid bone's is the triangulation's noise, under 2 %).", "",
          "| detector | bone | median mm | CV % | frames |", "|---|---|---:|---:|---:|"]
    for name, rows in data["bones"].items():
        for r in rows:
            L.append(f"| {name} | {r['bone']} | {r['mm']:.0f} | {100 * r['cv']:.1f} | "
                     f"{r['frames']} |")
    L += ["", "## Mirror clips: the focal length (truth 840 px) by detector and variant", "",
          "Per cell: median over the clips of |error| %, of the reported std %, of |error| / "
          "std; clips within 10 %; clips the output calls determined; clips with |error| > "
          "2 std.", "",
          "| detector | variant | clips | abs error median | std median | abs error / std "
          "median | within 10 % | determined | beyond 2 std | rotation error / std deg "
          "median |", "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for name in args.detectors:
        for v in args.variants:
            R = [c["res"].get(f"{name}/{v}", {}) for c in data["clips"]]
            ok = [r for r in R if "f" in r]
            if not ok:
                continue
            if v == "known_K":
                L.append(f"| {name} | {v} | {len(ok)} | - | - | - | - | - | - | "
                         f"{np.median([r['rot_err'] for r in ok]):.2f} / "
                         f"{np.median([r['rot_std'] for r in ok]):.2f} |")
                continue
            err = np.array([abs(r["f_err"]) for r in ok])
            std = np.array([r["f_std"] / r["f"] for r in ok])
            z = np.array([_z(r) for r in ok])
            L.append(f"| {name} | {v} | {len(ok)} of {len(R)} | {100 * np.median(err):.1f} % | "
                     f"{100 * np.median(std):.1f} % | {np.median(z):.2f} | "
                     f"{int(np.sum(err <= 0.1))} | {sum(r['determined'] for r in ok)} | "
                     f"{int(np.sum(z > 2))} | {np.median([r['rot_err'] for r in ok]):.2f} / "
                     f"{np.median([r['rot_std'] for r in ok]):.2f} |")
    L += ["", *reading(data, args), "", "## Every clip", "",
          "f +- std px (error %), `u`: undetermined; rotation error / std deg.", "",
          "| clip | " + " | ".join(f"{d} {v}" for d in args.detectors for v in args.variants)
          + " |", "|---|" + "---|" * (len(args.detectors) * len(args.variants))]
    for c in data["clips"]:
        cells = []
        for d in args.detectors:
            for v in args.variants:
                r = c["res"].get(f"{d}/{v}", {})
                if "f" in r:
                    flag = "" if r["determined"] else " u"
                    cells.append(f"{r['f']:.0f} +- {r['f_std']:.0f} ({100 * r['f_err']:+.0f} %)"
                                 f"{flag}; {r['rot_err']:.1f} / {r['rot_std']:.1f}")
                else:
                    cells.append("refused" if "refused" in r else "-")
        L.append(f"| {c['clip']} | " + " | ".join(cells) + " |")
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    sys.exit(main())
