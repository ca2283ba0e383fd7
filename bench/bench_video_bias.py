"""BlazePose against OpenPose on one real trial: where the two put the same joints.

The Pose2Sim demo trial ``Demo_SinglePerson`` (4 cameras, 100 frames, Qualisys
calibration) was published with OpenPose BODY_25B keypoints of every frame in
Pose2Sim's git history (``Pose2Sim/Demo/S00_Demo_Session/S00_P00_Participant/
S00_P00_T01_BalancingTrial/pose/cam0N_json/``, commit ``a4d38da``; the same
Qualisys file as the wheel's trial but for the cameras' names). The wheel ships
the videos only. Given those JSON folders (``--openpose DIR`` holding ``cam01`` ..
``cam04``, e.g. extracted with ``git show``), this script:

1. detects the four videos with mirrorgraph's BlazePose path (cached);
2. pairs the subject frame by frame (OpenPose: the tallest person; BlazePose: the
   pose nearest to it), after finding the frame offset between the two (the one
   that minimises the median distance);
3. per joint both have (shoulders, elbows, wrists, hips, knees, ankles, heels, big
   toes, nose, eyes, ears): the median distance and the median offset BlazePose -
   OpenPose along the body (towards the head: mid-hip to mid-shoulder) and across
   it, in % of the OpenPose torso (mid-shoulder to mid-hip);
4. both detectors' joints triangulated with the Qualisys cameras (undistorted,
   DLT + Gauss-Newton, :func:`mirrorgraph.geometry.triangulate`): the median bone
   lengths (mm) and their ratio, which is what a stature prior turns into the
   calibration's metric scale (the mirror distance scales with it); the
   reprojection error of each (px).

Usage::

    git -C pose2sim show a4d38da:Pose2Sim/Demo/S00_Demo_Session/S00_P00_Participant/\
        S00_P00_T01_BalancingTrial/pose/cam01_json/cam01.0000.json > op/cam01/...  # etc.
    python bench/bench_video_bias.py --openpose op > bench/RESULTS_video_bias.md

The frame offset found is +1 on all four cameras: OpenPose's file ``cam0N.00tt.json``
is the video's frame ``tt + 1`` as the wheel's videos decode.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mirrorgraph.geometry import triangulate  # noqa: E402
from mirrorgraph.io import read_keypoints  # noqa: E402
from mirrorgraph.io.qualisys import read_qca  # noqa: E402
from mirrorgraph.skeletons import BLAZEPOSE, BODY_25B  # noqa: E402
from mirrorgraph.video import VideoOptions, detect_video  # noqa: E402

COMMON = [n for n in BODY_25B.joints if BLAZEPOSE.has(n)]
BONES = {"femur": ("hip", "knee"), "tibia": ("knee", "ankle"), "humerus": ("shoulder", "elbow"),
         "forearm": ("elbow", "wrist")}


def _subject(people: np.ndarray) -> int | None:
    if len(people) == 0:
        return None
    ok = people[..., 2] > 0.3
    h = [np.ptp(p[k, 1]) if k.sum() >= 4 else 0.0 for p, k in zip(people, ok)]
    return int(np.argmax(h))


def pairs(op, bp, offset: int):
    """``(T, C, 3)`` OpenPose and BlazePose subjects on the COMMON joints (NaN where
    unseen: OpenPose confidence <= 0.3, BlazePose visibility < 0.5)."""
    io = [BODY_25B.index(n) for n in COMMON]
    ib = [BLAZEPOSE.index(n) for n in COMMON]
    bmap = {int(t): p for t, p in zip(bp.frame_ids, bp.people)}
    A, B, ts = [], [], []
    for t, people in zip(op.frame_ids, op.people):
        s = _subject(people)
        cand = bmap.get(int(t) + offset)
        if s is None or cand is None or len(cand) == 0:
            continue
        a = people[s][io].copy()
        a[a[:, 2] <= 0.3, :2] = np.nan
        best, bd = None, np.inf
        for c in cand:
            b = c[ib].copy()
            b[b[:, 2] < 0.5, :2] = np.nan
            d = np.nanmedian(np.linalg.norm(a[:, :2] - b[:, :2], axis=1))
            if d < bd:
                best, bd = b, d
        A.append(a)
        B.append(best)
        ts.append(int(t))
    return np.array(A), np.array(B), np.array(ts)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--openpose", required=True, type=Path,
                    help="folder holding cam01..cam04 OpenPose JSON folders")
    args = ap.parse_args()
    demo = Path(list(importlib.util.find_spec("Pose2Sim").submodule_search_locations)[0])
    trial = demo / "Demo_SinglePerson"
    cams = read_qca(trial / "calibration" / "Calib.qca.txt")
    names = ["cam01", "cam02", "cam03", "cam04"]
    along_all, tri = {n: [] for n in COMMON}, {}
    from _report import header
    print("# BlazePose vs OpenPose BODY_25B on Demo_SinglePerson\n")
    print("\n".join(header(bullet="-")) + "\n")
    print("| camera | frame offset | frames | median distance, all common joints (px) | "
          "torso (px) |")
    print("|---|---|---|---|---|")
    per_cam = {}
    for cam in names:
        op = read_keypoints(args.openpose / cam, skeleton="BODY_25B")
        bp = detect_video(trial / "videos" / f"{cam}.mp4", VideoOptions()).to_raw()
        scores = {}
        for k in range(-3, 4):
            A, B, _ = pairs(op, bp, k)
            scores[k] = np.nanmedian(np.linalg.norm(A[..., :2] - B[..., :2], axis=-1))
        k = min(scores, key=scores.get)
        A, B, ts = pairs(op, bp, k)
        per_cam[cam] = (A, B, ts, k)
        ls, rs = COMMON.index("left_shoulder"), COMMON.index("right_shoulder")
        lh, rh = COMMON.index("left_hip"), COMMON.index("right_hip")
        ms = (A[:, ls, :2] + A[:, rs, :2]) / 2
        mh = (A[:, lh, :2] + A[:, rh, :2]) / 2
        up = ms - mh
        torso = np.linalg.norm(up, axis=1)
        up = up / torso[:, None]
        across = np.stack([-up[:, 1], up[:, 0]], axis=1)
        d = B[..., :2] - A[..., :2]
        for j, n in enumerate(COMMON):
            along_all[n].append(np.column_stack([np.sum(d[:, j] * up, 1) / torso,
                                                 np.sum(d[:, j] * across, 1) / torso,
                                                 np.linalg.norm(d[:, j], axis=1)]))
        print(f"| {cam} | {k:+d} | {len(ts)} | {scores[k]:.1f} | {np.nanmedian(torso):.0f} |")
    print("\n| joint | median distance (px) | towards the head (% torso) | across the body, "
          "to the subject's left in the image (% torso) |")
    print("|---|---|---|---|")
    for n in COMMON:
        v = np.concatenate(along_all[n])
        print(f"| {n} | {np.nanmedian(v[:, 2]):.1f} | {100 * np.nanmedian(v[:, 0]):+.1f} | "
              f"{100 * np.nanmedian(v[:, 1]):+.1f} |")
    # widths, bones, 3D
    def undist(cam, xy):
        import cv2
        c = cams[cam]
        out = np.full(xy.shape, np.nan)
        ok = np.isfinite(xy).all(-1)
        if ok.any():
            out[ok] = cv2.undistortPoints(xy[ok].reshape(-1, 1, 2).astype(np.float64), c.K,
                                          np.r_[c.dist, 0], P=c.K).reshape(-1, 2)
        return out
    common_t = sorted(set.intersection(*(set((ts + 0).tolist()) for _, _, ts, _ in
                                         per_cam.values())))
    P = [cams[c].K @ np.column_stack([cams[c].R, cams[c].t]) for c in names]
    for label, which in (("OpenPose", 0), ("BlazePose", 1)):
        px = []
        for c in names:
            A, B, ts, _ = per_cam[c]
            idx = {int(t): i for i, t in enumerate(ts)}
            arr = (A, B)[which]
            px.append(undist(c, np.stack([arr[idx[t], :, :2] for t in common_t])))
        X, ok = triangulate(P, px, min_views=2)
        rep = []
        for Pc, uv in zip(P, px):
            h = np.concatenate([X, np.ones(X.shape[:-1] + (1,))], -1) @ Pc.T
            r = np.linalg.norm(h[..., :2] / h[..., 2:] - uv, axis=-1)
            rep.append(r[np.isfinite(r)])
        tri[label] = (X, np.median(np.concatenate(rep)))
    print(f"\n3D (the 4 Qualisys cameras, {len(common_t)} frames): median reprojection error "
          f"OpenPose {tri['OpenPose'][1]:.1f} px, BlazePose {tri['BlazePose'][1]:.1f} px\n")
    print("| segment | OpenPose (mm) | BlazePose (mm) | BlazePose / OpenPose |")
    print("|---|---|---|---|")
    segs = {f"{s} {b}": (f"{s}_{p}", f"{s}_{q}") for b, (p, q) in BONES.items()
            for s in ("left", "right")}
    segs["shoulder width"] = ("left_shoulder", "right_shoulder")
    segs["hip width"] = ("left_hip", "right_hip")
    segs["left trunk (shoulder-hip)"] = ("left_shoulder", "left_hip")
    segs["right trunk (shoulder-hip)"] = ("right_shoulder", "right_hip")
    ratios = []
    for name, (p, q) in segs.items():
        i, j = COMMON.index(p), COMMON.index(q)
        lo = np.nanmedian(np.linalg.norm(tri["OpenPose"][0][:, i] - tri["OpenPose"][0][:, j],
                                         axis=-1)) * 1000
        lb = np.nanmedian(np.linalg.norm(tri["BlazePose"][0][:, i] - tri["BlazePose"][0][:, j],
                                         axis=-1)) * 1000
        ratios.append(lb / lo)
        print(f"| {name} | {lo:.0f} | {lb:.0f} | {lb / lo:.3f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
