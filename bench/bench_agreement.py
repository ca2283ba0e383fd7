"""Annotations against video: one mirror clip calibrated from a detector's files and from its frames.

Issue #24's last deliverable: on real clips, the calibration from the video
(mirrorgraph's BlazePose path) should lie within the stated uncertainty of the one
from the annotations, and where BlazePose places joints differently from OpenPose,
this script measures the shift and what it does to the focal length and the distance.

**Clips.** The Pose2Sim demo trial ``Demo_SinglePerson`` (the ``pose2sim`` 0.10.49
wheel: 4 cameras, 100 frames, 1080 x 1920 at 60 fps, Qualisys calibration) is the
only real footage here with another detector's keypoints: OpenPose BODY_25B JSON of
its 4 cameras, published in Pose2Sim's git history (commit ``a4d38da``,
``Pose2Sim/Demo/S00_Demo_Session/S00_P00_Participant/S00_P00_T01_BalancingTrial/
pose/cam0N_json``; the wheel ships the videos only). No real mirror clip with a
person, a free licence and a second detector's keypoints was found in a package or
repository reachable here (the Mirrored-Human clips of Fang et al. are internet videos
behind a download link, their licence unstated). Two kinds of composite, every frame
at half the source's resolution (``cv2.INTER_AREA``):

* **two cameras** (:class:`PairClip`, exact): the mirror is the plane bisecting the
  centres of cameras A and B, so that A's virtual camera stands where B stands; what
  A sees in the mirror is then B's frame turned about B's centre and flipped, exact
  at every depth. The clip's camera is a pinhole at A's centre (f = 840 px, principal
  point at the centre of 1280 x 960) turned to look between the person and the
  reflection; the mirror fills the view behind the person, the person (A's frame,
  undistorted) drawn over it inside a silhouette built from A's OpenPose joints. The
  person stands 0.7-1.0 m in front of the mirror, between it and the camera: the
  reflection is half hidden behind them (as in a gym filmed from behind). Truth: K,
  the normal and the distance in metres from Qualisys.
* **cut-out** (:class:`CutoutClip`, ``bench_video.py``'s planar clip): the reflection
  of the person as a flat cut-out beside the frame, its normal ``angle`` deg off the
  optical axis; the person and the reflection apart, but the reflection that of a
  flat picture (not of a 3D body), so that only its epipole is exact, and the
  distance's truth holds for the cut-out's plane (the depth of the Qualisys origin).
  Padded on the left so that the principal point is the clip's centre (``@70off``:
  ``bench_video.py``'s layout, the principal point 274 px off centre).

**Two calibrations a clip**, :func:`mirrorgraph.calibrate`, no intrinsics (the image
size only: the focal length and principal point estimated), the same subject height
(1.60 m: the stature ``bench_real.py`` measures on this trial) and frame rate; then the
same two with the clip's true K (the focal length out of the question):

* **annotations**: the OpenPose subject (the tallest person of each file, as
  ``bench_video_bias.py``) transformed exactly as the compositing transforms the frame
  (the halving ``x / 2 - 1/4``: the half-pixel centres of ``INTER_AREA``; then the
  clip's mapping of A's pixels for the person, of B's, or of the person's through the
  cut-out's homography, for the reflection), the reflection's left/right labels swapped
  (as a detector labels a mirror image); joints the composite does not show (the person
  on the mirror's side, the reflection behind the person or outside the frame) at
  confidence 0. Written as an OpenPose JSON folder (two people a frame) and read back
  with ``skeleton="BODY_25B"``, as a user would (``--skeleton``: the layout cannot be
  guessed where the subject faces away). OpenPose's file ``t`` is the video's frame
  ``t + 1`` (``bench_video_bias.py``): it is written as the clip's frame ``t + 1``.
* **video**: :func:`mirrorgraph.video.detect_video` on the composited clip
  (BlazePose, defaults, the detection cache; on the two-camera clips also with the
  detector on every frame and its tiles, which the figures use: the defaults keep the
  half-hidden reflection in few frames), then :func:`mirrorgraph.calibrate` on its
  detections, the frames the annotations have (1-99).

**Agreement**: ``|f_a - f_v| / sqrt(std_a^2 + std_v^2)`` of the focal lengths (target
<= 2), the same of the distances, and the angle between the two mirror normals
against the rotation stds combined the same way.

**Bias.** On each clip's person (the frames' joints on the person's side) BlazePose's
joints are compared with OpenPose's: per joint, the median offset in the subject's own
frame (towards the head: mid-hip to mid-shoulder; across: its perpendicular) in units
of the OpenPose torso, as ``bench_video_bias.py``. Two more calibrations a clip from
the annotations with that bias put in (per joint, in the source frame, before the
compositing: a detector biased alike on the person and on the reflection): **+bias**
(every common joint) and **+hips** (the hips' offset only). Their focal length and
distance against the plain annotations' is what the bias does.

Usage::

    python bench/bench_agreement.py                      # ~9 min on 2 shared cores
    python bench/bench_agreement.py --pairs cam02-cam03 --cutouts cam01@70 --no-write

The OpenPose JSON is read from ``--openpose DIR`` (``cam01`` .. ``cam04`` folders), or
extracted from a clone of Pose2Sim (``--pose2sim-git DIR``, default the mirror of this
machine) with ``git show``. Writes ``bench/RESULTS_agreement.md`` and ``.json``.
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
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import mirrorgraph as mg  # noqa: E402
from mirrorgraph.io import read_keypoints, write_keypoints  # noqa: E402
from mirrorgraph.io.qualisys import read_qca  # noqa: E402
from mirrorgraph.keypoints import RawDetections  # noqa: E402
from mirrorgraph.metrics import normal_angle_deg  # noqa: E402
from mirrorgraph.skeletons import BLAZEPOSE, BODY_25B  # noqa: E402
from mirrorgraph.synth.mirror_clip import PlanarMirrorClip  # noqa: E402
from mirrorgraph.video import VideoOptions, detect_video  # noqa: E402
from mirrorgraph.video.track import TrackerOptions  # noqa: E402
from _report import header  # noqa: E402  (one header for every results file)

OP_COMMIT = "a4d38da"
OP_PATH = ("Pose2Sim/Demo/S00_Demo_Session/S00_P00_Participant/S00_P00_T01_BalancingTrial/"
           "pose/{cam}_json")
DEFAULT_GIT = Path("/work/.mirror/perfanalytics+pose2sim/repo")
HEIGHT = 1.60           # bench_real.py's stature of Demo_SinglePerson (RESULTS_real.json)
FPS = 30.0
COMMON = [n for n in BODY_25B.joints if BLAZEPOSE.has(n)]
HIPS = ("left_hip", "right_hip")


def demo_trial() -> Path:
    spec = importlib.util.find_spec("Pose2Sim")
    if spec is None:
        sys.exit("pose2sim is not installed (pip install --no-deps pose2sim==0.10.49)")
    return Path(list(spec.submodule_search_locations)[0]) / "Demo_SinglePerson"


def openpose_folders(args, cams: list[str], work: Path) -> Path:
    """The folder holding ``cam0N`` OpenPose JSON folders (extracted with ``git show``)."""
    if args.openpose:
        return args.openpose
    out = work / "openpose"
    for cam in cams:
        d = out / cam
        if d.is_dir() and len(list(d.glob("*.json"))) == 100:
            continue
        d.mkdir(parents=True, exist_ok=True)
        src = OP_PATH.format(cam=cam)
        names = subprocess.run(["git", "-C", str(args.pose2sim_git), "ls-tree", "--name-only",
                                OP_COMMIT, src + "/"], check=True, capture_output=True,
                               text=True).stdout.split()
        for name in names:
            blob = subprocess.run(["git", "-C", str(args.pose2sim_git), "show",
                                   f"{OP_COMMIT}:{name}"], check=True,
                                  capture_output=True).stdout
            (d / Path(name).name).write_bytes(blob)
    return out


def demo_subjects(args, cams: list[str]) -> tuple[Path, dict, dict[str, dict]]:
    """What every clip of the demo trial is built from: the trial's folder, its Qualisys
    cameras (name -> camera) and per camera of ``cams`` its OpenPose subject on the first
    ``args.frames`` frames (frame -> ``(25, 3)`` source px; ``args``: ``frames``, ``work``
    and :func:`openpose_folders`' ``openpose``, ``pose2sim_git``)."""
    trial = demo_trial()
    quals = read_qca(trial / "calibration" / "Calib.qca.txt")
    root = openpose_folders(args, list(cams), args.work)
    subjects = {cam: {t: s for t, s in openpose_subject(root / cam).items() if t < args.frames}
                for cam in cams}
    return trial, quals, subjects


def pair_clip(pair: str, quals: dict, subjects: dict[str, dict]) -> "PairClip":
    """The two-camera clip ``"A-B"`` (B as A's mirror) of :func:`demo_subjects`' output."""
    A, B = pair.split("-")
    return PairClip(A, B, quals[A], quals[B], subjects[A], subjects[B])


def subject(people: np.ndarray) -> np.ndarray | None:
    """The tallest person (confidence > 0.3), unseen joints NaN."""
    if len(people) == 0:
        return None
    ok = people[..., 2] > 0.3
    h = [np.ptp(p[k, 1]) if k.sum() >= 4 else 0.0 for p, k in zip(people, ok)]
    s = people[int(np.argmax(h))].copy()
    s[s[:, 2] <= 0.3] = np.nan
    return s


def openpose_subject(folder: Path) -> dict[int, np.ndarray]:
    """Clip frame -> ``(25, 3)`` source-pixel OpenPose subject (file t = frame t + 1)."""
    op = read_keypoints(folder, skeleton="BODY_25B")
    out = {}
    for t, people in zip(op.frame_ids, op.people):
        s = subject(people)
        if s is not None:
            out[int(t) + 1] = s
    return out


def half(xy: np.ndarray) -> np.ndarray:
    """Source px -> halved-frame px (``cv2.resize`` INTER_AREA by 1/2, pixel centres)."""
    return 0.5 * xy - 0.25


def half_K(K: np.ndarray) -> np.ndarray:
    """The camera matrix of the halved frame."""
    Kh = np.diag([0.5, 0.5, 1.0]) @ np.asarray(K, float)
    Kh[:2, 2] -= 0.25
    return Kh


def apply_h(H: np.ndarray, xy: np.ndarray) -> np.ndarray:
    h = np.concatenate([xy, np.ones(xy.shape[:-1] + (1,))], -1) @ H.T
    return h[..., :2] / h[..., 2:]


def read_half(video: Path, frames: int) -> list[np.ndarray]:
    import cv2
    cap = cv2.VideoCapture(str(video))
    out = []
    while len(out) < frames:
        ok, bgr = cap.read()
        if not ok:
            break
        out.append(cv2.resize(bgr[..., ::-1], (bgr.shape[1] // 2, bgr.shape[0] // 2),
                              interpolation=cv2.INTER_AREA))
    cap.release()
    return out


class CutoutClip:
    """bench_video's planar clip (:class:`PlanarMirrorClip`): the halved frame, to its right
    the reflection of the person as a flat cut-out at the depth of the Qualisys origin
    (``t_z``), the mirror at the distance that puts the reflection's left edge 20 px right
    of the frame's edge. ``centred``: black columns added on the left so that the principal
    point is the clip's centre (the prior of the unknown-intrinsics path); else the
    clip is 1080 px wide and its principal point the source's, 274 px left of its centre."""

    kind = "cut-out"

    def __init__(self, cam: str, q, angle: float, subj: dict, centred: bool = True):
        self.cam, self.reflection_cam = cam, cam
        self.name = f"cut-out {cam} {angle:g} deg" + ("" if centred else " (pp off centre)")
        K = half_K(q.K)
        a = np.radians(angle)
        n = np.array([np.sin(a), 0.0, np.cos(a)])
        t_z = float(q.t[2])
        pts = half(np.concatenate([s[:, :2] for s in subj.values()]))
        pts = pts[np.isfinite(pts).all(1)]
        lo, hi = t_z * n[2] * 1.0001, t_z * n[2] + 10.0    # the person in front of the mirror

        def clip(d, Kc=K, pad=0, width=1080):
            return PlanarMirrorClip(K=Kc, normal=n, distance=d, depth=t_z, width=width,
                                    split=540 + pad)
        for _ in range(60):              # the reflection's left edge 20 px right of the split
            mid = 0.5 * (lo + hi)
            left = np.percentile(apply_h(clip(mid).H, pts)[:, 0], 0.5)
            lo, hi = (mid, hi) if left < 540 + 20 else (lo, mid)
        self.pad, width = 0, 1080
        if centred:
            right = np.percentile(apply_h(clip(hi).H, pts)[:, 0], 99.5) + 20
            self.pad = int(max(0, np.ceil(right - 2 * K[0, 2] - 1)))
            width = int(np.ceil(2 * (K[0, 2] + self.pad) + 1))
            width += width % 2                              # the video encoder's even width
        self.K = K.copy()
        self.K[0, 2] += self.pad
        self.clip = clip(hi, self.K, self.pad, width)
        self.split = 540 + self.pad
        self.size = (width, 960)
        self.truth = {"focal": float(K[0, 0]), "normal": n.tolist(), "distance": float(hi),
                      "pp_off_centre_px": float(np.hypot(self.K[0, 2] - (width - 1) / 2,
                                                         self.K[1, 2] - (960 - 1) / 2))}

    def person_xy(self, xy):
        return half(xy) + np.array([self.pad, 0.0])

    def reflection_xy(self, xy):
        return apply_h(self.clip.H, self.person_xy(xy))

    def in_mirror(self, xy, t: int | None = None):
        return xy[..., 0] >= self.split - 0.5

    def frames(self, trial: Path, frames: int):
        for f in read_half(trial / "videos" / f"{self.cam}.mp4", frames):
            yield self.clip.compose(np.pad(f, ((0, 0), (self.pad, 0), (0, 0))))


def _distort(xn: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Normalised coordinates ``(..., 2)`` -> pixels of a camera with OpenCV's
    ``k1 k2 p1 p2`` distortion."""
    k1, k2, p1, p2 = (list(dist) + [0.0] * 4)[:4]
    x, y = xn[..., 0], xn[..., 1]
    r2 = x * x + y * y
    rad = 1 + k1 * r2 + k2 * r2 * r2
    xd = x * rad + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * rad + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    return np.stack([K[0, 0] * xd + K[0, 2], K[1, 1] * yd + K[1, 2]], -1)


def _undistort(xy: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """Pixels ``(..., 2)`` (NaN kept) -> normalised coordinates."""
    import cv2
    out = np.full(xy.shape, np.nan)
    ok = np.isfinite(xy).all(-1)
    if ok.any():
        out[ok] = cv2.undistortPoints(xy[ok].reshape(-1, 1, 2).astype(np.float64), K,
                                      np.r_[np.asarray(dist, float)[:4], 0.0]).reshape(-1, 2)
    return out


class PairClip:
    """An exact planar-mirror clip from two calibrated cameras A and B of the trial.

    The mirror is the plane bisecting the two cameras' centres, so that A's virtual
    camera (A reflected in it) stands where B stands: what A would see in that mirror is
    what B sees, up to a rotation about B's centre and a left-right flip, exact at every
    depth. The clip's camera is a pinhole at A's centre (``f`` = 840 px: half the
    Qualisys focal lengths, principal point at the centre of its 1280 x 960 frame), turned
    to look between the person and their reflection. The mirror fills the view: each
    pixel takes its colour from B's halved frame (undistorted with Qualisys' distortion,
    dimmed to 0.7) except inside the person's silhouette of that frame (thick bones from
    A's OpenPose joints, :meth:`person_mask`), which shows A's halved frame (the person
    in front of the mirror). Truth: ``f``, the principal point, the mirror's normal and
    distance in metres, all from the Qualisys calibration (the two videos' frames taken
    as simultaneous)."""

    kind = "two cameras"
    F, W, H = 840.0, 1280, 960

    def __init__(self, A: str, B: str, qA, qB, subjA: dict, subjB: dict):
        self.cam, self.reflection_cam = A, B
        self.name = f"{A} + {B} as its mirror"
        self.size = (self.W, self.H)
        self.KA, self.KB = half_K(qA.K), half_K(qB.K)
        self.distA, self.distB = np.asarray(qA.dist, float), np.asarray(qB.dist, float)
        self.RA, self.RB = np.asarray(qA.R, float), np.asarray(qB.R, float)
        cA, cB = -self.RA.T @ qA.t, -self.RB.T @ qB.t
        m = (cB - cA) / np.linalg.norm(cB - cA)                   # world, from A towards B
        self.S = np.eye(3) - 2 * np.outer(m, m)                   # reflection of directions
        # person and reflection directions in A, for the clip camera's orientation
        rays_p = self._rays(subjA, self.KA, self.distA, np.eye(3))
        rays_r = self._rays(subjB, self.KB, self.distB, self.RA @ self.S @ self.RB.T)
        target = rays_p.mean(0) / np.linalg.norm(rays_p.mean(0)) \
            + rays_r.mean(0) / np.linalg.norm(rays_r.mean(0))
        target /= np.linalg.norm(target)
        z = np.array([0.0, 0.0, 1.0])
        axis = np.cross(target, z)
        ang = np.arcsin(min(1.0, np.linalg.norm(axis)))
        import cv2
        self.Rrot = cv2.Rodrigues(axis / np.linalg.norm(axis) * ang)[0]   # A -> clip
        self.K = np.array([[self.F, 0, self.W / 2 - 0.5], [0, self.F, self.H / 2 - 0.5],
                           [0, 0, 1.0]])
        self.Rc = self.Rrot @ self.RA                             # world -> clip
        n = self.Rc @ m
        dist = float(np.linalg.norm(cB - cA) / 2)
        self.subjA = subjA
        self.truth = {"focal": self.F, "normal": n.tolist(), "distance": dist,
                      "pp_off_centre_px": 0.5,
                      "person_to_mirror_m": float(abs(m @ ((cA + cB) / 2))),
                      "normal_to_axis_deg": float(np.degrees(np.arccos(abs(n[2]))))}
        self._maps = None

    @staticmethod
    def _rays(subj, K, dist, R):
        xy = np.concatenate([s[:, :2] for s in subj.values()])
        xn = _undistort(half(xy), K, dist)
        xn = xn[np.isfinite(xn).all(1)]
        return np.column_stack([xn, np.ones(len(xn))]) @ R.T

    def _project(self, rays_clip):
        h = rays_clip @ self.K.T
        out = h[..., :2] / h[..., 2:]
        out[rays_clip[..., 2] <= 0] = np.nan
        return out

    def person_xy(self, xy):
        xn = _undistort(half(xy), self.KA, self.distA)
        return self._project(np.concatenate([xn, np.ones(xn.shape[:-1] + (1,))], -1)
                             @ self.Rrot.T)

    def reflection_xy(self, xy):
        xn = _undistort(half(xy), self.KB, self.distB)
        rays = np.concatenate([xn, np.ones(xn.shape[:-1] + (1,))], -1)
        return self._project(rays @ (self.Rc @ self.S @ self.RB.T).T)

    def person_mask(self, t: int) -> np.ndarray:
        """``(H, W)`` bool: the person of frame ``t``, drawn from the OpenPose joints
        (bones as thick lines, the trunk filled, the head a disc; sized by the torso)."""
        import cv2
        mask = np.zeros((self.H, self.W), np.uint8)
        s = self.subjA.get(t)
        if s is None:
            return mask.astype(bool)
        xy = self.person_xy(s[:, :2])
        J = BODY_25B.index

        def p(name):
            v = xy[J(name)]
            return None if not np.isfinite(v).all() else v
        sh = [p("left_shoulder"), p("right_shoulder")]
        hp = [p("left_hip"), p("right_hip")]
        if any(v is None for v in sh + hp):
            torso = 120.0
        else:
            torso = float(np.linalg.norm((sh[0] + sh[1]) / 2 - (hp[0] + hp[1]) / 2))
        bones = [("shoulder", "elbow", 0.32), ("elbow", "wrist", 0.26), ("hip", "knee", 0.45),
                 ("knee", "ankle", 0.34), ("ankle", "big_toe", 0.25), ("ankle", "heel", 0.25),
                 ("shoulder", "hip", 0.40)]
        for side in ("left", "right"):
            for a, b, w in bones:
                pa, pb = p(f"{side}_{a}"), p(f"{side}_{b}")
                if pa is not None and pb is not None:
                    cv2.line(mask, tuple(int(round(v)) for v in pa),
                             tuple(int(round(v)) for v in pb), 1, max(3, int(w * torso)))
        quad = [v for v in (sh[0], sh[1], hp[1], hp[0]) if v is not None]
        if len(quad) >= 3:
            cv2.fillPoly(mask, [np.round(np.array(quad)).astype(np.int32)], 1)
        head = [v for v in (p("nose"), p("left_ear"), p("right_ear"), p("left_eye"),
                            p("right_eye")) if v is not None]
        if head:
            cv2.circle(mask, tuple(int(round(v)) for v in np.mean(head, 0)),
                       int(0.32 * torso), 1, -1)
        if sh[0] is not None and sh[1] is not None and head:
            cv2.line(mask, tuple(int(round(v)) for v in (sh[0] + sh[1]) / 2),
                     tuple(int(round(v)) for v in np.mean(head, 0)), 1, int(0.3 * torso))
        return mask.astype(bool)

    def in_mirror(self, xy, t: int | None = None):
        """Where the clip shows the mirror: everywhere but the person of frame ``t``."""
        xy = np.asarray(xy, float)
        if t is None:
            return np.ones(xy.shape[:-1], bool)
        m = self.person_mask(t)
        i = np.clip(np.round(xy[..., 1]).astype(int), 0, self.H - 1)
        j = np.clip(np.round(xy[..., 0]).astype(int), 0, self.W - 1)
        return ~m[i, j]

    def maps(self):
        """Per clip pixel: the source pixel in A's and in B's halved frame, the mirror mask."""
        if self._maps is None:
            u, v = np.meshgrid(np.arange(self.W, dtype=float), np.arange(self.H, dtype=float))
            px = np.stack([u, v], -1)
            q = np.concatenate([px, np.ones(px.shape[:-1] + (1,))], -1) @ np.linalg.inv(self.K).T
            out = []
            for Kc, dc, M in ((self.KA, self.distA, self.Rrot.T),
                              (self.KB, self.distB, self.RB @ self.S @ self.Rc.T)):
                r = q @ M.T
                xn = r[..., :2] / np.where(r[..., 2:] > 0, r[..., 2:], np.nan)
                m = _distort(xn, Kc, dc).astype(np.float32)
                out.append(np.nan_to_num(m, nan=-1e4))
            self._maps = tuple(out)
        return self._maps

    def frames(self, trial: Path, frames: int):
        import cv2
        ma, mb = self.maps()
        A = read_half(trial / "videos" / f"{self.cam}.mp4", frames)
        B = read_half(trial / "videos" / f"{self.reflection_cam}.mp4", frames)
        for t, (fa, fb) in enumerate(zip(A, B)):
            mirror = ~self.person_mask(t)
            ia = cv2.remap(fa, ma[..., 0], ma[..., 1], cv2.INTER_LINEAR,
                           borderMode=cv2.BORDER_CONSTANT)
            ib = cv2.remap(fb, mb[..., 0], mb[..., 1], cv2.INTER_LINEAR,
                           borderMode=cv2.BORDER_CONSTANT)
            ib = (ib.astype(np.float32) * 0.7).astype(np.uint8)   # a mirror reflects less
            yield np.where(mirror[..., None], ib, ia)


def annotations(clip, subj: dict, subj_refl: dict, offsets: dict | None = None
                ) -> RawDetections:
    """The OpenPose subject of the clip's camera and (mapped from the reflection's source
    camera) its reflection, in clip pixels, the reflection's labels swapped; joints the
    clip does not show at confidence 0. ``offsets``: joint -> (towards the head, across)
    in torso units, added in each source frame first."""
    flip = np.asarray(BODY_25B.flip)
    W, H = clip.size
    frames, people = [], []
    for t in sorted(set(subj) & set(subj_refl)):
        s, r = shifted(subj[t], offsets), shifted(subj_refl[t], offsets)
        person = clip.person_xy(s[:, :2])
        refl = clip.reflection_xy(r[:, :2])[flip]
        rconf = r[flip, 2]

        def shown(xy, mirror_side):
            ok = np.isfinite(xy).all(1)
            inside = ok & (xy[:, 0] >= -0.5) & (xy[:, 0] < W - 0.5) & (xy[:, 1] >= -0.5) \
                & (xy[:, 1] < H - 0.5)
            side = np.zeros(len(xy), bool)
            side[ok] = clip.in_mirror(xy[ok], t) == mirror_side
            return inside & side
        kp = np.zeros((2, BODY_25B.num_joints, 3))
        for i, (xy, c, vis) in enumerate(((person, s[:, 2], shown(person, False)),
                                          (refl, rconf, shown(refl, True)))):
            good = vis & np.isfinite(c) & (c > 0)
            kp[i, good, :2] = xy[good]
            kp[i, good, 2] = c[good]
        frames.append(t)
        people.append(kp)
    return RawDetections(skeleton=BODY_25B, frame_ids=np.array(frames, np.int64), people=people,
                         image_size=clip.size, fps=FPS)


def shifted(s: np.ndarray, offsets: dict | None) -> np.ndarray:
    """``s`` (source px) with per-joint offsets in its own torso frame."""
    s = s.copy()
    if not offsets:
        return s
    ls, rs = BODY_25B.index("left_shoulder"), BODY_25B.index("right_shoulder")
    lh, rh = BODY_25B.index("left_hip"), BODY_25B.index("right_hip")
    up = (s[ls, :2] + s[rs, :2]) / 2 - (s[lh, :2] + s[rh, :2]) / 2
    torso = np.linalg.norm(up)
    idx = [BODY_25B.index(n) for n in offsets]
    if not np.isfinite(torso) or torso <= 0:
        s[idx, :2] = np.nan
        return s
    u = up / torso
    across = np.array([-u[1], u[0]])
    for name, (along, acr) in offsets.items():
        s[BODY_25B.index(name), :2] += torso * (along * u + acr * across)
    return s


def write_clip(path: Path, clip, trial: Path, frames: int) -> None:
    import cv2
    if path.exists():
        return                                  # keep its mtime: the detection cache's key
    tmp = path.with_suffix(".part.mp4")
    out = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), FPS, clip.size)
    for f in clip.frames(trial, frames):
        out.write(np.ascontiguousarray(f[..., ::-1]))
    out.release()
    tmp.rename(path)


def blaze_person(clip, det: RawDetections, subj: dict) -> dict[int, np.ndarray]:
    """Clip frame -> BlazePose pose (COMMON joints, clip px, NaN where visibility < 0.5)
    nearest to the OpenPose person in that frame."""
    io = [BODY_25B.index(n) for n in COMMON]
    ib = [BLAZEPOSE.index(n) for n in COMMON]
    out = {}
    for t, people in zip(det.frame_ids, det.people):
        if int(t) not in subj or len(people) == 0:
            continue
        a = clip.person_xy(subj[int(t)][io, :2])
        best, bd = None, np.inf
        for p in people:
            b = p[ib].copy()
            b[b[:, 2] < 0.5, :2] = np.nan
            d = np.nanmedian(np.linalg.norm(a - b[:, :2], axis=1)) if np.isfinite(
                b[:, :2]).any() else np.inf
            if d < bd:
                best, bd = b[:, :2], d
        if best is not None and bd < 60:
            out[int(t)] = best
    return out


def bias_samples(clip, subj: dict, blaze: dict) -> np.ndarray:
    """``(N, C, 2)`` BlazePose - OpenPose per COMMON joint, (towards the head, across) in
    OpenPose torso units, on the person's side of the clip."""
    io = [BODY_25B.index(n) for n in COMMON]
    ls, rs = COMMON.index("left_shoulder"), COMMON.index("right_shoulder")
    lh, rh = COMMON.index("left_hip"), COMMON.index("right_hip")
    out = []
    for t, b in blaze.items():
        a = clip.person_xy(subj[t][io, :2])
        up = (a[ls] + a[rs]) / 2 - (a[lh] + a[rh]) / 2
        torso = np.linalg.norm(up)
        if not np.isfinite(torso) or torso <= 0:
            continue
        u = up / torso
        across = np.array([-u[1], u[0]])
        d = b - a
        hidden = np.zeros(len(a), bool)
        ok = np.isfinite(a).all(1)
        hidden[ok] = clip.in_mirror(a[ok], t)
        d[hidden] = np.nan
        out.append(np.column_stack([d @ u, d @ across]) / torso)
    return np.array(out)


def figures(run) -> dict:
    c = run.calibration
    est = c.intrinsics.estimated or {}
    u = c.uncertainty
    return {"focal": float(c.intrinsics.K[0, 0]), "focal_std": float(u.get("focal_std_px",
                                                                           np.nan)),
            "determined": bool(est.get("determined", True)),
            "distance": float(c.distance), "distance_std": float(u.get("distance_std", np.nan)),
            "rotation_std": float(u.get("rotation_std_deg", np.nan)),
            "normal": [float(x) for x in c.normal], "pp": [float(c.intrinsics.K[0, 2]),
                                                         float(c.intrinsics.K[1, 2])],
            "frames_used": int(c.frames_used), "pairs_used": int(c.pairs_used),
            "warnings": list(c.warnings)}


def calibrate(keypoints, K: np.ndarray | None = None) -> dict:
    """No intrinsics (the image size only), or ``K`` given (the clip's true matrix)."""
    size = tuple(keypoints.image_size)
    opts = mg.CalibrateOptions(image_size=size, subject_height=HEIGHT, fps=FPS)
    intr = None if K is None else mg.Intrinsics(K=K, image_size=size,
                                                  source="the clip's matrix")
    t0 = time.perf_counter()
    try:
        out = figures(mg.calibrate(keypoints, intr, opts))
    except (mg.InputError, mg.DegenerateGeometryError) as exc:
        out = {"refused": str(exc)[:300], **{k: float("nan") for k in (
            "focal", "focal_std", "distance", "distance_std", "rotation_std")},
               "normal": [float("nan")] * 3, "determined": False, "warnings": []}
    out["seconds"] = time.perf_counter() - t0
    return out


def z(a: float, sa: float, b: float, sb: float) -> float:
    return abs(a - b) / float(np.hypot(sa, sb))


def read_annotations(folder: Path) -> RawDetections:
    """The written OpenPose folder, read as a user would with ``--skeleton BODY_25B`` (the
    layout cannot be guessed where the subject's face is unseen: cam03, cam04)."""
    return read_keypoints(folder, skeleton="BODY_25B")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pairs", nargs="*", default=["cam01-cam04", "cam01-cam03",
                                                    "cam02-cam03", "cam02-cam04"],
                    help="two-camera clips A-B (B as A's mirror)")
    ap.add_argument("--cutouts", nargs="*", default=[f"cam0{i}@{a}" for a in (80, 75)
                                                      for i in range(1, 5)] + ["cam01@70off"],
                    help="cut-out clips CAM@ANGLE (normal's angle to the optical axis, deg; "
                    "a suffix 'off': bench_video's layout, the principal point off centre)")
    ap.add_argument("--frames", type=int, default=100, help="frames of each clip")
    ap.add_argument("--openpose", type=Path, help="folder of cam0N OpenPose JSON folders")
    ap.add_argument("--pose2sim-git", type=Path, default=DEFAULT_GIT)
    ap.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) / "bench_agreement",
                    help="clips and annotations (kept: the detection cache keys on the clips)")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    started = datetime.datetime.now(datetime.timezone.utc)
    t_all = time.perf_counter()
    args.work.mkdir(parents=True, exist_ok=True)
    cams = sorted({c for p in args.pairs for c in p.split("-")}
                  | {c.split("@")[0] for c in args.cutouts})
    trial, quals, subjects = demo_subjects(args, cams)
    clips = [(f"pair_{p.replace('-', '_')}", pair_clip(p, quals, subjects)) for p in args.pairs]
    for c in args.cutouts:
        cam, angle = c.split("@")
        off = angle.endswith("off")
        clips.append((f"cutout_{cam}_{angle}", CutoutClip(
            cam, quals[cam], float(angle.removesuffix("off")), subjects[cam], not off)))
    rows = []
    for tag, clip in clips:
        tag = f"{tag}_{clip.size[0]}x{clip.size[1]}"            # a clip's file names its layout
        video = args.work / f"{tag}.mp4"
        write_clip(video, clip, trial, args.frames)
        subj, subj_r = subjects[clip.cam], subjects[clip.reflection_cam]
        frames = set(subj) & set(subj_r)

        def detect(opts):
            t0 = time.perf_counter()
            det = detect_video(video, opts).to_raw()
            keep = [i for i, t in enumerate(det.frame_ids) if int(t) in frames]
            used = replace(det, frame_ids=det.frame_ids[keep], people=[det.people[i]
                                                                      for i in keep])
            return used, time.perf_counter() - t0, float(np.mean([len(p) >= 2
                                                                  for p in used.people]))
        det_used, det_s, two = detect(VideoOptions(end=args.frames))
        folder = args.work / f"ann_{tag}"
        write_keypoints(annotations(clip, subj, subj_r), folder, "openpose", meta=True)
        ann = read_annotations(folder)
        res = {"annotations": calibrate(ann), "annotations K": calibrate(ann, clip.K)}
        detection = "defaults"
        if clip.kind == "two cameras":
            # the half-hidden reflection: the defaults keep it in few frames (a track the
            # landmark model loses); the detector on every frame and its tiles find it
            res["video (defaults)"] = calibrate(det_used)
            two_default = two
            det_used, det_s, two = detect(VideoOptions(end=args.frames, tracker=TrackerOptions(
                detect_every=1, tiles_every=1)))
            detection = f"detector every frame (defaults: 2+ people in {two_default:.0%})"
        res["video"], res["video K"] = calibrate(det_used), calibrate(det_used, clip.K)
        blaze = blaze_person(clip, det_used, subj)
        rows.append({"clip": clip.name, "tag": tag, "kind": clip.kind, "truth": clip.truth,
                     "detect_seconds": det_s, "frames": len(det_used.people), "res": res,
                     "two_people": two, "detection": detection,
                     "bias": bias_samples(clip, subj, blaze), "clip_obj": clip})
        a, v, t = res["annotations"], res["video"], clip.truth
        print(f"{clip.name}: f {a['focal']:.0f}+-{a['focal_std']:.0f} / {v['focal']:.0f}+-"
              f"{v['focal_std']:.0f} (truth {t['focal']:.0f}), z "
              f"{z(a['focal'], a['focal_std'], v['focal'], v['focal_std']):.2f}; d "
              f"{a['distance']:.2f}+-{a['distance_std']:.2f} / {v['distance']:.2f}+-"
              f"{v['distance_std']:.2f} (truth {t['distance']:.2f}); normals "
              f"{normal_angle_deg(np.array(a['normal']), np.array(v['normal'])):.2f} deg "
              f"apart; K given: d {res['annotations K']['distance']:.2f} / "
              f"{res['video K']['distance']:.2f}; detect {det_s:.0f} s", flush=True)
    # the bias, pooled over every clip's person, then put into the annotations
    pooled = np.concatenate([r["bias"] for r in rows if len(r["bias"])])
    med = np.nanmedian(pooled, axis=0)                                  # (C, 2)
    offsets_all = {n: (float(med[i, 0]), float(med[i, 1])) for i, n in enumerate(COMMON)
                   if np.isfinite(med[i]).all()}
    offsets_hips = {n: offsets_all[n] for n in HIPS}
    for r in rows:
        clip = r["clip_obj"]
        for tag, offs in (("+bias", offsets_all), ("+hips", offsets_hips)):
            folder = args.work / f"ann_{r['tag']}_{tag[1:]}"
            write_keypoints(annotations(clip, subjects[clip.cam], subjects[clip.reflection_cam],
                                        offs), folder, "openpose", meta=True)
            ann = read_annotations(folder)
            r["res"][tag] = calibrate(ann)
            r["res"][tag + " K"] = calibrate(ann, clip.K)
        print(f"{r['clip']}: +bias f {r['res']['+bias']['focal']:.0f} d "
              f"{r['res']['+bias']['distance']:.3f}; +hips f {r['res']['+hips']['focal']:.0f} d "
              f"{r['res']['+hips']['distance']:.3f}", flush=True)
    seconds = time.perf_counter() - t_all
    report(rows, offsets_all, pooled, seconds, started, argv, args)
    return 0


