"""Detection on real clips, before and after: people a frame, tracks a clip, frames/s.

Runs :func:`mirrorgraph.video.detect_video` (BlazePose, its defaults, no cache) on
each clip twice in this one run, with two versions of the ``mirrorgraph``
package side by side, clip by clip (so that both see the same load on the
machine):

* **before**: the package of a git revision (``--before``, default ``main``),
  extracted with ``git archive`` into a temporary folder;
* **after**: the package this script sits next to (the working tree).

Each run is a subprocess of this script (``--worker``) with its own
``PYTHONPATH``; it returns every frame's keypoints, track ids and the detection
time, and the figures are computed here, the same way for both:

* **people a frame**: the share of frames whose number of people lies in the
  clip's expected range: the subjects, plus up to the bystanders that are in view
  (counted by eye on the frames: Demo_SinglePerson cam01 has one person standing
  at the back, cam02 one person and an anatomical skeleton model; cam03, cam04
  none), and the mean number a frame;
* **people a frame against the people in view, frame by frame** (the
  Demo_MultiPerson clips; :func:`multi_person_reference`): the count by eye above is a
  fixed 2 for every frame; here each camera's reference comes from the other three:
  their detections (this tree's :func:`detect_video`, defaults) matched across the
  cameras and triangulated with the Qualisys cameras (:func:`people_3d`), projected
  into the camera, and a person is in view where more than half of their torso and
  limb joints (shoulders, elbows, wrists, hips, knees, ankles; :data:`VIEW_JOINTS`)
  fall inside the image and not within the other person's projected outline
  (limb capsules, filled torso, head: :data:`BODY_CAPSULES`) where that person is in
  front (:func:`in_view`). The rendered avatars of these videos are not drawn by
  depth (cam03 draws the woman over the man where he is a metre nearer), so the
  reference is a range: people in view whichever of two overlapping people is drawn
  in front, up to those in view in either order (and a subject not triangulated in
  a frame) plus the bystanders; "nearer in front" is the count with the nearer
  person hiding the farther. Also: the frames where a person in view has no
  detection on them (:func:`match_detections`), those with more detections than
  people possibly in view plus bystanders, and the share of frames with neither. ``--draw DIR`` writes PNGs of the frames
  where the reference or the count differs from the subjects';
* **duplicates**: frames holding two poses of one person by the criteria of
  :func:`mirrorgraph.video.nms.pose_nms` (object keypoint similarity above 0.5,
  left/right swaps included, box IoU above 0.7, or 85 % of one's keypoints on the
  other's body): the "after" code applies them, so its count is 0 by construction;
  the "people a frame" figure, against the counts by eye, is the independent one;
* **tracks**: track ids over the clip (the subjects' count is the ideal);
* **frames whose poses changed**: between the two runs (another count, or a keypoint
  moved by more than 1 px): where the figures agree, whether the skeletons do;
* **frames/s**: frames over the detection's wall time (decoding included, model
  loading and the one-time import of ``scipy.sparse`` not), under whatever else the machine runs (the load average is
  written); **CPU ms a frame**: the process's CPU time (all threads) a frame, which
  other jobs change far less: on an idle machine the wall time a frame is about
  that (the models' runtime measured no faster with 2 threads than with 1).

Clips (100 frames each unless ``--frames``): the eight Demo_SinglePerson and
Demo_MultiPerson videos of the ``pose2sim`` wheel (1080 x 1920, 60 fps; one or
two subjects); ``mirror1080``: Demo_SinglePerson cam01 composited into a
1920 x 1080 mirror scene (:class:`mirrorgraph.synth.mirror_clip.MirrorComposite`:
the person at half scale and a flipped 0.4x, 0.6x as bright copy: one person and
one reflection, plus the bystander and theirs); ``planar``: the tests' planar
mirror clip (:class:`mirrorgraph.synth.mirror_clip.PlanarMirrorClip`, 840 x 960).

Usage::

    python bench/bench_video.py                       # ~15 min on 2 cores
    python bench/bench_video.py --clips mirror1080 --frames 60 --no-write

Writes ``bench/RESULTS_video.md`` (machine, command, date, table), or ``--out FILE``.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import datetime  # noqa: E402
import importlib.util  # noqa: E402
import json  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

from _report import header  # noqa: E402  (one header for every results file)

#: clip -> (subjects, bystanders in view at most)
DEMO_PEOPLE = {"cam01": 1, "cam02": 2, "cam03": 0, "cam04": 0}


def _demo_root() -> Path:
    spec = importlib.util.find_spec("Pose2Sim")
    if spec is None:
        sys.exit("pose2sim is not installed (pip install --no-deps pose2sim==0.10.49)")
    return Path(list(spec.submodule_search_locations)[0])


def _write_clip(path: Path, frames, fps: float) -> Path:
    import cv2
    h, w = frames[0].shape[:2]
    out = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (w, h))
    for f in frames:
        out.write(np.ascontiguousarray(f[..., ::-1]))
    out.release()
    return path


def _read(path: Path, n: int):
    import cv2
    cap = cv2.VideoCapture(str(path))
    out = []
    while len(out) < n:
        ok, bgr = cap.read()
        if not ok:
            break
        out.append(np.ascontiguousarray(bgr[..., ::-1]))
    cap.release()
    return out


def clips(names: list[str], frames: int, folder: Path) -> list[tuple[str, Path, int, int]]:
    """``(name, video, subjects, most people)`` of the clips asked for (composites
    written into ``folder``)."""
    demo = _demo_root()
    out = []
    for name in names:
        if name == "mirror1080":
            from mirrorgraph.synth.mirror_clip import MirrorComposite
            comp = MirrorComposite()
            src = _read(demo / "Demo_SinglePerson" / "videos" / "cam01.mp4", frames)
            out.append((name, _write_clip(folder / "mirror1080.mp4",
                                          [comp.compose(f) for f in src], 30.0), 2, 4))
        elif name == "planar":
            import cv2
            from mirrorgraph.io.qualisys import read_qca
            from mirrorgraph.synth.mirror_clip import PlanarMirrorClip
            trial = demo / "Demo_SinglePerson"
            K = np.diag([0.5, 0.5, 1.0]) @ read_qca(
                trial / "calibration" / "Calib.qca.txt")["cam01"].K
            a = np.radians(70)
            clip = PlanarMirrorClip(K=K, normal=np.array([np.sin(a), 0.0, np.cos(a)]),
                                    distance=1.6, depth=2.9, width=840, split=420)
            src = _read(trial / "videos" / "cam01.mp4", frames)
            out.append((name, _write_clip(folder / "planar.mp4", [clip.compose(
                cv2.resize(f, (540, 960), interpolation=cv2.INTER_AREA)) for f in src], 30.0),
                2, 2 + DEMO_PEOPLE["cam01"]))
        else:
            trial, cam = name.split("/")
            subjects = 2 if trial == "Demo_MultiPerson" else 1
            video = demo / trial / "videos" / f"{cam}.mp4"
            out.append((name, video, subjects, subjects + DEMO_PEOPLE[cam]))
    return out


# --------------------------------------------------------------------------- in view
#: The joints the in-view rule counts: torso and limbs (shoulders, elbows, wrists, hips,
#: knees, ankles). The face's 11 landmarks and the hands' and feet's 10 would give a
#: head or a foot the weight of half a body.
VIEW_JOINTS = ("left_shoulder", "right_shoulder", "left_elbow", "right_elbow", "left_wrist",
               "right_wrist", "left_hip", "right_hip", "left_knee", "right_knee",
               "left_ankle", "right_ankle")

#: A person is in view where more than this share of their :data:`VIEW_JOINTS` (of those
#: triangulated) project inside the image and are not hidden behind a nearer person.
IN_VIEW_SHARE = 0.5

#: A body's outline: capsules ``(joint, joint, radius m)`` around the bones (radii of an
#: adult's limbs: upper arm, forearm, thigh, shank; the torso's sides and the neck a
#: little wider than the joint centres), and the head a ball of 0.11 m about the ears'
#: midpoint; the torso's quadrilateral (shoulders, hips) is filled.
BODY_CAPSULES = (("left_shoulder", "left_elbow", 0.05), ("right_shoulder", "right_elbow", 0.05),
                 ("left_elbow", "left_wrist", 0.04), ("right_elbow", "right_wrist", 0.04),
                 ("left_hip", "left_knee", 0.08), ("right_hip", "right_knee", 0.08),
                 ("left_knee", "left_ankle", 0.06), ("right_knee", "right_ankle", 0.06),
                 ("left_shoulder", "right_shoulder", 0.07), ("left_hip", "right_hip", 0.07),
                 ("left_shoulder", "left_hip", 0.07), ("right_shoulder", "right_hip", 0.07))
HEAD_RADIUS = 0.11
TORSO = ("left_shoulder", "right_shoulder", "right_hip", "left_hip")

#: A group of detections (one a camera) is one person where the median reprojection
#: error of its triangulated :data:`VIEW_JOINTS` is under this (px, 1088 x 1920 video;
#: the same person in cam01, cam02, cam04 of Demo_MultiPerson: 5-27 px, the Qualisys
#: cameras and the detector's bias; two people: 31 px and more, mostly above 80).
GROUP_PX = 40.0

#: A detection is a reference person's where the median distance of their
#: :data:`VIEW_JOINTS` (left/right as labelled or swapped, the nearer) is under this share
#: of the person's projected height.
DETECTION_SHARE = 0.2

#: A triangulated body whose lower ankle is higher than this above the floor (m; the
#: Qualisys world's z = 0) stands on nothing: two detections of different things that
#: happen to meet (the subjects' ankles: 0.05-0.41 m, jumping included).
FLOOR_M = 0.5

#: Two triangulated bodies whose torso and limb joints lie a median of less than this
#: apart (m) are one person (a second group made of a duplicate detection).
SAME_M = 0.3

#: A triangulated body with a bone of :data:`BODY_CAPSULES` longer than this (m) is not one
#: person (the subjects' longest, a torso's side: 0.55 m).
BONE_M = 0.7

#: A joint triangulated from views whose rays meet at less than this (deg) has no depth.
MIN_ANGLE_DEG = 10.0


def _qualisys(trial: str) -> dict:
    from mirrorgraph.io.qualisys import read_qca
    return read_qca(_demo_root() / trial / "calibration" / "Calib.qca.txt")


def _undistorted(cam, people: np.ndarray, min_confidence: float) -> np.ndarray:
    """``(P, J, 2)`` undistorted pixels of a frame's detections, NaN where unsure."""
    from mirrorgraph.intrinsics import Intrinsics
    from mirrorgraph.skeletons import BLAZEPOSE
    kp = np.asarray(people, float).reshape(-1, BLAZEPOSE.num_joints, 3)
    xy = Intrinsics(cam.K, cam.dist).undistort_points(kp[..., :2])
    return np.where(((kp[..., 2] >= min_confidence) & np.isfinite(xy).all(-1))[..., None],
                    xy, np.nan)


