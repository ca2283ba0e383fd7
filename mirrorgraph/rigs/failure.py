"""A camera that does not fit its rig: its share of keypoints kept, and its likeliest cause.

A camera fails when the solved rig keeps (within the outlier threshold, after the final
solve) under :data:`MIN_FIT_SHARE` of the keypoints its views offered the graph: its pose
is then fitted to a minority of its data and may be anywhere. :func:`fit_shares` gives
every camera's share from the solve's per-view counts.

The cause (:func:`failure_cause`) is read from the data, not from the failed camera's
solved pose (the very thing in doubt). The camera's direct keypoints at frame ``t + s``
are matched with every sound camera's at frame ``t`` for each shift ``s`` in
``-window..window``; per shift, the share of joint correspondences within the outlier
threshold (Sampson distance, pixels) of the best essential matrix (OpenCV's five-point
solver in MAGSAC++, the cameras' solved intrinsics), pooled over the sound cameras, is
the shift's epipolar consistency; the best shift is the one of least truncated
quadratic cost (MSAC's: Torr and Zisserman, CVIU 2000), which does not saturate as the
share does. A best shift whose consistency is far above the frames as given
(:data:`OFFSET_GAIN`) names a time offset; else the camera sees too few keypoints
shared with the others (:data:`MIN_SCAN_CORRESPONDENCES`), or its people do not match
theirs.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from ..geometry import sampson_distances
from ..keypoints import DEFAULT_MIN_CONFIDENCE
from .tracking import track_people

__all__ = ["MIN_FIT_SHARE", "OFFSET_WINDOW", "OFFSET_GAIN", "MIN_SCAN_CORRESPONDENCES",
           "OffsetScan", "fit_shares", "scan_offsets", "failure_cause", "offset_hint",
           "most_confident", "candidate_people"]

#: A camera keeping fewer than this share of its offered keypoints fails.
MIN_FIT_SHARE = 0.5
#: Shifts tried, frames either way.
OFFSET_WINDOW = 15
#: A shift names a time offset when its epipolar consistency is at least this many times
#: that of the frames as given, and at least :data:`MIN_FIT_SHARE`.
OFFSET_GAIN = 1.25
#: Fewer joint correspondences with every sound camera than this: "too few keypoints".
MIN_SCAN_CORRESPONDENCES = 100
#: Correspondences per camera pair and shift at most (frames taken evenly): the scan's cost.
MAX_SCAN_CORRESPONDENCES = 3000


def fit_shares(camera_names, view_names, view_counts, view_observed
               ) -> dict[str, tuple[int, int]]:
    """Per camera, ``(kept, offered)``: the keypoints of all its views (direct,
    ``"<camera>"``, and through mirrors, ``"<camera>/<mirror>"``) the final solve kept
    and those offered to the graph."""
    out = {c: [0, 0] for c in camera_names}
    for v, k, n in zip(view_names, view_counts, view_observed):
        cam = str(v).split("/")[0]
        if cam in out:
            out[cam][0] += int(k)
            out[cam][1] += int(n)
    return {c: (k, n) for c, (k, n) in out.items()}


@dataclass
class OffsetScan:
    """The epipolar consistency of one camera with the others per time shift.

    Attributes:
        shifts: ``(S,)`` frames: the camera's frame ``t + s`` against the others' ``t``.
        consistency: ``(S,)`` share of pooled correspondences within the threshold of the
            best essential matrix (NaN where too few correspondences).
        cost: ``(S,)`` their truncated quadratic cost (0-1, lower fits better; NaN alike).
        correspondences: ``(S,)`` pooled correspondences.
    """

    shifts: np.ndarray
    consistency: np.ndarray
    cost: np.ndarray
    correspondences: np.ndarray

    def at(self, shift: int) -> float:
        """The consistency at ``shift``."""
        return float(self.consistency[np.flatnonzero(self.shifts == shift)[0]])

    @property
    def best(self) -> int:
        """The shift of lowest cost (0 when none is finite)."""
        c = np.where(np.isfinite(self.cost), self.cost, np.inf)
        return int(self.shifts[int(np.argmin(c))]) if np.isfinite(c).any() else 0


def _shifted(a: np.ndarray, b: np.ndarray, s: int) -> tuple[np.ndarray, np.ndarray]:
    """``a`` at frames ``t + s`` and ``b`` at ``t``, over the frames both hold."""
    T = min(len(a), len(b))
    if s >= 0:
        return a[s:T], b[:T - s]
    return a[:T + s], b[-s:T]


def _consistency(K_a: np.ndarray, K_b: np.ndarray, ua: np.ndarray, ub: np.ndarray,
                 threshold_px: float, seed: int) -> tuple[float, float, int]:
    """Of the ``(N, 2)`` pixel pairs under the best essential matrix: the share within
    ``threshold_px`` (Sampson distance), the truncated quadratic cost (the mean of
    ``min(d, threshold)^2 / threshold^2``, 0-1), and ``N``."""
    n = len(ua)
    if n < MIN_SCAN_CORRESPONDENCES // 4:
        return float("nan"), float("nan"), n
    if n > MAX_SCAN_CORRESPONDENCES:
        keep = np.linspace(0, n - 1, MAX_SCAN_CORRESPONDENCES).round().astype(int)
        ua, ub = ua[keep], ub[keep]
    xa = cv2.undistortPoints(ua.reshape(-1, 1, 2).astype(np.float64), K_a, None).reshape(-1, 2)
    xb = cv2.undistortPoints(ub.reshape(-1, 1, 2).astype(np.float64), K_b, None).reshape(-1, 2)
    f = 0.5 * (0.5 * (K_a[0, 0] + K_a[1, 1]) + 0.5 * (K_b[0, 0] + K_b[1, 1]))
    cv2.setRNGSeed(int(seed))
    E, _ = cv2.findEssentialMat(xa, xb, np.eye(3), method=cv2.USAC_MAGSAC, prob=0.999,
                                threshold=threshold_px / f, maxIters=1000)
    if E is None or E.shape[1:] != (3,) or E.shape[0] < 3:
        return 0.0, 1.0, n
    best = (0.0, 1.0)
    for k in range(E.shape[0] // 3):           # the solver's candidates: the best one
        d = np.abs(f * sampson_distances(E[3 * k:3 * k + 3], xa, xb))
        cost = float(np.mean(np.minimum(d, threshold_px) ** 2)) / threshold_px ** 2
        if cost < best[1]:
            best = (float(np.mean(d < threshold_px)), cost)
    return best[0], best[1], n


def scan_offsets(points: list[np.ndarray], Ks: list[np.ndarray], camera: int,
                 others: list[int], threshold_px: float, *, window: int = OFFSET_WINDOW,
                 seed: int = 0) -> OffsetScan:
    """The epipolar consistency of camera ``camera`` with ``others`` per time shift.

    Args:
        points: per camera ``(T, J, 2)`` undistorted pixels of the person's joints on the
            rig's clock, NaN where unseen.
        Ks: per camera ``(3, 3)`` intrinsics.
        camera: the camera scanned (index into ``points``).
        others: the cameras it is matched with.
        threshold_px: the inlier threshold (Sampson distance), pixels.
        window: shifts ``-window..window`` frames.
        seed: OpenCV's RANSAC seed.
    """
    shifts = np.arange(-int(window), int(window) + 1)
    cons, cost = np.full(len(shifts), np.nan), np.full(len(shifts), np.nan)
    corr = np.zeros(len(shifts), int)
    for i, s in enumerate(shifts):
        inliers = costs = total = 0.0
        for o in others:
            a, b = _shifted(points[camera], points[o], int(s))
            both = np.isfinite(a).all(-1) & np.isfinite(b).all(-1)
            share, c, n = _consistency(np.asarray(Ks[camera], float),
                                       np.asarray(Ks[o], float), a[both], b[both],
                                       threshold_px, seed)
            corr[i] += n
            if np.isfinite(share):
                inliers += share * n
                costs += c * n
                total += n
        if total:
            cons[i], cost[i] = inliers / total, costs / total
    return OffsetScan(shifts=shifts, consistency=cons, cost=cost, correspondences=corr)


def failure_cause(scan: OffsetScan | None, frame_offset: int = 0, frame_step: int = 1) -> str:
    """The likeliest cause of a failed camera, in words, from its :func:`scan_offsets`
    (``frame_offset``: the camera's offset in the rig file, for the fix; ``frame_step``:
    the frames between two rows of the scanned arrays, a video read every n-th frame)."""
    if scan is None or scan.correspondences[scan.shifts == 0][0] < MIN_SCAN_CORRESPONDENCES:
        n = 0 if scan is None else int(scan.correspondences[scan.shifts == 0][0])
        return (f"too few keypoints ({n} joint observations shared with the sound cameras, "
                f"{MIN_SCAN_CORRESPONDENCES} needed to judge)")
    best, here = scan.best, scan.at(0)
    top = scan.at(best)
    frames = best * int(frame_step)
    if best != 0 and top >= MIN_FIT_SHARE and top >= OFFSET_GAIN * here:
        edge = " or more (the end of the scan)" if abs(best) == scan.shifts.max() else ""
        return (f"a time offset: its frames fit the others best shifted by {frames:+d}{edge} "
                f"({100 * top:.0f} % of its joints consistent, {100 * here:.0f} % as given): "
                f"set frame_offset = {frame_offset + frames} for it in the rig file")
    return (f"its people do not match the others' ({100 * here:.0f} % of its joints "
            f"consistent with the other cameras, at best {100 * top:.0f} % over shifts of "
            f"-{len(scan.shifts) // 2}..{len(scan.shifts) // 2} frames)")


def most_confident(people: list[np.ndarray], T: int, J: int, joints: np.ndarray
                   ) -> np.ndarray:
    """``(T, J, 3)`` per frame the detection of highest summed confidence over ``joints``
    among ``people`` (``T`` arrays ``(P_t, J, 3)``), NaN where none."""
    out = np.full((T, J, 3), np.nan)
    for t, p in enumerate(people[:T]):
        if len(p):
            conf = np.nan_to_num(np.asarray(p)[:, joints, 2]).sum(1)
            out[t] = p[int(np.argmax(conf))]
    return out


#: :func:`offset_hint` scans this many of a camera's longest tracks (and its most confident
#: detection per frame).
HINT_TRACKS = 3


def candidate_people(people: list[np.ndarray], T: int, J: int, joints: np.ndarray,
                     min_confidence: float = DEFAULT_MIN_CONFIDENCE) -> list[np.ndarray]:
    """``(T, J, 3)`` sequences that may be a camera's person: its most confident detection
    per frame, and its :data:`HINT_TRACKS` longest tracks (:func:`~.tracking.track_people`),
    NaN where absent."""
    out = [most_confident(people, T, J, joints)]
    ids = track_people(list(people[:T]), joints, min_confidence)
    flat = np.concatenate([np.asarray(i, int).ravel() for i in ids]) if ids else np.zeros(0)
    labels, counts = np.unique(flat[flat >= 0], return_counts=True)
    for label in labels[np.argsort(-counts)][:HINT_TRACKS]:
        seq = np.full((T, J, 3), np.nan)
        for t, (p, i) in enumerate(zip(people[:T], ids)):
            hit = np.flatnonzero(np.asarray(i) == label)
            if hit.size:
                seq[t] = np.asarray(p)[hit[0]]
        out.append(seq)
    return out


def offset_hint(ref_person: np.ndarray, K_ref: np.ndarray, people: list[np.ndarray],
                K: np.ndarray, joints: np.ndarray, threshold_px: float, frame_offset: int = 0,
                frame_step: int = 1, *, min_confidence: float = DEFAULT_MIN_CONFIDENCE) -> str | None:
    """A time offset where a camera none of whose people matches the reference camera's
    person fits it shifted (:func:`scan_offsets` of its most confident detection per
    frame against ``ref_person``), in words; ``None`` where no shift names one.

    Args:
        ref_person: ``(T, J, 3)`` the reference camera's person on this camera's frames.
        K_ref, K: ``(3, 3)`` the two cameras' intrinsics.
        people: ``T`` arrays ``(P_t, J, 3)``: this camera's detections per frame.
        joints: the joints compared (indices).
        threshold_px: the inlier threshold, pixels.
        frame_offset: the camera's offset in the rig file, for the fix.
        frame_step: the camera's frames between two rows (a video read every n-th frame).
    """
    joints = np.asarray(joints, int)
    T, J = ref_person.shape[:2]

    def pixels(a):
        out = np.full((T, J, 2), np.nan)
        ok = np.nan_to_num(a[:, joints, 2]) >= min_confidence
        out[:, joints] = np.where(ok[..., None], a[:, joints, :2], np.nan)
        return out

    ref = pixels(np.asarray(ref_person, float))
    found = []
    for mine in candidate_people(people, T, J, joints, min_confidence):
        scan = scan_offsets([pixels(mine), ref], [K, K_ref], 0, [1], threshold_px)
        cause = failure_cause(scan, frame_offset, frame_step)
        if cause.startswith("a time offset"):
            found.append((scan.at(scan.best), cause))
    return max(found)[1] if found else None
