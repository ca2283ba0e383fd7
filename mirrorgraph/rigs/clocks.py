"""Cameras on different clocks: each camera's time offset found from the people it sees.

A camera with offset ``o`` (frames of the rig's clock, the first camera's) shows at its
frame ``f`` the rig's frame ``f - o`` (the rig file's ``frame_offset``); a fractional
``o`` puts its frames between the rig's. Every camera is compared with the reference
camera (the first) on the person both see, in two steps:

1. **Whole frames** (:func:`scan_shifts`): for every shift ``s`` of a window about the
   given offset, the camera's joints at its frame ``t + s`` are matched with the
   reference's at ``t`` and the essential matrix of least median Sampson distance is
   fitted to them (OpenCV's five-point solver in LMedS, the cameras' intrinsics); that
   median (pixels) is the shift's cost, lowest where the two views see one instant. It
   needs no threshold, hence no guess of the detector's noise. A moving person makes the
   true shift stand out; a still one gives a flat curve (:attr:`ShiftScan.contrast`
   below :data:`MIN_CONTRAST`: the offset is kept as given, with a warning).
2. **A fraction of a frame** (:func:`subframe_offset`): about the best shift each joint's
   trajectory is the least-squares quadratic through ``2 HALF_WINDOW + 1`` samples
   (a Savitzky-Golay filter evaluated between samples; the reference's the same filter
   at its sample), the camera's evaluated at ``t + s + dt``; the relative pose (five
   parameters) and ``dt`` are fitted together by robust least squares (Huber loss on the
   Sampson distance, its scale the whole shift's median), each residual scaled by the
   filter's noise at ``dt`` so that no ``dt`` is favoured for averaging the noise more.
   ``dt``'s std is the spread of that fit over a block bootstrap of the reference's
   frames (blocks of :data:`BOOTSTRAP_BLOCK` samples: the detector's error and the
   person's motion are correlated over neighbouring frames, which a curvature std
   would ignore). The offset is observable only where the joints move across the
   epipolar lines: the std says how well.

Continuous-time calibration treats a camera's time as ``t + dt`` in the same way (e.g.
Kalibr's temporal calibration, Furgale et al., IROS 2013); Pose2Sim synchronises whole
frames from the keypoints' speeds instead. :func:`resample` puts a camera's keypoints on
the rig's frames for a fractional offset (linear interpolation of each joint between the
two frames around it).

Shapes: a camera's person is ``(T_c, J, 2)`` normalised or pixel coordinates on its own
samples (NaN where unseen); a sample is one row of its frames (``frame_step`` frames
apart for a video read every n-th frame).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from ..geometry import sampson_distances
from ..keypoints import DEFAULT_MIN_CONFIDENCE
from .config import OFFSET_WINDOW
from .failure import candidate_people

__all__ = ["ClockEstimate", "ShiftScan", "MIN_CORRESPONDENCES",
           "BOOTSTRAP_BLOCK", "BOOTSTRAP_RUNS", "scan_shifts", "subframe_offset",
           "estimate_offset", "resample", "dense_samples", "find_clocks", "on_rig_clock",
           "frame_step", "INLIER_SCALES", "MIN_CONTRAST"]

#: Fewer correspondences (joint pairs seen at one instant) than this at a shift: the
#: shift is not judged.
MIN_CORRESPONDENCES = 60
#: Correspondences per shift at most (taken evenly): the scan's cost.
MAX_CORRESPONDENCES = 3000
#: Frames of one block of the block bootstrap of the sub-frame offset's std.
BOOTSTRAP_BLOCK = 10
#: Bootstrap resamples of the sub-frame offset's std.
BOOTSTRAP_RUNS = 30
#: The sub-frame fit keeps the correspondences within this many robust stds of the
#: whole shift's essential matrix.
INLIER_SCALES = 3.0
#: A scan whose best shift does not stand out by this factor
#: (:attr:`ShiftScan.contrast`) judges nothing.
MIN_CONTRAST = 1.25


@dataclass
class ShiftScan:
    """The epipolar cost of a camera against the reference per whole shift.

    Attributes:
        shifts: ``(S,)`` samples: the camera's sample ``t + s`` against the reference's ``t``.
        cost: ``(S,)`` the median Sampson distance (pixels) under the essential matrix of
            least median (lower fits better; NaN where fewer than
            :data:`MIN_CORRESPONDENCES`).
        correspondences: ``(S,)`` correspondences per shift.
    """

    shifts: np.ndarray
    cost: np.ndarray
    correspondences: np.ndarray

    @property
    def best(self) -> int | None:
        """The shift of lowest cost (``None`` where no shift was judged)."""
        ok = np.isfinite(self.cost)
        if not ok.any():
            return None
        return int(self.shifts[ok][int(np.argmin(self.cost[ok]))])

    def cost_at(self, shift: int) -> float:
        """The cost at ``shift`` (NaN outside the scan)."""
        hit = np.flatnonzero(self.shifts == shift)
        return float(self.cost[hit[0]]) if hit.size else float("nan")

    @property
    def contrast(self) -> float:
        """How far the best shift stands out: the median cost of the shifts more than one
        sample away from it over its own cost (1: a flat curve; NaN: nothing judged)."""
        b = self.best
        if b is None:
            return float("nan")
        far = np.isfinite(self.cost) & (np.abs(self.shifts - b) > 1)
        if not far.any():
            return float("nan")
        return float(np.median(self.cost[far]) / max(self.cost_at(b), 1e-12))


@dataclass
class ClockEstimate:
    """One camera's time offset against the reference camera.

    Attributes:
        offset: frames of the rig's clock: the camera's frame ``f`` is the rig's frame
            ``f - offset`` (the rig file's ``frame_offset``, fractional).
        std: its std, frames (0 for the reference, NaN where not estimated).
        source: ``"reference"``, ``"given"`` (the rig file's, not searched, or the data
            could not judge it), or ``"search"``.
        given: the rig file's ``frame_offset``.
        scan: the whole-frame scan (``None`` where not searched); its shifts in samples.
        note: why the offset is what it is where that needs saying (the data disagree
            with the given offset, too few correspondences, a flat scan), else ``""``.
    """

    offset: float
    std: float
    source: str
    given: int = 0
    scan: ShiftScan | None = field(default=None, repr=False)
    note: str = ""

    @property
    def whole(self) -> int:
        """The offset rounded to whole frames."""
        return int(np.round(self.offset))


def dense_samples(points: np.ndarray, frame_ids: np.ndarray, base: int, step: int,
                  length: int) -> np.ndarray:
    """``(length, J, 2)``: a camera's ``(T_c, J, 2)`` points at rows ``(frame - base) /
    step`` of a grid of samples (NaN elsewhere; frames off the grid dropped)."""
    out = np.full((length,) + points.shape[1:], np.nan)
    rel = np.asarray(frame_ids, np.int64) - int(base)
    on = (rel % step == 0) & (rel >= 0) & (rel // step < length)
    out[rel[on] // step] = points[on]
    return out


def _pairs(a: np.ndarray, b: np.ndarray, s: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``a`` at samples ``t + s`` and ``b`` at ``t`` where both see a joint: ``(N, 2)``,
    ``(N, 2)`` and the ``(N,)`` samples ``t`` of ``b``."""
    T = min(len(a), len(b))
    t = np.arange(max(0, -s), min(T, len(a) - s))
    if not t.size:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, int)
    A, B = a[t + s], b[t]
    ok = np.isfinite(A).all(-1) & np.isfinite(B).all(-1)
    rows = np.broadcast_to(t[:, None], ok.shape)
    return A[ok], B[ok], rows[ok]