def report(rows, offsets, pooled, seconds, started, argv, args) -> None:
    cmd = "python bench/bench_agreement.py " + " ".join(argv if argv is not None
                                                          else sys.argv[1:])
    L = ["# Annotations against video: one mirror clip, two calibrations (issue #24)", "",
         *header(started=f"{started:%Y-%m-%d %H:%M} UTC; run time {seconds / 60:.1f} min "
                 "(detection included unless read from the cache)", cmd=cmd.strip(),
                 bullet="-", code=True),
         f"- clips: Demo_SinglePerson (pose2sim 0.10.49), {args.frames} frames each, composited "
         "as a planar mirror from two of its cameras (exact; the reflection half hidden "
         "behind the person) or from one camera with a flat cut-out reflection (see the "
         "script's docstring); annotations: OpenPose BODY_25B of "
         f"Pose2Sim commit {OP_COMMIT}; video: BlazePose (`mirrorgraph.video`, defaults; "
         "on the two-camera clips with the detector on every frame, see the table); "
         f"both calibrated without intrinsics (image size only), subject height {HEIGHT} m, "
         "frames 1-99 (those with an OpenPose file)", "",
         "| clip | video: frames with 2+ people | truth f (px) | annotations f +- std | "
         "video f +- std | focal z | "
         "truth d (m) | annotations d +- std | video d +- std | distance z | normals apart "
         "(deg) / combined rotation std | ann. / video normal off truth (deg) |",
         "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    zs = []
    for r in rows:
        a, v, t = r["res"]["annotations"], r["res"]["video"], r["truth"]
        zf = z(a["focal"], a["focal_std"], v["focal"], v["focal_std"])
        zd = z(a["distance"], a["distance_std"], v["distance"], v["distance_std"])
        zs.append(zf)
        na, nv, nt = (np.array(x) for x in (a["normal"], v["normal"], t["normal"]))
        flag = lambda x: "" if x["determined"] else " (undetermined)"  # noqa: E731
        L.append(f"| {r['clip']} | {r['two_people']:.0%}"
                 + ("" if r["detection"] == "defaults" else f" ({r['detection']})")
                 + f" | {t['focal']:.0f} | "
                 f"{a['focal']:.0f} +- {a['focal_std']:.0f}"
                 f"{flag(a)} | {v['focal']:.0f} +- {v['focal_std']:.0f}{flag(v)} | "
                 f"**{zf:.2f}** | {t['distance']:.2f} | {a['distance']:.2f} +- "
                 f"{a['distance_std']:.2f} | {v['distance']:.2f} +- {v['distance_std']:.2f} | "
                 f"{zd:.2f} | {normal_angle_deg(na, nv):.2f} / "
                 f"{np.hypot(a['rotation_std'], v['rotation_std']):.2f} | "
                 f"{normal_angle_deg(na, nt):.2f} / {normal_angle_deg(nv, nt):.2f} |")
    ok = sum(x <= 2 for x in zs)
    L += ["", f"Focal z = |f_a - f_v| / sqrt(std_a^2 + std_v^2): **{ok} of {len(zs)} clips "
          f"<= 2** (median {np.nanmedian(zs):.2f}, largest {np.nanmax(zs):.2f}; a refused "
          "calibration counts as not met; 'undetermined': the run's own verdict on its focal "
          "length). 'd' is the mirror distance (m); a cut-out's truth holds for its flat "
          "picture at the Qualisys origin's depth, not for the 3D person.", "",
          "## BlazePose against OpenPose on the clips' person", "",
          f"Median offset BlazePose - OpenPose per joint, {len(pooled)} person-frames of all "
          "clips (each camera's person appears in both angles' clips: the same frames twice), "
          "% of the OpenPose torso:", "",
          "| joint | towards the head | across (+: the image's right for an upright subject) |",
          "|---|---|---|"]
    for n, (al, ac) in offsets.items():
        L.append(f"| {n} | {100 * al:+.1f} | {100 * ac:+.1f} |")
    L += ["", "What the bias does: the annotations with BlazePose's offsets put in (every common "
          "joint: **+bias**; the hips only: **+hips**), calibrated the same way; shifts against "
          "the plain annotations (in % of their value, and in their std).", "",
          "| clip | annotations f / d | +bias f / d | shift f, d (%) | shift f, d (std) | "
          "+hips f / d | shift f, d (%) | video - annotations f, d (%) |",
          "|---|---|---|---|---|---|---|---|"]
    sh = {"+bias": [], "+hips": [], "video": []}
    for r in rows:
        a = r["res"]["annotations"]
        cells = [r["clip"], f"{a['focal']:.0f} / {a['distance']:.3f}"]
        for tag in ("+bias", "+hips", "video"):
            b = r["res"][tag]
            pf = 100 * (b["focal"] / a["focal"] - 1)
            pd = 100 * (b["distance"] / a["distance"] - 1)
            sh[tag].append((pf, pd))
            if tag == "+bias":
                cells += [f"{b['focal']:.0f} / {b['distance']:.3f}", f"{pf:+.1f}, {pd:+.1f}",
                          f"{(b['focal'] - a['focal']) / a['focal_std']:+.2f}, "
                          f"{(b['distance'] - a['distance']) / a['distance_std']:+.2f}"]
            elif tag == "+hips":
                cells += [f"{b['focal']:.0f} / {b['distance']:.3f}", f"{pf:+.1f}, {pd:+.1f}"]
            else:
                cells.append(f"{pf:+.1f}, {pd:+.1f}")
        L.append("| " + " | ".join(cells) + " |")
    med = {k: np.nanmedian(np.array(v), axis=0) for k, v in sh.items()}
    L += ["", f"Median shifts (f, d in %): +bias {med['+bias'][0]:+.1f}, {med['+bias'][1]:+.1f}; "
          f"+hips {med['+hips'][0]:+.1f}, {med['+hips'][1]:+.1f}; video against annotations "
          f"{med['video'][0]:+.1f}, {med['video'][1]:+.1f}.", ""]
    L += ["## The same with the clip's camera matrix given", "",
          "The focal length taken out (the clip's true K): what is left of the disagreement "
          "and of the bias is the mirror and the distance.", "",
          "| clip | annotations d +- std | video d +- std | distance z | normals apart (deg) / "
          "combined rotation std | ann. / video normal off truth (deg) | +bias d | shift d (%) "
          "| +hips shift d (%) |", "|---|---|---|---|---|---|---|---|---|"]
    kd = []
    for r in rows:
        a, v, t = r["res"]["annotations K"], r["res"]["video K"], r["truth"]
        b, h = r["res"]["+bias K"], r["res"]["+hips K"]
        na, nv, nt = (np.array(x) for x in (a["normal"], v["normal"], t["normal"]))
        pd, ph = (100 * (x["distance"] / a["distance"] - 1) for x in (b, h))
        kd.append((pd, ph, 100 * (v["distance"] / a["distance"] - 1)))
        L.append(f"| {r['clip']} | {a['distance']:.3f} +- {a['distance_std']:.3f} | "
                 f"{v['distance']:.3f} +- {v['distance_std']:.3f} | "
                 f"{z(a['distance'], a['distance_std'], v['distance'], v['distance_std']):.2f} "
                 f"| {normal_angle_deg(na, nv):.2f} / "
                 f"{np.hypot(a['rotation_std'], v['rotation_std']):.2f} | "
                 f"{normal_angle_deg(na, nt):.2f} / {normal_angle_deg(nv, nt):.2f} | "
                 f"{b['distance']:.3f} | {pd:+.1f} | {ph:+.1f} |")
    kd = np.nanmedian(np.array(kd), axis=0)
    L += ["", f"Median distance shifts with K given: +bias {kd[0]:+.1f} %, +hips {kd[1]:+.1f} %, "
          f"video against annotations {kd[2]:+.1f} %.", ""]
    L += ["Warnings of the runs (first of each):", ""]
    for r in rows:
        for tag in ("annotations", "video"):
            w = r["res"][tag]["warnings"]
            if "refused" in r["res"][tag]:
                L.append(f"- {r['clip']} {tag}: REFUSED: {r['res'][tag]['refused']}")
            elif w:
                L.append(f"- {r['clip']} {tag}: {w[0][:300]}")
    text = "\n".join(L) + "\n"
    print(text)
    if args.no_write:
        return
    (ROOT / "bench" / "RESULTS_agreement.md").write_text(text)
    js = [{k: v for k, v in r.items() if k not in ("bias", "clip_obj")} for r in rows]
    (ROOT / "bench" / "RESULTS_agreement.json").write_text(json.dumps(
        {"rows": js, "offsets": offsets, "seconds": seconds, "command": cmd,
         "date": f"{started:%Y-%m-%d %H:%M}"}, indent=1) + "\n")


if __name__ == "__main__":
    sys.exit(main())