def people_3d(detections: dict[str, list[np.ndarray]], cams: dict, views: list[str]
              ) -> list[np.ndarray]:
    """Per frame ``(P, J, 3)`` the people seen by two or more of ``views`` (world, m).

    Every group of one detection a view (or none; two views at least) is triangulated
    with the Qualisys cameras (:func:`mirrorgraph.geometry.triangulate`) and scored by
    the median reprojection error of its :data:`VIEW_JOINTS`; groups are taken greedily,
    most views first, then the lowest error, under :data:`GROUP_PX`, no detection in two
    (three views decide: two people of one height lie on about the same epipolar
    lines of two level cameras, a third camera tells them apart; a group of three only
    where every two of its views agree too: a detection half on the other person can
    hide in the median of three), and standing
    (:data:`FLOOR_M`), with human bones (:data:`BONE_M`; half its torso and limb joints
    triangulated at least). A chosen group's joint that one of its views places
    elsewhere (a detection half on the other person scatters some joints) is
    triangulated from the views that agree on it (:func:`_robust_joints`).
    """
    import itertools
    import warnings

    from mirrorgraph.geometry import triangulate
    from mirrorgraph.keypoints import DEFAULT_MIN_CONFIDENCE
    from mirrorgraph.skeletons import BLAZEPOSE
    J = BLAZEPOSE.num_joints
    main = [BLAZEPOSE.index(n) for n in VIEW_JOINTS]
    ankles = [BLAZEPOSE.index(n) for n in ("left_ankle", "right_ankle")]
    capsules = [(BLAZEPOSE.index(a), BLAZEPOSE.index(b)) for a, b, _ in BODY_CAPSULES]
    P = [cams[v].projection for v in views]
    T = min(len(detections[v]) for v in views)

    def reprojection(X, pix):                       # V x (G, J, 2) -> (V, G, J)
        Xh = np.concatenate([X, np.ones(X.shape[:-1] + (1,))], -1)
        return np.stack([np.linalg.norm(h[..., :2] / h[..., 2:] - u, axis=-1) for h, u in
                         ((np.einsum("ab,gjb->gja", Pi, Xh), u) for Pi, u in zip(P, pix))])

    out = []
    for t in range(T):
        uv = [_undistorted(cams[v], detections[v][t], DEFAULT_MIN_CONFIDENCE) for v in views]
        groups = [g for g in itertools.product(*[range(-1, len(u)) for u in uv])
                  if sum(k >= 0 for k in g) >= 2]
        if not groups:
            out.append(np.zeros((0, J, 3)))
            continue
        none = np.full((J, 2), np.nan)
        pix = [np.stack([uv[i][g[i]] if g[i] >= 0 else none for g in groups])
               for i in range(len(views))]                                    # V x (G, J, 2)
        X, ok = triangulate(P, pix)                                           # (G, J, 3)
        err = reprojection(X, pix)[:, :, main].transpose(1, 0, 2).reshape(len(groups), -1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            cost = np.nanmedian(err, axis=1)
            floor = np.nanmin(X[:, ankles, 2], axis=1)
        cost = np.where((ok[:, main].sum(1) >= len(main) // 2) & (floor < FLOOR_M), cost, np.inf)
        nviews = np.array([sum(k >= 0 for k in g) for g in groups])
        pair = {g: c for g, c, n in zip(groups, cost, nviews) if n == 2}
        for k in np.flatnonzero(nviews > 2):          # every two of its views agree too
            have = [i for i, g in enumerate(groups[k]) if g >= 0]
            for a, b in itertools.combinations(have, 2):
                sub = tuple(g if i in (a, b) else -1 for i, g in enumerate(groups[k]))
                cost[k] = max(cost[k], pair[sub])
        used: set[tuple[int, int]] = set()
        people = []
        for k in np.lexsort((cost, -nviews)):
            if not cost[k] <= GROUP_PX:
                continue
            mine = {(i, g) for i, g in enumerate(groups[k]) if g >= 0}
            if mine & used:
                continue
            X_k = _robust_joints([p[k] for p in pix], P, reprojection)
            bones = np.linalg.norm(X_k[[a for a, _ in capsules]] - X_k[[b for _, b in capsules]],
                                   axis=-1)
            if (bones > BONE_M).any() or np.isfinite(X_k[main]).all(-1).sum() < len(main) // 2:
                continue                            # no body: parts of two people, or too few
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                if any(np.nanmedian(np.linalg.norm(X_k[main] - q[main], axis=-1)) < SAME_M
                       for q in people):
                    continue                        # the same body from other detections
            used |= mine
            people.append(X_k)
        out.append(np.array(people).reshape(-1, J, 3))
    return out


def _robust_joints(pix: list[np.ndarray], P: list[np.ndarray], reprojection) -> np.ndarray:
    """``(J, 3)``: each joint triangulated from all the group's views, or where some
    view reprojects it farther than :data:`GROUP_PX`, from the most views that all
    reproject it within that and whose rays meet at :data:`MIN_ANGLE_DEG` or more; NaN
    where no such views (Demo_MultiPerson: cam02 and cam04 face each other across the
    room, the man often on the line between them)."""
    import itertools

    from mirrorgraph.geometry import triangulate
    have = [i for i, u in enumerate(pix) if np.isfinite(u).any()]
    centres = [-np.linalg.solve(p[:, :3], p[:, 3]) for p in P]
    best = None
    agree = None
    for n in range(len(have), 1, -1):
        for sub in itertools.combinations(have, n):
            u = [p[None] if i in sub else np.full_like(p, np.nan)[None] for i, p in enumerate(pix)]
            X, ok = triangulate(P, u)
            good = ok[0] & (np.nan_to_num(reprojection(X, u)[:, 0], nan=0.0) <= GROUP_PX).all(0)
            rays = np.stack([X[0] - c for c in (centres[i] for i in sub)])      # (n, J, 3)
            rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
            cos = np.abs(np.einsum("ajk,bjk->abj", rays, rays)).min(axis=(0, 1))
            good &= cos < np.cos(np.radians(MIN_ANGLE_DEG))   # depth determined
            if best is None:
                best, agree = X[0].copy(), good.copy()
                continue
            take = good & ~agree
            best[take], agree[take] = X[0][take], True
    best[~agree] = np.nan           # no two views agree on it, or they look along one line
    return best


def _segment_hits(p: np.ndarray, a: np.ndarray, b: np.ndarray, za, zb, radius_px
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Points ``p (N, 2)`` within the capsule ``a-b`` (radius px at each end, linear), and
    the capsule's depth at the nearest point of its axis."""
    ab = b - a
    s = np.clip(((p - a) @ ab) / max(float(ab @ ab), 1e-9), 0.0, 1.0)
    d = np.linalg.norm(p - (a + s[:, None] * ab), axis=1)
    return d <= radius_px[0] + s * (radius_px[1] - radius_px[0]), za + s * (zb - za)


def visible_joints(X: np.ndarray, cam, order: int = 1
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For the people ``X (P, J, 3)`` (world, m) of one frame seen from ``cam``: ``(P, J)``
    bools inside the image (the lens' distortion applied), hidden behind another
    person (the joint falls within that person's projected outline, :data:`BODY_CAPSULES`
    and the filled torso, and that person's outline is nearer there; ``order=-1``: farther,
    the picture of a renderer that draws the farther person over the nearer), and the
    ``(P, J, 2)`` pixels (distorted)."""
    from mirrorgraph.skeletons import BLAZEPOSE
    from mirrorgraph.synth.camera import distort_pixels
    idx = BLAZEPOSE.index
    Xc = np.einsum("ab,pjb->pja", cam.R, X) + cam.t
    z = Xc[..., 2]
    with np.errstate(all="ignore"):
        u = np.einsum("ab,pjb->pja", cam.K, Xc)
        u = u[..., :2] / u[..., 2:]
    w, h = cam.size
    px = distort_pixels(cam.K, cam.dist, u)
    inside = (z > 0) & (px[..., 0] >= 0) & (px[..., 0] < w) & (px[..., 1] >= 0) & \
        (px[..., 1] < h)
    hidden = np.zeros(z.shape, bool)
    f = float(cam.K[0, 0])
    import cv2
    for p in range(len(X)):
        pts = u[p]
        known = np.isfinite(pts).all(-1)
        for q in range(len(X)):
            if q == p:
                continue
            cover = np.zeros(len(pts), bool)
            for a, b, r in BODY_CAPSULES:
                ia, ib = idx(a), idx(b)
                if not (np.isfinite(u[q, [ia, ib]]).all() and z[q, ia] > 0 and z[q, ib] > 0):
                    continue
                hit, depth = _segment_hits(np.nan_to_num(pts), u[q, ia], u[q, ib], z[q, ia],
                                           z[q, ib], f * r / z[q, [ia, ib]])
                cover |= hit & (order * (z[p] - depth) > 0)
            ears = [idx("left_ear"), idx("right_ear")]
            if np.isfinite(u[q, ears]).all():
                c, zc = u[q, ears].mean(0), z[q, ears].mean()
                cover |= (np.linalg.norm(np.nan_to_num(pts) - c, axis=1) <= f * HEAD_RADIUS / zc) \
                    & (order * (z[p] - zc) > 0)
            quad = [idx(n) for n in TORSO]
            if np.isfinite(u[q, quad]).all():
                poly = u[q, quad].astype(np.float32).reshape(-1, 1, 2)
                inq = np.array([cv2.pointPolygonTest(poly, (float(x), float(y)), False) >= 0
                                for x, y in np.nan_to_num(pts)])
                cover |= inq & (order * (z[p] - z[q, quad].mean()) > 0)
            hidden[p] |= cover & known
    return inside, hidden, px


def in_view(people: list[np.ndarray], cam) -> list[dict]:
    """Per frame, the people of ``people`` (world, m) in view of ``cam``: ``in_view``
    ``(P,)`` bool (more than :data:`IN_VIEW_SHARE` of their triangulated
    :data:`VIEW_JOINTS` inside the image and not hidden behind a nearer person),
    ``share`` ``(P,)``, ``xy`` ``(P, J, 2)`` the projected joints (distorted px),
    ``hidden`` ``(P, J)``; ``certain`` and ``possible`` ``(P,)``: in view whichever of two
    overlapping people is drawn in front (the Demo videos are rendered avatars, and
    cam03's draws the woman over the man where he is a metre nearer), and fewer than
    half of the joints triangulated (possible only) or in view in either order."""
    from mirrorgraph.skeletons import BLAZEPOSE
    main = [BLAZEPOSE.index(n) for n in VIEW_JOINTS]
    out = []
    for X in people:
        known = np.isfinite(X[:, main]).all(-1)
        res = {}
        for order in (1, -1):
            inside, hidden, px = visible_joints(X, cam, order)
            seen = (inside & ~hidden)[:, main] & known
            res[order] = (seen.sum(1) / np.maximum(known.sum(1), 1), hidden)
        share, hidden = res[1]
        enough = known.sum(1) >= len(main) // 2
        out.append({"in_view": share > IN_VIEW_SHARE, "share": share, "xy": px,
                    "hidden": hidden, "share_reversed": res[-1][0],
                    "certain": enough & (np.minimum(share, res[-1][0]) > IN_VIEW_SHARE),
                    "possible": ~enough | (np.maximum(share, res[-1][0]) > IN_VIEW_SHARE)})
    return out


def match_detections(ref_xy: np.ndarray, detections: np.ndarray) -> np.ndarray:
    """``(P,)`` the detection index of each reference person (``-1``: none): Hungarian
    assignment on the median distance of their :data:`VIEW_JOINTS` (the detection's
    labels as they are or left/right swapped, the nearer), under
    :data:`DETECTION_SHARE` of the person's projected height."""
    from scipy.optimize import linear_sum_assignment

    from mirrorgraph.keypoints import DEFAULT_MIN_CONFIDENCE
    from mirrorgraph.skeletons import BLAZEPOSE
    main = np.array([BLAZEPOSE.index(n) for n in VIEW_JOINTS])
    out = np.full(len(ref_xy), -1)
    if not len(ref_xy) or not len(detections):
        return out
    det = np.where((detections[..., 2] >= DEFAULT_MIN_CONFIDENCE)[..., None],
                   detections[..., :2], np.nan)
    cost = np.full((len(ref_xy), len(det)), np.inf)
    for p, r in enumerate(ref_xy):
        size = np.nanmax(r[main, 1]) - np.nanmin(r[main, 1])
        for d, x in enumerate(det):
            with np.errstate(all="ignore"):
                import warnings
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)
                    m = min(np.nanmedian(np.linalg.norm(x[main] - r[main], axis=1)),
                            np.nanmedian(np.linalg.norm(x[BLAZEPOSE.flip][main] - r[main],
                                                        axis=1)))
            if m <= DETECTION_SHARE * size:
                cost[p, d] = m
    ok = np.isfinite(cost)
    rows, cols = linear_sum_assignment(np.where(ok, cost, 1e9))
    for a, b in zip(rows, cols):
        if ok[a, b]:
            out[a] = b
    return out


def multi_person_reference(frames: int, trial: str = "Demo_MultiPerson", subjects: int = 2
                           ) -> dict[str, dict]:
    """Per camera of ``trial``, the people in view frame by frame, from the other
    cameras: each camera's video detected (this tree's :func:`detect_video`, defaults), the
    people of the others matched and triangulated (:func:`people_3d`), projected into it
    (:func:`in_view`). ``{camera: {"count": (T,) in view, "lo": (T,) certainly, "hi":
    (T,) possibly (a subject not triangulated, of ``subjects``, possibly), "untriangulated":
    (T,), "frames": [in_view() per frame], "people": [(P, J, 3) per frame]}}``."""
    from mirrorgraph.video import VideoOptions, detect_video
    cams = _qualisys(trial)
    names = list(cams)
    dets = {n: detect_video(_demo_root() / trial / "videos" / f"{n}.mp4",
                            VideoOptions(end=frames, cache=False)).people for n in names}
    out = {}
    for n in names:
        people = people_3d(dets, cams, [v for v in names if v != n])
        views = in_view(people, cams[n])
        out[n] = {"count": np.array([int(v["in_view"].sum()) for v in views]),
                  "lo": np.array([int(v["certain"].sum()) for v in views]),
                  "hi": np.array([int(v["possible"].sum()) + max(subjects - len(v["xy"]), 0)
                                  for v in views]),
                  "untriangulated": np.array([max(subjects - len(v["xy"]), 0) for v in views]),
                  "frames": views, "people": people}
    return out


def worker(video: str, frames: int, out: str) -> None:
    """Detect one clip with the ``mirrorgraph`` on ``sys.path``; save what was found."""
    import mirrorgraph
    from mirrorgraph.video import VideoOptions, detect_video
    from mirrorgraph.video.blazepose import BlazePoseModels
    BlazePoseModels()                                   # model loading out of the timing
    import scipy.sparse  # noqa: F401  (imported by the first letterbox: 0.2 s, 2 ms a frame of 100)
    t0, c0 = time.perf_counter(), time.process_time()
    det = detect_video(video, VideoOptions(end=frames, cache=False))      # its defaults
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    counts = np.array([len(p) for p in det.people])
    J = det.skeleton.num_joints
    np.savez(out, counts=counts, seconds=seconds, cpu=cpu,
             keypoints=np.concatenate(det.people) if counts.sum() else np.zeros((0, J, 3)),
             track_ids=np.concatenate(det.track_ids) if counts.sum() else np.zeros(0, int),
             package=str(Path(mirrorgraph.__file__).parent),
             stats=json.dumps(det.stats))


def _run(package_root: Path, video: Path, frames: int, tmp: Path, tag: str) -> dict:
    out = tmp / f"{tag}.npz"
    env = dict(os.environ, PYTHONPATH=str(package_root))
    subprocess.run([sys.executable, str(Path(__file__).resolve()), "--worker", str(video),
                    str(frames), str(out)], check=True, env=env, cwd=str(tmp))
    with np.load(out, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def reference_figures(counts: np.ndarray, people: list[np.ndarray], ref: dict,
                      subjects: int, bystanders: int) -> dict:
    """A run against the per-frame reference (:func:`multi_person_reference`): frames whose
    count lies in ``[in view, in view + bystanders]`` (``in_range_depth``: the nearer person
    hides the farther) and in ``[certainly in view, possibly in view + bystanders]``
    (``in_range_ref``: whichever is drawn in front, :func:`in_view`); frames where a person
    certainly in view has no detection on them (:func:`match_detections`), frames with
    more detections than people possibly in view plus bystanders (their numbers), and
    the share of frames with neither (``right``)."""
    T = min(len(counts), len(ref["count"]))
    n, lo, hi = ref["count"][:T], ref["lo"][:T], ref["hi"][:T]
    c = counts[:T]
    missed = [t for t in range(T) if (match_detections(
        ref["frames"][t]["xy"][ref["frames"][t]["certain"]], people[t]) < 0).any()]
    return {"in_range_depth": float(np.mean((c >= n) & (c <= n + bystanders))),
            "in_range_ref": float(np.mean((c >= lo) & (c <= hi + bystanders))),
            "ref_not_subjects": int(np.sum((lo != subjects) | (hi != subjects))),
            "depth_not_subjects": int(np.sum(n != subjects)),
            "untriangulated": int(np.sum(ref["untriangulated"][:T] > 0)),
            "missed": missed, "extra": np.flatnonzero(c > hi + bystanders).tolist(),
            "right": float(np.mean([t not in missed and c[t] <= hi[t] + bystanders
                                    for t in range(T)])) if T else 0.0}


def figures(res: dict, lo: int, hi: int, ref: dict | None = None) -> dict:
    """People a frame, duplicates, tracks and speed of one run (see the module docstring);
    with ``ref``, against the per-frame reference too (:func:`reference_figures`)."""
    from mirrorgraph.skeletons import BLAZEPOSE
    from mirrorgraph.video.nms import pose_nms
    counts = res["counts"]
    people = np.split(res["keypoints"], np.cumsum(counts)[:-1])
    dup = 0
    for kp in people:
        if len(kp) >= 2:
            seen = np.isfinite(kp[..., :2]).all(-1)
            xy = np.where(seen[..., None], kp[..., :2], np.nanmean(kp[..., :2], axis=1,
                                                                   keepdims=True))
            dup += len(pose_nms(xy, np.where(seen, kp[..., 2], 0.0), flip=BLAZEPOSE.flip)) \
                < len(kp)
    T = len(counts)
    extra = reference_figures(counts, people, ref, lo, hi - lo) if ref is not None else {}
    return {**extra, "frames": T, "in_range": float(np.mean((counts >= lo) & (counts <= hi))),
            "mean": float(counts.mean()), "max": int(counts.max()) if T else 0,
            "dup_frames": dup, "tracks": len(np.unique(res["track_ids"])),
            "fps": T / float(res["seconds"]), "cpu_ms": 1000 * float(res["cpu"]) / T,
            "stats": json.loads(str(res["stats"]))}


def changed_frames(before: dict, after: dict, px: float = 1.0) -> int:
    """Frames whose poses differ between two runs: another count, or a keypoint (of the
    poses in the order found) more than ``px`` away or seen in one run only (the
    detection is deterministic: one tree run twice gives the same keypoints)."""
    cb, ca = before["counts"], after["counts"]
    pb = np.split(before["keypoints"], np.cumsum(cb)[:-1])
    pa = np.split(after["keypoints"], np.cumsum(ca)[:-1])
    n = 0
    for x, y in zip(pb, pa):
        if len(x) != len(y):
            n += 1
            continue
        if not len(x):
            continue
        ok = np.isfinite(x[..., :2]).all(-1)
        if (ok != np.isfinite(y[..., :2]).all(-1)).any() or \
                (np.abs(x[..., :2] - y[..., :2])[ok] > px).any():
            n += 1
    return n + abs(len(cb) - len(ca))


def _git(*args: str) -> str:
    return subprocess.run(["git", "-C", str(ROOT), *args], check=True, capture_output=True,
                          text=True).stdout.strip()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--before", default="main", help="git revision of the 'before' package")
    ap.add_argument("--clips", nargs="+", default=[
        "mirror1080", "planar", *(f"{t}/cam0{i}" for t in ("Demo_SinglePerson",
                                                            "Demo_MultiPerson")
                                  for i in range(1, 5))])
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--draw", type=Path, metavar="DIR",
                    help="write PNGs of the Demo_MultiPerson frames where the per-frame "
                         "reference is not the subjects' count or the 'after' run is out of "
                         "its range: the reference's projected skeletons and the detections")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "RESULTS_video.md",
                    help="the results file (default bench/RESULTS_video.md)")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT))                       # this tree's mirrorgraph for the figures
    before_rev = _git("rev-parse", "--short", args.before)
    after_rev = _git("rev-parse", "--short", "HEAD")
    dirty = bool(_git("status", "--porcelain", "--", "mirrorgraph"))
    rows, loads = [], []
    started = datetime.datetime.now(datetime.timezone.utc)
    with tempfile.TemporaryDirectory(prefix="bench_video_") as t:
        tmp = Path(t)
        old = tmp / "before"
        old.mkdir()
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", before_rev, "mirrorgraph"],
                                 check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(old)], input=archive, check=True)
        refs: dict[str, dict] = {}
        for name, video, lo, hi in clips(args.clips, args.frames, tmp):
            ref = None
            if name.startswith("Demo_MultiPerson/"):
                if not refs:
                    print("... the people in view of each Demo_MultiPerson camera, from the "
                          "others", flush=True)
                    refs.update(multi_person_reference(args.frames))
                ref = refs[name.split("/")[1]]
            got, raw = {}, {}
            for side, root in (("before", old), ("after", ROOT)):
                res = raw[side] = _run(root, video, args.frames, tmp, side)
                got[side] = figures(res, lo, hi, ref)
                if args.draw and ref is not None and side == "after":
                    draw_frames(args.draw, name, video, res, ref, lo, hi)
            got["after"]["changed"] = changed_frames(raw["before"], raw["after"])
            rows.append((name, lo, hi, got))
            b, a = got["before"], got["after"]
            print(f"{name:28s} people {lo}-{hi}: in range {b['in_range']:6.1%} -> "
                  f"{a['in_range']:6.1%}, mean {b['mean']:.2f} -> {a['mean']:.2f}, dup frames "
                  f"{b['dup_frames']} -> {a['dup_frames']}, tracks {b['tracks']} -> "
                  f"{a['tracks']}, frames whose poses changed {a['changed']}, "
                  f"{b['fps']:.1f} -> {a['fps']:.1f} frames/s, CPU "
                  f"{b['cpu_ms']:.0f} -> {a['cpu_ms']:.0f} ms a frame (load "
                  f"{os.getloadavg()[0]:.1f})", flush=True)
            if ref is not None:
                print(f"{'':28s} per-frame reference: in range {b['in_range_ref']:6.1%} -> "
                      f"{a['in_range_ref']:6.1%} (the nearer hides: {b['in_range_depth']:6.1%} "
                      f"-> {a['in_range_depth']:6.1%}); frames with a person in view missed "
                      f"{_ranges(b['missed'])} -> {_ranges(a['missed'])}; with more than the "
                      f"people in view and bystanders {_ranges(b['extra'])} -> "
                      f"{_ranges(a['extra'])}; neither {b['right']:.0%} -> {a['right']:.0%}",
                      flush=True)
            loads.append(os.getloadavg()[0])
    lines = [
        "# Video detection: people a frame, tracks, speed (before / after)", "",
        *header(started=f"{started:%Y-%m-%d %H:%M} UTC", argv=argv, script="bench_video.py",
                bullet="-", note="shared with other jobs: frames/s are of one run under that "
                "load, before and after side by side; load average "
                f"{min(loads):.1f}-{max(loads):.1f} during the run"),
        f"- before: `{before_rev}` ({args.before}); after: `{after_rev}`"
        + (" + uncommitted changes" if dirty else ""),
        f"- {args.frames} frames a clip, BlazePose with each version's default options "
        "(its LiteRT threads included), no cache", "",
        "| clip | people (subjects-most) | in range | mean a frame | max | frames with "
        "duplicates | tracks | frames whose poses changed | frames/s | CPU ms a frame | "
        "detector runs | landmark runs |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, lo, hi, got in rows:
        b, a = got["before"], got["after"]
        lines.append(
            f"| {name} | {lo}-{hi} | {b['in_range']:.0%} / **{a['in_range']:.0%}** | "
            f"{b['mean']:.2f} / {a['mean']:.2f} | {b['max']} / {a['max']} | "
            f"{b['dup_frames']} / {a['dup_frames']} | {b['tracks']} / {a['tracks']} | "
            f"{a['changed']} | "
            f"{b['fps']:.1f} / **{a['fps']:.1f}** | {b['cpu_ms']:.0f} / {a['cpu_ms']:.0f} | "
            f"{b['stats'].get('detector_runs', '')} / "
            f"{a['stats'].get('detector_runs', '')} | {b['stats'].get('landmark_runs', '')} / "
            f"{a['stats'].get('landmark_runs', '')} |")
    lines += ["", "Each cell: before / after. See the docstring of `bench/bench_video.py` for "
              "what each figure is."]
    with_ref = [(name, lo, hi, got) for name, lo, hi, got in rows if "in_range_ref" in
                got["after"]]
    if with_ref:
        lines += ["", "## Demo_MultiPerson against the people in view, frame by frame", "",
                  "The reference of each camera from the other three (`multi_person_reference`"
                  ": the people detected there, matched and triangulated with the Qualisys "
                  "cameras, projected; a person is in view where more than "
                  f"{IN_VIEW_SHARE:.0%} of their torso and limb joints are in the image and not "
                  "within the other person's projected outline where that one is in front). "
                  "*Nearer in front*: in range where the count lies between the people in view "
                  "and those plus the bystanders, the nearer person hiding the farther. "
                  "*Per-frame reference*: between the people in view whichever of two is "
                  "drawn in front (and with half their joints or more triangulated) and those "
                  "in view in either order (or not triangulated well enough) plus the "
                  "bystanders: the renderer of these videos draws one person over the other "
                  "regardless of depth (see the notes). Missed: a person in view in both "
                  "orders with no detection whose torso and limb joints lie within "
                  f"{DETECTION_SHARE:.0%} of their height (median).", "",
                  "| clip | in range, fixed count (as above) | in range, nearer in front | "
                  "in range, per-frame reference | frames whose reference is not the "
                  "subjects' count (nearer in front / reference) | frames with a person in "
                  "view missed | frames with more than the people in view + bystanders | "
                  "frames with neither |",
                  "|---|---|---|---|---|---|---|---|"]

        def frames_(x):
            return f"{len(x)}" + (f" ({_ranges(x)})" if x else "")
        for name, lo, hi, got in with_ref:
            b, a = got["before"], got["after"]
            lines.append(
                f"| {name} | {b['in_range']:.0%} / **{a['in_range']:.0%}** | "
                f"{b['in_range_depth']:.0%} / {a['in_range_depth']:.0%} | "
                f"{b['in_range_ref']:.0%} / **{a['in_range_ref']:.0%}** | "
                f"{a['depth_not_subjects']} / {a['ref_not_subjects']} | "
                f"{frames_(b['missed'])} / {frames_(a['missed'])} | "
                f"{frames_(b['extra'])} / {frames_(a['extra'])} | "
                f"{b['right']:.0%} / **{a['right']:.0%}** |")
    text = "\n".join(lines) + "\n"
    print(text)
    if not args.no_write:
        args.out.write_text(text)
    return 0


def _ranges(frames: list[int]) -> str:
    """``[3, 4, 5, 9]`` -> ``"3-5, 9"``."""
    out, start = [], None
    for i, f in enumerate(frames):
        if start is None:
            start = f
        if i + 1 == len(frames) or frames[i + 1] != f + 1:
            out.append(f"{start}" if start == f else f"{start}-{f}")
            start = None
    return ", ".join(out)


def draw_frames(folder: Path, name: str, video: Path, res: dict, ref: dict, lo: int,
                hi: int) -> None:
    """PNGs (half size) of the frames where the reference is not the subjects' count
    ``lo`` or the run's count is out of the reference's range: the reference's people
    projected (colour a person, filled red where hidden, their share of joints in view
    written), the detections in white."""
    import cv2

    from mirrorgraph.skeletons import BLAZEPOSE
    folder.mkdir(parents=True, exist_ok=True)
    counts = res["counts"]
    people = np.split(res["keypoints"], np.cumsum(counts)[:-1])
    bones = [(BLAZEPOSE.index(a), BLAZEPOSE.index(b)) for a, b, _ in BODY_CAPSULES]
    main = [BLAZEPOSE.index(n) for n in VIEW_JOINTS]
    want = {t for t in range(min(len(counts), len(ref["count"])))
            if ref["count"][t] != lo or not (ref["count"][t] <= counts[t] <=
                                              ref["count"][t] + hi - lo)}
    cap = cv2.VideoCapture(str(video))
    colours = [(0, 200, 255), (255, 100, 0), (0, 255, 0), (255, 0, 255)]
    t = 0
    while want and t <= max(want):
        ok, img = cap.read()
        if not ok:
            break
        if t in want:
            v = ref["frames"][t]
            for p, xy in enumerate(v["xy"]):
                c = colours[p % len(colours)]
                for a, b in bones:
                    if np.isfinite(xy[[a, b]]).all():
                        cv2.line(img, tuple(map(int, xy[a])), tuple(map(int, xy[b])), c, 4)
                for j in main:
                    if np.isfinite(xy[j]).all():
                        cv2.circle(img, tuple(map(int, xy[j])), 10,
                                   (0, 0, 255) if v["hidden"][p, j] else c,
                                   -1 if v["hidden"][p, j] else 3)
                cv2.putText(img, f"person {p}: {v['share'][p]:.0%} of joints in view, "
                            f"{'in view' if v['in_view'][p] else 'not in view'}",
                            (20, 60 + 60 * p), 0, 1.4, c, 3)
            for d in people[t]:
                for a, b in bones:
                    if (d[[a, b], 2] >= 0.3).all():
                        cv2.line(img, tuple(map(int, d[a, :2])), tuple(map(int, d[b, :2])),
                                 (255, 255, 255), 2)
            cv2.putText(img, f"{name} frame {t}: {len(people[t])} detections, "
                        f"{ref['count'][t]} in view", (20, img.shape[0] - 30), 0, 1.3,
                        (255, 255, 255), 3)
            cv2.imwrite(str(folder / f"{name.replace('/', '_')}_{t:03d}.png"),
                        cv2.resize(img, (img.shape[1] // 2, img.shape[0] // 2)))
        t += 1
    cap.release()


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[1] == "--worker":
        worker(sys.argv[2], int(sys.argv[3]), sys.argv[4])
        sys.exit(0)
    sys.exit(main())