def _essential(xa: np.ndarray, xb: np.ndarray, seed: int
               ) -> tuple[np.ndarray | None, float]:
    """The essential matrix of normalised correspondences (``xb^T E xa = 0``) of least
    median Sampson distance (OpenCV's five-point solver in LMedS: no threshold, so the
    cost does not depend on a guess of the detector's noise) and that median
    (normalised)."""
    cv2.setRNGSeed(int(seed))
    E, _ = cv2.findEssentialMat(xa, xb, np.eye(3), method=cv2.LMEDS, prob=0.999,
                                maxIters=1000)
    if E is None or E.shape[1:] != (3,) or E.shape[0] < 3:
        return None, float("inf")
    best, cost = None, float("inf")
    for k in range(E.shape[0] // 3):
        d = np.abs(sampson_distances(E[3 * k:3 * k + 3], xa, xb))
        c = float(np.median(np.nan_to_num(d, nan=np.inf)))
        if c < cost:
            best, cost = E[3 * k:3 * k + 3], c
    return best, cost


def _evenly(n: int, most: int) -> np.ndarray:
    return np.arange(n) if n <= most else np.linspace(0, n - 1, most).round().astype(int)


def scan_shifts(camera: np.ndarray, reference: np.ndarray, f: float, shifts,
                *, seed: int = 0) -> ShiftScan:
    """The epipolar cost of ``camera`` against ``reference`` per whole shift.

    Args:
        camera, reference: ``(N, J, 2)`` normalised coordinates (``K^-1`` applied) on one
            grid of samples, NaN where unseen.
        f: a focal length, pixels (the cost's scale).
        shifts: the shifts tried, samples (the camera's ``t + s`` against ``t``).
        seed: OpenCV's RANSAC seed.
    """
    shifts = np.asarray(list(shifts), int)
    cost = np.full(len(shifts), np.nan)
    corr = np.zeros(len(shifts), int)
    for i, s in enumerate(shifts):
        xa, xb, _ = _pairs(camera, reference, int(s))
        corr[i] = len(xa)
        if len(xa) < MIN_CORRESPONDENCES:
            continue
        keep = _evenly(len(xa), MAX_CORRESPONDENCES)
        cost[i] = _essential(xa[keep], xb[keep], seed)[1] * f
    return ShiftScan(shifts=shifts, cost=cost, correspondences=corr)


#: Samples either side of the one a joint's trajectory is evaluated about (the local
#: quadratic's window is twice this plus one).
HALF_WINDOW = 3


def _local_quadratic(u: float) -> np.ndarray:
    """``(2 HALF_WINDOW + 1,)`` weights of the samples ``-HALF_WINDOW..HALF_WINDOW`` giving
    the least-squares quadratic through them at ``u`` (a Savitzky-Golay filter at any
    point): smooth in ``u``, and with nearly the same noise for every ``u`` in [-1, 1]."""
    x = np.arange(-HALF_WINDOW, HALF_WINDOW + 1, dtype=float)
    X = np.vander(x, 3, increasing=True)
    return np.array([1.0, u, u * u]) @ np.linalg.solve(X.T @ X, X.T)


def _noise_factor(u: float) -> float:
    """The variance of the local quadratic at ``u`` over one sample's (``w . w``)."""
    w = _local_quadratic(u)
    return float(w @ w)


def _windows(a: np.ndarray, b: np.ndarray, s: int
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The correspondences about shift ``s`` whose camera is seen at every sample of
    ``t + s - HALF_WINDOW .. t + s + HALF_WINDOW`` and the reference at every one of
    ``t - HALF_WINDOW .. t + HALF_WINDOW``: ``(W, N, 2)`` the camera's, ``(W, N, 2)`` the
    reference's, ``(N,)`` the reference's samples ``t``."""
    h = HALF_WINDOW
    T = len(b)
    t = np.arange(max(h, h - s), min(T - h, len(a) - s - h))
    if not t.size:
        return np.zeros((2 * h + 1, 0, 2)), np.zeros((2 * h + 1, 0, 2)), np.zeros(0, int)
    offs = np.arange(-h, h + 1)
    A = np.stack([a[t + s + o] for o in offs])                  # (W, n, J, 2)
    B = np.stack([b[t + o] for o in offs])
    ok = np.isfinite(A).all((0, -1)) & np.isfinite(B).all((0, -1))
    rows = np.broadcast_to(t[:, None], ok.shape)
    return A[:, ok], B[:, ok], rows[ok]


def _at(W: np.ndarray, u: float) -> np.ndarray:
    """``(N, 2)``: the local quadratic of the samples ``W`` (``(2 HALF_WINDOW + 1, N, 2)``)
    at ``u`` samples from their centre."""
    return np.tensordot(_local_quadratic(u), W, axes=1)


def _rotation(r: np.ndarray) -> np.ndarray:
    return cv2.Rodrigues(np.asarray(r, float).reshape(3, 1))[0]


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]], float)


def _fit_subframe(A3, xb, E0_R, E0_t, dt0, f, huber_px):
    """Least squares of ``(rotation, translation direction, dt)`` from a start; returns
    ``(dt, R, t)``."""
    from scipy.optimize import least_squares

    t0 = E0_t / np.linalg.norm(E0_t)
    u = np.cross(t0, [1.0, 0, 0] if abs(t0[0]) < 0.9 else [0, 1.0, 0])
    u /= np.linalg.norm(u)
    v = np.cross(t0, u)

    def parts(p):
        R = _rotation(p[:3]) @ E0_R
        t = t0 + p[3] * u + p[4] * v
        return R, t / np.linalg.norm(t)

    v0 = _noise_factor(0.0)

    def residuals(p):
        R, t = parts(p)
        d = sampson_distances(_skew(t) @ R, _at(A3, p[5]), xb) * f
        # the same noise for every dt: the local quadratic's varies a little with it
        d *= np.sqrt(2 * v0 / (v0 + _noise_factor(p[5])))
        return np.nan_to_num(d, nan=0.0, posinf=0.0, neginf=0.0)

    x0 = np.array([0, 0, 0, 0, 0, float(np.clip(dt0, -0.99, 0.99))])
    lo = np.array([-np.inf] * 5 + [-1.0])
    hi = np.array([np.inf] * 5 + [1.0])
    res = least_squares(residuals, x0, bounds=(lo, hi), loss="huber", f_scale=huber_px,
                        x_scale="jac", diff_step=1e-4, max_nfev=200)
    R, t = parts(res.x)
    return float(res.x[5]), R, t


def subframe_offset(camera: np.ndarray, reference: np.ndarray, shift: int, f: float,
                    *, seed: int = 0, runs: int = BOOTSTRAP_RUNS) -> tuple[float, float]:
    """The fraction of a sample ``dt`` (in [-1, 1]) by which ``camera``'s sample ``t + shift
    + dt`` matches ``reference``'s ``t`` best, and its std (see the module docstring).

    The residuals' scale is read from the data: ``s`` = 1.4826 times the median Sampson
    distance under the shift's essential matrix (the normal's MAD); correspondences
    farther than :data:`INLIER_SCALES` ``s`` are left out and the Huber loss turns linear
    at ``s``.

    Args:
        camera, reference: ``(N, J, 2)`` normalised coordinates on one grid, NaN unseen.
        shift: the whole shift found (:func:`scan_shifts`).
        f: a focal length, pixels (the Sampson distance's scale).
        seed: seed of the RANSAC and of the bootstrap.
        runs: bootstrap resamples (0: no std, NaN).

    Returns:
        ``(dt, std)`` samples; ``(0, NaN)`` where too few correspondences.
    """
    A3, B3, rows = _windows(camera, reference, int(shift))
    if len(rows) < MIN_CORRESPONDENCES:
        return 0.0, float("nan")
    keep = _evenly(len(rows), MAX_CORRESPONDENCES)
    A3, xb, rows = A3[:, keep], _at(B3[:, keep], 0.0), rows[keep]
    E, median = _essential(_at(A3, 0.0), xb, seed)
    if E is None or not median > 0:
        return 0.0, float("nan")
    scale = 1.4826 * median
    inl = np.abs(sampson_distances(E, _at(A3, 0.0), xb)) < INLIER_SCALES * scale
    if inl.sum() < MIN_CORRESPONDENCES:
        return 0.0, float("nan")
    A3, xb, rows = A3[:, inl], xb[inl], rows[inl]
    _, R0, t0, _ = cv2.recoverPose(E, _at(A3, 0.0), xb, np.eye(3))
    t0 = t0.ravel()
    huber = scale * f
    # the start: the best of a coarse grid of dt under the shift's pose
    Ee = _skew(t0 / np.linalg.norm(t0)) @ R0
    grid = np.linspace(-1.0, 1.0, 9)
    costs = np.array([np.sum(_huber(sampson_distances(Ee, _at(A3, g), xb) * f, huber))
                      for g in grid])
    dt, R, t = _fit_subframe(A3, xb, R0, t0, _parabola_min(grid, costs), f, huber)
    if runs <= 0:
        return dt, float("nan")
    rng = np.random.default_rng(seed)
    frames = np.unique(rows)
    blocks = [frames[i:i + BOOTSTRAP_BLOCK] for i in range(0, len(frames), BOOTSTRAP_BLOCK)]
    by_row = {r: np.flatnonzero(rows == r) for r in frames}
    draws = []
    for _ in range(int(runs)):
        pick = rng.integers(0, len(blocks), len(blocks))
        idx = np.concatenate([by_row[r] for k in pick for r in blocks[k]])
        if len(idx) < MIN_CORRESPONDENCES:
            continue
        draws.append(_fit_subframe(A3[:, idx], xb[idx], R, t, dt, f, huber)[0])
    std = float(np.std(draws, ddof=1)) if len(draws) > 1 else float("nan")
    return dt, std


def _parabola_min(x: np.ndarray, y: np.ndarray) -> float:
    """The minimum of the parabola through the lowest of ``y`` on the grid ``x`` and its
    two neighbours (the grid point itself at an end or where the three do not curve up)."""
    i = int(np.argmin(y))
    if i == 0 or i == len(x) - 1:
        return float(x[i])
    a = 0.5 * (y[i + 1] - 2 * y[i] + y[i - 1])
    if a <= 0:
        return float(x[i])
    h = x[1] - x[0]
    return float(x[i] - h * 0.25 * (y[i + 1] - y[i - 1]) / a)


def _huber(r: np.ndarray, k: float) -> np.ndarray:
    a = np.abs(np.nan_to_num(r, nan=k, posinf=k, neginf=k))
    return np.where(a <= k, 0.5 * a ** 2, k * (a - 0.5 * k))


def estimate_offset(candidates: list[np.ndarray], reference: np.ndarray, f: float,
                    *, given: int = 0, step: int = 1,
                    window: int = OFFSET_WINDOW, seed: int = 0,
                    runs: int = BOOTSTRAP_RUNS) -> ClockEstimate:
    """A camera's offset against the reference camera (whole frames, then a fraction).

    Args:
        candidates: the sequences that may be the camera's person, each ``(N, J, 2)``
            normalised coordinates on one grid of samples with the reference
            (:func:`dense_samples`: row ``r`` is frame ``base + r * step`` of each camera's
            own numbering), NaN where unseen; the one whose best shift fits best is taken.
        reference: ``(N, J, 2)`` the reference camera's person on that grid.
        f: a focal length, pixels (the Sampson distance's scale).
        given: the offset the rig file gives (relative to the reference's), frames: the
            centre of the window.
        step: frames between two samples.
        window: frames either way of ``given``.
        seed: seed of every random choice.
        runs: bootstrap resamples of the std.

    Returns:
        :class:`ClockEstimate` relative to the reference (``offset`` frames: the camera's
        frame ``f`` is the reference's ``f - offset``).
    """
    step = max(int(step), 1)
    centre = int(np.round(given / step))
    reach = max(int(np.ceil(window / step)), 1)
    scans = [scan_shifts(c, reference, f,
                         range(centre - reach, centre + reach + 1), seed=seed)
             for c in candidates]
    lowest = [np.nanmin(s.cost) if np.isfinite(s.cost).any() else np.inf for s in scans]
    pick = int(np.argmin(lowest))
    scan, camera = scans[pick], candidates[pick]
    best = scan.best
    if best is None:
        n = int(max(s.correspondences.max() for s in scans))
        return ClockEstimate(offset=float(given), std=float("nan"), source="given", given=given,
                             scan=scan, note=f"too few joints seen with the reference camera "
                                             f"at any shift ({n} at most, "
                                             f"{MIN_CORRESPONDENCES} needed): kept as given "
                                             f"({given})")
    if not scan.contrast > MIN_CONTRAST:
        return ClockEstimate(offset=float(given), std=float("nan"), source="given", given=given,
                             scan=scan, note="no shift fits clearly better than the others "
                                             "(does the person move?): kept as given "
                                             f"({given})")
    dt, std = subframe_offset(camera, reference, best, f, seed=seed, runs=runs)
    offset = (best + dt) * step
    note = ""
    if int(np.round(offset)) != given and (not np.isfinite(std) or
                                           abs(offset - given) > 3 * std * step):
        edge = " (the edge of the search window)" if abs(best - centre) == reach else ""
        note = (f"the people put it at {offset:+.2f} frames{edge} against the rig file's "
                f"frame_offset = {given}")
    return ClockEstimate(offset=float(offset), std=float(std * step), source="search",
                         given=given, scan=scan, note=note)


def resample(a: np.ndarray, dt: float) -> np.ndarray:
    """``(T, J, C)`` keypoints at rows ``t + dt`` instead of ``t`` (``dt`` in samples, any
    sign): each coordinate interpolated linearly between the two rows around, the
    confidence (last channel) the smaller of theirs; NaN coordinates and confidence 0
    where either row lacks the joint or falls outside."""
    a = np.asarray(a, float)
    if dt == 0:
        return a.copy()
    k = int(np.floor(dt))
    w = float(dt - k)
    T = len(a)
    idx = np.arange(T) + k
    out = np.full_like(a, np.nan)
    out[..., -1] = 0.0
    lo_ok = (idx >= 0) & (idx < T)
    hi_ok = (idx + 1 >= 0) & (idx + 1 < T)
    if w == 0:
        rows = np.flatnonzero(lo_ok)
        out[rows] = a[idx[rows]]
        return out
    rows = np.flatnonzero(lo_ok & hi_ok)
    lo, hi = a[idx[rows]], a[idx[rows] + 1]
    xy = (1 - w) * lo[..., :-1] + w * hi[..., :-1]
    conf = np.minimum(np.nan_to_num(lo[..., -1]), np.nan_to_num(hi[..., -1]))
    seen = np.isfinite(xy).all(-1) & (conf > 0)
    out[rows, ..., :-1] = np.where(seen[..., None], xy, np.nan)
    out[rows, ..., -1] = np.where(seen, conf, 0.0)
    return out


def _pixels(seq: np.ndarray, joints: np.ndarray, min_confidence: float) -> np.ndarray:
    """``(T, J, 2)`` a ``(T, J, 3)`` sequence's ``joints`` seen with ``min_confidence``."""
    seq = np.asarray(seq, float)
    out = np.full(seq.shape[:2] + (2,), np.nan)
    ok = np.nan_to_num(seq[:, joints, 2]) >= min_confidence
    out[:, joints] = np.where(ok[..., None], seq[:, joints, :2], np.nan)
    return out


def _normalised(xy: np.ndarray, K: np.ndarray) -> np.ndarray:
    K = np.asarray(K, float)
    return (xy - K[:2, 2]) @ np.linalg.inv(K[:2, :2]).T


def frame_step(frame_ids: np.ndarray) -> int:
    """The frames between two samples of a camera (a video read every n-th frame): the
    median difference of its frame numbers, at least 1."""
    ids = np.asarray(frame_ids)
    return max(int(np.median(np.diff(ids))), 1) if len(ids) > 1 else 1


def find_clocks(people: list[tuple[np.ndarray, list[np.ndarray] | None]],
                frame_ids: list[np.ndarray], Ks: list[np.ndarray], given: list[int],
                joints, *, search: bool = True, window: int = OFFSET_WINDOW, seed: int = 0,
                min_confidence: float = DEFAULT_MIN_CONFIDENCE,
                runs: int = BOOTSTRAP_RUNS) -> list[ClockEstimate]:
    """Every camera's time offset (see the module docstring); the first is the reference.

    Args:
        people: per camera ``(person, candidates)``: the ``(T_c, J, 3)`` person as the
            camera alone sees it (undistorted pixels; the reference camera's: its
            subject) and ``T_c`` arrays ``(P_t, J, 3)`` of candidates for the person per
            frame, or ``None``; where a frame holds several, the camera's longest tracks
            compete too (:func:`~mirrorgraph.rigs.failure.candidate_people`).
        frame_ids: per camera ``(T_c,)`` its own frame numbers.
        Ks: per camera ``(3, 3)`` intrinsics (of the undistorted pixels).
        given: per camera the rig file's ``frame_offset``.
        joints: the joints compared (indices).
        search: search the offsets (else every camera keeps its given one).
        window: frames searched either way of a camera's given offset (relative to the
            reference's).
        seed: seed of every random choice.
        min_confidence: joints below this confidence are left out.
        runs: bootstrap resamples of the stds.

    Returns:
        per camera a :class:`ClockEstimate` on the rig's clock (``offset``: the camera's
        frame ``f`` is the rig's frame ``f - offset``).
    """
    joints = np.asarray(joints, int)
    out = [ClockEstimate(offset=float(given[0]), std=0.0, source="reference", given=given[0])]
    if not search or len(people) < 2:
        return out + [ClockEstimate(offset=float(g), std=float("nan"), source="given", given=g)
                      for g in given[1:]]
    steps = [frame_step(f) for f in frame_ids]
    step = steps[0]
    base = int(min(np.min(f) for f in frame_ids if len(f)))
    length = int((max(np.max(f) for f in frame_ids if len(f)) - base) // step + 1)
    ref_px = _pixels(people[0][0], joints, min_confidence)
    ref = dense_samples(_normalised(ref_px, Ks[0]), frame_ids[0], base, step, length)
    for c in range(1, len(people)):
        rel = int(given[c]) - int(given[0])
        if steps[c] != step:
            out.append(ClockEstimate(offset=float(given[c]), std=float("nan"), source="given",
                                     given=given[c],
                                     note=f"its frames are {steps[c]} apart, the reference's "
                                          f"{step}: not searched, kept as given ({given[c]})"))
            continue
        person, cands = people[c]
        seqs = [np.asarray(person, float)]
        if cands is not None and any(len(p) > 1 for p in cands):
            seqs += candidate_people(cands, *seqs[0].shape[:2], joints, min_confidence)
        dense = [dense_samples(_normalised(_pixels(s, joints, min_confidence), Ks[c]),
                               frame_ids[c], base, step, length) for s in seqs]
        f = 0.25 * (Ks[0][0, 0] + Ks[0][1, 1] + Ks[c][0, 0] + Ks[c][1, 1])
        est = estimate_offset(dense, ref, f, given=rel, step=step, window=window,
                              seed=seed, runs=runs)
        est.offset += given[0]
        est.given = int(given[c])
        if est.source == "given":
            est.offset = float(given[c])
        out.append(est)
    return out


def on_rig_clock(a: np.ndarray, clock: ClockEstimate, step: int = 1) -> np.ndarray:
    """A camera's ``(T, J, 3)`` keypoints placed on the rig's rows by its whole offset,
    moved by the offset's fraction (:func:`resample`; ``step``: frames between two rows)."""
    frac = clock.offset - clock.whole
    if clock.source != "search" or frac == 0:
        return a
    return resample(a, frac / max(int(step), 1))
