"""Cameras on different clocks: each camera's time offset (and clock rate) found from the people.

The rig's clock runs at the first camera's frame rate times a whole number (the finest
the cameras need: :func:`rig_rates`). A camera at ``rate`` rig frames per own frame (2 for
30 fps on a 60 fps clock), offset ``o`` (rig frames) and clock rate ``r`` (1 unless its
drift is measured) shows at its frame ``g`` the rig's frame ``(rate g - o) / r``: at one
frame rate, frame ``f`` shows rig frame ``f - o`` (the rig file's ``frame_offset``); a
fractional ``o`` puts its frames between the rig's. Three steps (three cameras or more):

1. **A start** (:func:`coarse_cost`): per camera, the best of every sixth whole shift by
   the least median Sampson distance of an essential matrix fitted there (LMedS).
2. **Whole offsets against the rig** (:func:`_rig_search`): the rig's poses from the
   essential matrix of the reference and its best partner, the others resected; then in
   rounds every camera's median reprojection error per whole shift against the joints
   triangulated from all the others at their offsets, its pose resected anew at every
   shift (so no shift is favoured), the best taken; from the start, and from the rig
   file's offsets where they fit the rig better than that result, the configuration the
   rig fits better kept.
3. **Fractions against the rig** (:func:`_rig_fraction`): every camera's joints as
   local quadratics of its own samples, evaluated at its own instants ``t + u`` on a grid
   of ``u`` (a 30 fps camera's seven samples span twelve frames of a 60 fps clock), the
   others at their latest fractions, the Huber cost fitted by a quadratic, in rounds; the
   std the M-estimator's sandwich over blocks of samples through the cameras' coupling. A camera leaves the rig file's whole offset
   only where the move is significant (the block bootstrap of its whole-shift scan
   prefers it in :data:`ACCEPT_LEVEL` of the draws, or the fraction lies beyond
   :data:`FRACTION_Z` stds) and the draws agree on it (:data:`MOVE_SPREAD`); a fraction
   is applied beyond :data:`FRACTION_Z` stds, or where the camera moved and the people
   fix it within half a frame.

With ``drift`` (the rig file's ``clock_drift``) a line through each camera's fractions in
:data:`DRIFT_STRETCHES` stretches gives its clock rate and offset (:func:`_drift`).

Two cameras: the pair's epipolar cost per whole shift (:func:`scan_shifts`,
:func:`joint_offsets`) and the fraction against the reference (:func:`subframe_offset`).
:func:`on_rig_clock` puts a camera's keypoints on the rig's frames at their instants
(linear interpolation). Reference: Kalibr's temporal calibration (Furgale et al., IROS 2013).

Shapes: a camera's person is ``(T_c, J, 2)`` coordinates on its own samples (NaN where
unseen; a sample is one row, ``frame_step`` frames apart); the scans run on a grid of rig
frames (:class:`_Track`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from ..geometry import sampson_distances, skew
from ..keypoints import DEFAULT_MIN_CONFIDENCE
from .config import OFFSET_WINDOW
from .failure import candidate_people
from .tracking import TRACK_MAX_GAP, jumping

__all__ = ["ClockEstimate", "ShiftScan", "MIN_CORRESPONDENCES", "COARSE_STRIDE", "coarse_cost",
           "ACCEPT_LEVEL", "FRACTION_Z", "FRACTION_REACH", "BOOTSTRAP_BLOCK", "BOOTSTRAP_RUNS",
           "BOOTSTRAP_DRAWS", "scan_shifts", "joint_offsets", "subframe_offset", "resample",
           "dense_samples", "find_clocks", "on_rig_clock", "frame_step", "rig_instants",
           "rig_rates",
           "INLIER_SCALES"]

#: Fewer correspondences (joint pairs seen at one instant) than this at a shift: the
#: shift is not judged.
MIN_CORRESPONDENCES = 60
#: Correspondences per shift judged at most (taken evenly): the scan's cost.
MAX_CORRESPONDENCES = 1500
#: Correspondences of one shift of the coarse scan at most.
COARSE_CORRESPONDENCES = 300
#: Correspondences of the sub-frame fit at most.
SUBFRAME_CORRESPONDENCES = 1000
#: The coarse scan fits an essential matrix at every this many shifts.
COARSE_STRIDE = 3
#: Samples of one block of the block bootstraps.
BOOTSTRAP_BLOCK = 10
#: Bootstrap resamples of the sub-frame offset's std (each a robust fit).
BOOTSTRAP_RUNS = 12
#: Bootstrap draws of the whole offsets' test and std (each a weighted median).
BOOTSTRAP_DRAWS = 200
#: A camera leaves its given whole offset where the found one fits better in this share
#: of the bootstrap draws (a one-sided test at 1 %).
ACCEPT_LEVEL = 0.99

#: A camera moves from its given offset only where the bootstrap draws' best whole
#: shifts lie within this many frames (RMS) of the move: a shift the people fix to a
#: frame or two, not one a draw may put anywhere in the window (a camera seeing another
#: person part of the time).
MOVE_SPREAD = 2.0
#: A fraction of a frame is applied where it exceeds this many of its stds (the
#: two-sided normal test at 1 %).
FRACTION_Z = 2.576
#: Samples either way of the whole offset the sub-frame fit may move it (beyond one:
#: it also settles a whole offset the scan leaves a sample either way).
FRACTION_REACH = 2.0
#: The sub-frame fit keeps the correspondences within this many robust stds of the
#: whole shift's essential matrix.
INLIER_SCALES = 3.0


@dataclass
class ShiftScan:
    """The epipolar cost of camera ``b`` against camera ``a`` per whole shift.

    Attributes:
        shifts: ``(S,)`` samples: ``b``'s sample ``t + s`` against ``a``'s ``t`` (``s`` is
            ``o_b - o_a`` where it fits).
        cost: ``(S,)`` the median Sampson distance (pixels) under the pair's cross-fitted
            essential matrices (lower fits better; NaN where fewer than
            :data:`MIN_CORRESPONDENCES`).
        correspondences: ``(S,)`` correspondences per shift.
        distances: per shift the ``(n,)`` Sampson distances judged (pixels), or ``None``.
        rows: per shift the ``(n,)`` samples ``t`` of ``a`` of those, or ``None``.
    """

    shifts: np.ndarray
    cost: np.ndarray
    correspondences: np.ndarray
    distances: list = field(default_factory=list, repr=False)
    rows: list = field(default_factory=list, repr=False)

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


@dataclass
class ClockEstimate:
    """One camera's time offset (and clock rate) against the reference camera.

    Attributes:
        offset: frames of the rig's clock (``unit`` to a reference camera's frame): the
            camera's frame ``g`` shows the rig's frame ``(rate_nominal g - offset) / rate``
            (the rig file's ``frame_offset`` times ``unit``, fractional), where
            ``rate_nominal`` is the rig's frames per camera frame its frame rate gives.
        std: its std, rig frames (0 for the reference, NaN where not searched): the whole
            offset's bootstrap spread and the fraction's together.
        source: ``"reference"``, ``"given"`` (the rig file's, not searched), or
            ``"search"`` (the search's: the given offset where the data do not
            significantly prefer another).
        given: the rig file's ``frame_offset``, rig frames.
        scan: the whole-frame scan against the rig (against the reference in a rig
            of two cameras; ``None`` where not searched); its shifts in samples.
        note: why the offset is what it is where that needs saying (the data disagree
            with the given offset, too few correspondences, a time the people hardly
            fix, a clock rate not determined), else ``""``.
        unit: the rig's frames per reference camera frame (2 for a 30 fps reference
            beside 60 fps cameras; else 1).
        rate: the camera's clock rate against the reference's (its frames per the
            reference's, over the ratio of their nominal frame rates): ``1 + drift``, 1
            where not estimated or not significant.
        rate_std: its std (NaN where not estimated).
        fps: the camera's nominal frame rate, or ``None`` where unknown.
        rig_fps: the rig clock's frame rate, or ``None`` where unknown.
    """

    offset: float
    std: float
    source: str
    given: int = 0
    scan: ShiftScan | None = field(default=None, repr=False)
    note: str = ""
    unit: int = 1
    rate: float = 1.0
    rate_std: float = float("nan")
    fps: float | None = None
    rig_fps: float | None = None

    @property
    def whole(self) -> int:
        """The offset rounded to whole rig frames."""
        return int(np.round(self.offset))

    @property
    def reference_frames(self) -> tuple[float, float]:
        """The offset and its std in the reference camera's frames."""
        return self.offset / self.unit, self.std / self.unit

    @property
    def seconds(self) -> tuple[float, float]:
        """The offset and its std in seconds (NaN where the rig's frame rate is unknown)."""
        if not self.rig_fps:
            return float("nan"), float("nan")
        return self.offset / self.rig_fps, self.std / self.rig_fps


def dense_samples(points: np.ndarray, frame_ids: np.ndarray, base: int, step: int,
                  length: int) -> np.ndarray:
    """``(length, J, 2)``: a camera's ``(T_c, J, 2)`` points at rows ``(frame - base) /
    step`` of a grid of samples (NaN elsewhere; frames off the grid dropped)."""
    out = np.full((length,) + points.shape[1:], np.nan)
    rel = np.asarray(frame_ids, np.int64) - int(base)
    on = (rel % step == 0) & (rel >= 0) & (rel // step < length)
    out[rel[on] // step] = points[on]
    return out


@dataclass
class _Track:
    """One camera's joints on its own samples and their place on the search's grid of
    samples (``step`` rig frames apart): its own sample ``k`` lies at grid position
    ``first + per k - o`` for an offset ``o`` (samples). A camera at the grid's rate has
    ``per = 1``; a 30 fps camera on a 60 fps grid ``per = 2``; a 25 fps one on a 30 fps
    grid ``per = 1.2`` (its samples between the grid's rows, placed at the nearest).

    Attributes:
        own: ``(n, J, 2)`` on its own consecutive samples, NaN unseen.
        first: grid position of its sample 0 at offset 0 (samples, fractional).
        per: grid samples per own sample (> 0).
        length: rows of the grid.
    """

    own: np.ndarray
    first: float
    per: float
    length: int

    def rows(self, offset: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The grid rows the camera's samples fall nearest at ``offset`` (samples): ``(m,)``
        rows, ``(m,)`` own samples ``k``, and ``(m,)`` the row's instant on the camera's
        own samples less ``k`` (its fraction of a sample, within half a row). One sample a
        row (of several, the nearest)."""
        k = np.arange(len(self.own))
        x = self.first + self.per * k - float(offset)
        r = np.round(x).astype(np.int64)
        ok = (r >= 0) & (r < self.length)
        k, x, r = k[ok], x[ok], r[ok]
        if self.per < 1 - 1e-9 and len(r):               # faster than the grid: the nearest
            order = np.lexsort((np.abs(x - r), r))
            first = np.r_[True, np.diff(r[order]) != 0]
            k, x, r = k[order][first], x[order][first], r[order][first]
        return r, k, (r - x) / self.per

    def samples(self, offset: float = 0.0) -> np.ndarray:
        """``(length, J, 2)``: the camera's joints at the rows its samples fall nearest at
        ``offset``, at those rows' instants: its own samples where they fall on a row, else
        interpolated linearly between the two around (NaN where either is unseen)."""
        out = np.full((self.length,) + self.own.shape[1:], np.nan)
        r, k, d = self.rows(offset)
        exact = np.abs(d) < 1e-9
        out[r[exact]] = self.own[k[exact]]
        r, k, d = r[~exact], k[~exact], d[~exact]
        lo = k + np.floor(d).astype(np.int64)
        w = (d - np.floor(d))[:, None, None]
        ok = (lo >= 0) & (lo + 1 < len(self.own))
        out[r[ok]] = (1 - w[ok]) * self.own[lo[ok]] + w[ok] * self.own[lo[ok] + 1]
        return out

    def window(self, centre: int) -> tuple[np.ndarray, np.ndarray]:
        """The local quadratics' samples about the rows the camera's samples fall nearest at
        the whole offset ``centre``: ``(2 HALF_WINDOW + 1, length, J, 2)`` its own samples
        ``k - HALF_WINDOW .. k + HALF_WINDOW`` at each such row (NaN elsewhere) and ``(length,)``
        the row's instant less ``k`` (own samples; NaN elsewhere). The camera at offset
        ``centre + u`` is ``_at(W, pos + u / per)``."""
        h = HALF_WINDOW
        W = np.full((2 * h + 1, self.length) + self.own.shape[1:], np.nan)
        pos = np.full(self.length, np.nan)
        r, k, d = self.rows(centre)
        for i, j in enumerate(range(-h, h + 1)):
            ok = (k + j >= 0) & (k + j < len(self.own))
            W[i, r[ok]] = self.own[k[ok] + j]
        pos[r] = d
        return W, pos

    def smoothed(self, centre: int, offset) -> np.ndarray:
        """``(length, J, 2)``: the local quadratics about the rows of the whole offset
        ``centre`` (:meth:`window`) evaluated at ``offset`` (samples; or ``(length,)``, one
        a row: a drifting clock)."""
        W, pos = self.window(int(centre))
        u = np.nan_to_num(pos) + (np.asarray(offset, float) - int(centre)) / self.per
        return _at(W, u)


def _track(points: np.ndarray, frame_ids: np.ndarray, rate: float, base: int, step: int,
           length: int) -> _Track:
    """A camera's ``(T_c, J, 2)`` points on its own frames ``frame_ids`` as a
    :class:`_Track` on the grid of samples ``(frame - base) / step`` of the rig's frames,
    its frame ``g`` at the rig's frame ``rate g`` (``rate``: the rig's frames per own
    frame)."""
    ids = np.asarray(frame_ids, np.int64)
    own_step = frame_step(ids)
    g0 = int(ids.min())
    n = int((ids.max() - g0) // own_step) + 1
    own = np.full((n,) + points.shape[1:], np.nan)
    on = (ids - g0) % own_step == 0
    own[(ids[on] - g0) // own_step] = points[on]
    return _Track(own=own, first=(rate * g0 - base) / step, per=rate * own_step / step,
                  length=int(length))


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
    E, _ = cv2.findEssentialMat(xa, xb, np.eye(3), method=cv2.LMEDS, prob=0.99,
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


def coarse_cost(camera: np.ndarray, reference: np.ndarray, shifts, *, seed: int = 0
                ) -> np.ndarray:
    """``(S,)`` the coarse scan (normalised units): at every :data:`COARSE_STRIDE`-th
    shift with enough correspondences, the least median Sampson distance of an essential
    matrix fitted at that shift alone (``inf`` elsewhere)."""
    shifts = np.asarray(list(shifts), int)
    out = np.full(len(shifts), np.inf)
    judged = [i for i, s in enumerate(shifts)
              if len(_pairs(camera, reference, int(s))[0]) >= MIN_CORRESPONDENCES]
    for i in judged[::COARSE_STRIDE]:
        xa, xb, _ = _pairs(camera, reference, int(shifts[i]))
        keep = _evenly(len(xa), COARSE_CORRESPONDENCES)
        out[i] = _essential(xa[keep], xb[keep], seed)[1]
    return out


def scan_shifts(camera: np.ndarray, reference: np.ndarray, f: float, shifts,
                *, seed: int = 0, coarse: np.ndarray | None = None) -> ShiftScan:
    """The epipolar cost of ``camera`` against ``reference`` per whole shift (see the
    module docstring, step 1).

    Args:
        camera, reference: ``(N, J, 2)`` normalised coordinates (``K^-1`` applied) on one
            grid of samples, NaN where unseen.
        f: a focal length, pixels (the cost's scale).
        shifts: the shifts tried, samples (the camera's ``t + s`` against ``t``).
        seed: OpenCV's RANSAC seed.
        coarse: the coarse scan (:func:`coarse_cost`) where already made.
    """
    shifts = np.asarray(list(shifts), int)
    S = len(shifts)
    cost = np.full(S, np.nan)
    found = [_pairs(camera, reference, int(s)) for s in shifts]
    corr = np.array([len(p[0]) for p in found], int)
    judged = np.flatnonzero(corr >= MIN_CORRESPONDENCES)
    scan = ShiftScan(shifts=shifts, cost=cost, correspondences=corr,
                     distances=[None] * S, rows=[None] * S)
    if not judged.size:
        return scan
    if coarse is None:
        coarse = coarse_cost(camera, reference, shifts, seed=seed)
    if not np.isfinite(coarse).any():
        return scan
    i0 = int(np.argmin(coarse))
    pool = [i for i in (i0 - 1, i0, i0 + 1) if 0 <= i < S and corr[i] >= MIN_CORRESPONDENCES]
    xa = np.concatenate([found[i][0] for i in pool])
    xb = np.concatenate([found[i][1] for i in pool])
    half = (np.concatenate([found[i][2] for i in pool]) // BOOTSTRAP_BLOCK) % 2
    Es = []
    for h in (0, 1):
        sel = np.flatnonzero(half == h)
        sel = sel[_evenly(len(sel), MAX_CORRESPONDENCES)]
        Es.append(_essential(xa[sel], xb[sel], seed)[0] if len(sel) >= MIN_CORRESPONDENCES
                  else None)
    if Es[0] is None or Es[1] is None:           # one half too thin: the whole pool
        keep = _evenly(len(xa), MAX_CORRESPONDENCES)
        E = _essential(xa[keep], xb[keep], seed)[0]
        if E is None:
            return scan
        Es = [E, E]
    for i in judged:
        xa, xb, rows = found[i]
        keep = _evenly(len(xa), MAX_CORRESPONDENCES)
        xa, xb, rows = xa[keep], xb[keep], rows[keep]
        odd = (rows // BOOTSTRAP_BLOCK) % 2 == 1
        # each block judged by the matrix fitted to the other parity's blocks
        d = np.where(odd, sampson_distances(Es[0], xa, xb), sampson_distances(Es[1], xa, xb))
        d = np.nan_to_num(np.abs(d), nan=np.inf) * f
        cost[i] = float(np.median(d))
        scan.distances[i], scan.rows[i] = d, rows
    return scan


def _weighted_medians(d: np.ndarray, blocks: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``(R,)`` medians of ``d`` (``(n,)``) with each value weighted by its block's weight
    in each row of ``weights`` (``(R, B)``; the bootstrap's draw counts)."""
    order = np.argsort(d)
    w = weights[:, blocks[order]]
    cs = np.cumsum(w, axis=1)
    total = cs[:, -1]
    idx = np.minimum((cs < 0.5 * total[:, None]).sum(1), len(d) - 1)
    out = d[order][idx]
    return np.where(total > 0, out, np.nan)


def _bootstrap_costs(scan: ShiftScan, weights: np.ndarray) -> np.ndarray:
    """``(R, S)``: the scan's costs under each draw of block weights (``(R, B)``)."""
    out = np.full((len(weights), len(scan.shifts)), np.nan)
    for i, (d, rows) in enumerate(zip(scan.distances, scan.rows)):
        if d is not None:
            out[:, i] = _weighted_medians(d, rows // BOOTSTRAP_BLOCK, weights)
    return out


class _PairCurves:
    """Every pair's cost relative to its lowest as a function of the pair's offset,
    for the full data (row 0) and the bootstrap draws (rows 1..R)."""

    def __init__(self, scans: dict, weights: np.ndarray):
        self.terms = {}
        for (a, b), scan in scans.items():
            lo = np.nanmin(scan.cost)
            curves = np.vstack([scan.cost[None], _bootstrap_costs(scan, weights)]) / lo
            top = np.nanmax(curves[0])
            curves = np.where(np.isfinite(curves), curves, top)
            self.terms[(a, b)] = (scan.shifts, curves, top)

    def value(self, a: int, b: int, rel: np.ndarray) -> np.ndarray:
        """``(R + 1, len(rel))``: pair ``(a, b)``'s relative cost at ``o_b - o_a = rel``
        (its largest outside its window)."""
        shifts, curves, top = self.terms[(a, b)]
        rel = np.asarray(rel, int)
        i = np.clip(rel - shifts[0], 0, len(shifts) - 1)
        inside = (rel >= shifts[0]) & (rel <= shifts[-1])
        return np.where(inside[None], curves[:, i], top)

    def camera(self, c: int, offsets: np.ndarray, candidates: np.ndarray,
               skip: set[int] = frozenset()) -> np.ndarray:
        """``(R + 1, K)``: the summed relative cost of camera ``c`` at each candidate
        offset, the others at ``offsets`` (the pairs with a camera of ``skip`` left out)."""
        total = 0.0
        for (a, b) in self.terms:
            if a in skip or b in skip:
                continue
            if a == c:
                total = total + self.value(a, b, offsets[b] - candidates)
            elif b == c:
                total = total + self.value(a, b, candidates - offsets[a])
        return np.broadcast_to(total, (self._rows(), len(candidates))) if np.isscalar(total) \
            else total

    def _rows(self) -> int:
        return next(iter(self.terms.values()))[1].shape[0] if self.terms else 1


def joint_offsets(curves: _PairCurves, start: np.ndarray, windows: list[np.ndarray],
                  fixed: set[int], skip: set[int] = frozenset()) -> np.ndarray:
    """Whole offsets (samples) minimising the sum of the pairs' relative costs by
    coordinate descent from ``start``; the cameras in ``fixed`` stay at ``start``, the
    others move within their ``windows``; the pairs with a camera of ``skip`` (one whose
    time the people do not fix) are left out."""
    o = np.asarray(start, int).copy()
    for _ in range(10):
        moved = False
        for c in range(len(o)):
            if c in fixed:
                continue
            cost = curves.camera(c, o, windows[c], skip)[0]
            best = int(windows[c][int(np.argmin(cost))])
            if best != o[c] and cost.min() < curves.camera(c, o, np.array([o[c]]), skip)[0, 0]:
                o[c], moved = best, True
        if not moved:
            break
    return o


#: Samples either side of the one a joint's trajectory is evaluated about (the local
#: quadratic's window is twice this plus one).
HALF_WINDOW = 3


def _local_quadratic(u) -> np.ndarray:
    """``(..., 2 HALF_WINDOW + 1)`` weights of the samples ``-HALF_WINDOW..HALF_WINDOW``
    giving the least-squares quadratic through them at ``u`` (a scalar or an array; a
    Savitzky-Golay filter at any point): smooth in ``u``, its noise varying a little with
    ``u`` (:func:`_noise_factor`)."""
    x = np.arange(-HALF_WINDOW, HALF_WINDOW + 1, dtype=float)
    X = np.vander(x, 3, increasing=True)
    u = np.asarray(u, float)
    return np.stack([np.ones_like(u), u, u * u], -1) @ np.linalg.solve(X.T @ X, X.T)


def _noise_factor(u):
    """The variance of the local quadratic at ``u`` over one sample's (``w . w``; the
    shape of ``u``)."""
    w = _local_quadratic(u)
    out = np.sum(w * w, -1)
    return float(out) if np.ndim(out) == 0 else out


def _windows(a: "_Track", b: "_Track", s: int
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The correspondences of camera ``a`` at whole shift ``s`` (samples) against the
    reference ``b`` at the rows both fall on, each seen at every sample of its local
    quadratic's window (:meth:`_Track.window`): ``(W, N, 2)`` the camera's, ``(W, N, 2)``
    the reference's, ``(N,)`` the rows, and ``(N,)`` the camera's and ``(N,)`` the
    reference's instants there less their windows' centres (own samples)."""
    Wa, pa = a.window(int(s))
    Wb, pb = b.window(0)
    ok = np.isfinite(Wa).all((0, -1)) & np.isfinite(Wb).all((0, -1))          # (L, J)
    rows = np.nonzero(ok)[0]
    return Wa[:, ok], Wb[:, ok], rows, pa[rows], pb[rows]


def _at(W: np.ndarray, u) -> np.ndarray:
    """``(N, ...)``: the local quadratic of the samples ``W`` (``(2 HALF_WINDOW + 1, N,
    ...)``) at ``u`` samples from their centre (a scalar, or ``(N,)``: one per column)."""
    w = _local_quadratic(u)
    if w.ndim == 1:
        return np.tensordot(w, W, axes=1)
    return np.einsum("nw,wn...->n...", w, W)


def _rotation(r: np.ndarray) -> np.ndarray:
    return cv2.Rodrigues(np.asarray(r, float).reshape(3, 1))[0]


def _fit_subframe(A3, pa, per, xb, E0_R, E0_t, dt0, f, huber_px, max_nfev: int = 200,
                  tol: float = 1e-8):
    """Least squares of ``(rotation, translation direction, dt)`` from a start (the
    camera's windows ``A3`` at their instants ``pa + dt / per``); returns ``(dt, R, t)``."""
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
        u = pa + p[5] / per
        d = sampson_distances(skew(t) @ R, _at(A3, u), xb) * f
        # the same noise for every dt: the local quadratic's varies a little with it
        d *= np.sqrt(2 * v0 / (v0 + _noise_factor(u)))
        return np.nan_to_num(d, nan=0.0, posinf=0.0, neginf=0.0)

    r = FRACTION_REACH
    x0 = np.array([0, 0, 0, 0, 0, float(np.clip(dt0, -0.99 * r, 0.99 * r))])
    lo = np.array([-np.inf] * 5 + [-r])
    hi = np.array([np.inf] * 5 + [r])
    res = least_squares(residuals, x0, bounds=(lo, hi), loss="huber", f_scale=huber_px,
                        x_scale="jac", diff_step=1e-4, max_nfev=max_nfev, ftol=tol,
                        xtol=tol)
    R, t = parts(res.x)
    return float(res.x[5]), R, t


def subframe_offset(camera: "_Track", reference: "_Track", shift: int, f: float,
                    *, seed: int = 0, runs: int = BOOTSTRAP_RUNS) -> tuple[float, float]:
    """The fraction of a sample ``dt`` (within :data:`FRACTION_REACH`) by which
    ``camera``'s sample ``t + shift + dt`` matches ``reference``'s ``t`` best, and its std.

    Each joint's trajectory is the least-squares quadratic through ``2 HALF_WINDOW + 1``
    of its own samples (a Savitzky-Golay filter evaluated between samples; the
    reference's the same filter at its sample; a camera at another frame rate on its own
    samples at its own instants), the camera's evaluated at ``t + shift + dt``; the relative
    pose (five parameters) and ``dt`` are fitted together by robust least squares, each
    residual scaled by the filter's noise at ``dt`` so that no ``dt`` is favoured for
    averaging the noise more. The std is the spread of that fit over a bootstrap of
    blocks of :data:`BOOTSTRAP_BLOCK` of the reference's samples (the detector's error
    and the motion are correlated over neighbouring frames).

    The residuals' scale is read from the data: ``s`` = 1.4826 times the median Sampson
    distance under the shift's essential matrix (the normal's MAD); correspondences
    farther than :data:`INLIER_SCALES` ``s`` are left out and the Huber loss turns linear
    at ``s``.

    Args:
        camera, reference: their normalised coordinates on their own samples, placed on
            one grid (:class:`_Track`).
        shift: the whole shift found (:func:`scan_shifts`).
        f: a focal length, pixels (the Sampson distance's scale).
        seed: seed of the RANSAC and of the bootstrap.
        runs: bootstrap resamples (0: no std, NaN).

    Returns:
        ``(dt, std)`` samples; ``(0, NaN)`` where too few correspondences.
    """
    A3, B3, rows, pa, pb = _windows(camera, reference, int(shift))
    if len(rows) < MIN_CORRESPONDENCES:
        return 0.0, float("nan")
    keep = _evenly(len(rows), SUBFRAME_CORRESPONDENCES)
    A3, xb, rows, pa = A3[:, keep], _at(B3[:, keep], pb[keep]), rows[keep], pa[keep]
    per = camera.per
    xa = _at(A3, pa)
    E, median = _essential(xa, xb, seed)
    if E is None or not median > 0:
        return 0.0, float("nan")
    scale = 1.4826 * median
    inl = np.abs(sampson_distances(E, xa, xb)) < INLIER_SCALES * scale
    if inl.sum() < MIN_CORRESPONDENCES:
        return 0.0, float("nan")
    A3, xb, rows, pa = A3[:, inl], xb[inl], rows[inl], pa[inl]
    _, R0, t0, _ = cv2.recoverPose(E, _at(A3, pa), xb, np.eye(3))
    t0 = t0.ravel()
    huber = scale * f
    # the start: the best of a coarse grid of dt under the shift's pose
    Ee = skew(t0 / np.linalg.norm(t0)) @ R0
    grid = np.linspace(-FRACTION_REACH, FRACTION_REACH, int(8 * FRACTION_REACH) + 1)
    costs = np.array([np.sum(_huber(sampson_distances(Ee, _at(A3, pa + g / per), xb) * f,
                                    huber)) for g in grid])
    dt, R, t = _fit_subframe(A3, pa, per, xb, R0, t0, _parabola_min(grid, costs), f, huber)
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
        # from the full fit: a resample moves it little (looser tolerances suffice)
        draws.append(_fit_subframe(A3[:, idx], pa[idx], per, xb[idx], R, t, dt, f, huber,
                                   max_nfev=60, tol=1e-6)[0])
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
    """Huber's loss of residuals ``r`` at ``k`` (``scipy.special.huber``); a missing
    residual (NaN, inf) costs what one at ``k`` does."""
    from scipy.special import huber

    return huber(k, np.nan_to_num(r, nan=k, posinf=k, neginf=k))


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


def rig_rates(fps: list[float | None]) -> tuple[list[float], int, float | None]:
    """The rig's clock from the cameras' frame rates (the first camera's the reference's):
    the reference's rate times the whole number ``unit`` nearest the fastest camera's
    over it (a 30 fps reference beside 60 fps cameras: a 60 fps clock, ``unit = 2``), and
    per camera the rig's frames per own frame (2 for a 30 fps camera on a 60 fps clock;
    1.2 for 25 fps on 30; 1.001 for 29.97 fps on 30). A ratio within 0.01 % of a whole
    number is that number (a rate written to fewer digits); a camera whose rate is unknown is taken at the reference's, and every camera
    at one rate where the reference's is unknown. Returns ``(rates, unit, rig_fps)``
    (``rig_fps`` ``None`` where unknown)."""
    ref = fps[0]
    if not ref or not np.isfinite(ref) or ref <= 0:
        return [1.0] * len(fps), 1, None
    known = [float(f) for f in fps if f and np.isfinite(f) and f > 0]
    unit = max(int(round(max(known) / float(ref))), 1)
    rig_fps = float(ref) * unit
    rates = []
    for f in fps:
        if not f or not np.isfinite(f) or f <= 0:
            rates.append(float(unit))
            continue
        q = rig_fps / float(f)
        rates.append(float(round(q)) if round(q) >= 1 and abs(q / round(q) - 1) < 1e-4 else q)
    return rates, unit, rig_fps


def frame_step(frame_ids: np.ndarray) -> int:
    """The frames between two samples of a camera (a video read every n-th frame): the
    median difference of its frame numbers, at least 1."""
    ids = np.asarray(frame_ids)
    return max(int(np.median(np.diff(ids))), 1) if len(ids) > 1 else 1


def find_clocks(people: list[tuple[np.ndarray, list[np.ndarray] | None]],
                frame_ids: list[np.ndarray], Ks: list[np.ndarray], given: list[int],
                joints, *, rates=None, unit: int = 1, drift: bool = False,
                search: bool = True, window: int = OFFSET_WINDOW, seed: int = 0,
                min_confidence: float = DEFAULT_MIN_CONFIDENCE,
                runs: int = BOOTSTRAP_RUNS) -> list[ClockEstimate]:
    """Every camera's time offset (see the module docstring); the first is the reference.

    Args:
        people: per camera ``(person, candidates)``: the ``(T_c, J, 3)`` person as the
            camera alone sees it (undistorted pixels; the reference camera's: its
            subject) and ``T_c`` arrays ``(P_t, J, 3)`` of candidates for the person per
            frame, or ``None``; where a frame holds several, the camera's longest tracks
            compete too (:func:`~mirrorgraph.rigs.failure.candidate_people`: the one that
            fits the reference best is taken).
        frame_ids: per camera ``(T_c,)`` its own frame numbers.
        Ks: per camera ``(3, 3)`` intrinsics (of the undistorted pixels).
        given: per camera the rig file's ``frame_offset`` in rig frames.
        joints: the joints compared (indices).
        rates: per camera the rig's frames per own frame (its nominal rate: the rig's
            frame rate over its own; default 1 for every camera). The scans run on the
            grid of rig frames every camera's whole samples fall on; a camera whose own
            frames fall between the grid's rows is placed at its instants
            (:class:`_Track`).
        unit: the rig's frames per reference camera frame (the notes' frames are the
            reference's).
        drift: estimate every camera's clock rate on the rig (:func:`_drift`): its
            fractions in stretches of its frames, a line through them; applied where
            it differs from 1 by more than :data:`FRACTION_Z` stds.
        search: search the offsets (else every camera keeps its given one). Frames more
            than :data:`~.tracking.TRACK_MAX_GAP` apart, or whose people jump from frame
            to frame in the reference camera (:func:`~.tracking.jumping`; snapshots: no
            motion continues from one to the next), are not searched either: every
            camera keeps its given offset, with a note.
        window: reference camera frames searched either way of a camera's given offset
            (relative to the reference's).
        seed: seed of every random choice.
        min_confidence: joints below this confidence are left out.
        runs: bootstrap resamples of the fractions' stds.

    Returns:
        per camera a :class:`ClockEstimate` on the rig's clock (``offset``: the camera's
        frame ``g`` is the rig's frame ``(rates[c] g - offset) / rate``).
    """
    joints = np.asarray(joints, int)
    N = len(people)
    rates = [1.0] * N if rates is None else [float(r) for r in rates]
    unit = int(unit)

    def said(frames: float) -> str:            # rig frames in the reference's, for notes
        return f"{frames / unit:g}"

    out: list[ClockEstimate | None] = [
        ClockEstimate(offset=float(given[0]), std=0.0, source="reference", given=given[0],
                      unit=unit)]
    if not search or N < 2:
        return out + [ClockEstimate(offset=float(g), std=float("nan"), source="given", given=g,
                                    unit=unit) for g in given[1:]]
    # the grid: every step-th rig frame, step the largest that every camera's samples
    # whose rig frames are whole fall on (a slower camera sees every n-th sample)
    whole = []
    for f, r in zip(frame_ids, rates):
        q = r * frame_step(f)
        if abs(q - round(q)) < 1e-6:
            whole.append(max(int(round(q)), 1))
    step = int(np.gcd.reduce(whole)) if whole else 1
    ref_people = people[0][1] if people[0][1] is not None else [
        p[None] for p in np.asarray(people[0][0], float)]
    if frame_step(frame_ids[0]) * rates[0] > TRACK_MAX_GAP * unit or \
            jumping(ref_people, joints, min_confidence, frame_ids[0]):
        why = (f"frames {frame_step(frame_ids[0])} apart"
               if frame_step(frame_ids[0]) * rates[0] > TRACK_MAX_GAP * unit else
               "the people jump from frame to frame")   # snapshots: shifts mean nothing
        return out + [ClockEstimate(offset=float(g), std=float("nan"), source="given", given=g,
                                    unit=unit,
                                    note=f"{why} (snapshots): not searched, kept as given "
                                         f"({said(g)})") for g in given[1:]]
    spans = [(r * np.min(f), r * np.max(f)) for f, r in zip(frame_ids, rates) if len(f)]
    base = int(np.floor(min(a for a, _ in spans)))
    length = int((max(b for _, b in spans) - base) // step + 1)
    reach = max(int(np.ceil(window * unit / step)), 1)
    rel = np.array([int(np.round((int(g) - int(given[0])) / step)) for g in given])
    focal = [0.5 * (K[0, 0] + K[1, 1]) for K in Ks]

    def track(points: np.ndarray, c: int) -> _Track:
        return _track(_normalised(_pixels(points, joints, min_confidence), Ks[c]),
                      frame_ids[c], rates[c], base, step, length)

    tracks: list[_Track | None] = [track(people[0][0], 0)] + [None] * (N - 1)
    seqs: list[np.ndarray | None] = [tracks[0].samples()] + [None] * (N - 1)
    out += [None] * (N - 1)
    windows = [np.arange(r - reach, r + reach + 1) for r in rel]
    coarse: dict[int, np.ndarray] = {}
    for c in range(1, N):
        person, cands = people[c]
        options = [np.asarray(person, float)]
        if cands is not None and any(len(p) > 1 for p in cands):
            options += candidate_people(cands, *options[0].shape[:2], joints, min_confidence)
        found = [track(s, c) for s in options]
        dense = [t.samples() for t in found]
        # a coarser scan (every other shift of the coarse one): the candidate that fits
        # best where several, and the rig's start (its first round scans every shift);
        # a rig of two cameras scans it in full
        rough = [coarse_cost(d, seqs[0], windows[c][::2], seed=seed) for d in dense]
        pick = int(np.argmin([r.min() for r in rough]))
        seqs[c], tracks[c] = dense[pick], found[pick]
        coarse[c] = np.full(len(windows[c]), np.inf)
        coarse[c][::2] = rough[pick]
        if N == 2 or not np.isfinite(coarse[c]).any():
            coarse[c] = coarse_cost(seqs[c], seqs[0], windows[c], seed=seed)
        if not np.isfinite(coarse[c]).any():
            n = int(max(max((len(_pairs(d, seqs[0], int(s))[0]) for s in windows[c]), default=0)
                        for d in dense))
            out[c] = ClockEstimate(offset=float(given[c]), std=float("nan"), source="given",
                                   given=given[c], unit=unit,
                                   note=f"too few joints seen with the reference camera at "
                                        f"any shift ({n} at most, {MIN_CORRESPONDENCES} "
                                        f"needed): kept as given ({said(given[c])})")
    live = [c for c in range(1, N) if out[c] is None]
    if not live:
        return out
    rng = np.random.default_rng(seed)
    blocks = int(np.ceil(length / BOOTSTRAP_BLOCK))
    weights = rng.multinomial(blocks, np.full(blocks, 1.0 / blocks),
                              size=BOOTSTRAP_DRAWS).astype(float)
    start = rel.copy()
    for c in live:
        start[c] = windows[c][int(np.argmin(coarse[c]))]
    found = _rig_offsets(seqs, tracks, live, rel, start, windows, focal, weights, seed) \
        if len(live) >= 2 else None
    if found is None:
        found = _pair_offsets(seqs, live, rel, windows, coarse, focal, weights, seed, reach)
    o, draws, scans, fractions, P = found
    drifts = _rig_drifts(tracks, P, o, fractions, focal, -base / step) \
        if drift and fractions else {}
    for c in live:
        f = 0.5 * (focal[0] + focal[c])
        if fractions is not None and c in fractions:
            # the rig's fractional offset: its draws' spread covers the whole offset too
            u, dt_std = fractions[c]
            # within a frame at the two-sided 1 % level
            near = np.isfinite(dt_std) and FRACTION_Z * dt_std <= 1
            dt, whole_std = u - o[c], 0.0
        elif fractions is not None:           # kept as given: the whole scan's draws
            near = np.mean(np.abs(draws[c] - o[c]) <= 1) >= ACCEPT_LEVEL
            dt, dt_std, whole_std = 0.0, float("nan"), float(np.std(draws[c])) * step
        else:
            # the fraction covers a sample either way: the whole offset's spread counts
            # only where the draws put it farther
            near = np.mean(np.abs(draws[c] - o[c]) <= 1) >= ACCEPT_LEVEL
            whole_std = 0.0 if near else float(np.std(draws[c])) * step
            # a fraction means something only about a whole offset the people fix, or
            # one they moved the camera to (where it may also settle the whole offset)
            dt, dt_std = (subframe_offset(tracks[c], tracks[0], int(o[c]), f, seed=seed,
                                          runs=runs)
                          if near or o[c] != rel[c] else (0.0, float("nan")))
        # a fraction moves a camera from its given offset where significant; one the rig's
        # search moved elsewhere sits at its estimate where the people fix it within half a
        # frame either way (at the two-sided 1 % level), else at the whole offset
        moved = fractions is not None and c in fractions and o[c] != rel[c] and \
            FRACTION_Z * dt_std <= 0.5
        frac = dt if np.isfinite(dt_std) and (moved or abs(dt) > FRACTION_Z * dt_std) else 0.0
        offset = (o[c] + frac) * step + given[0]
        # a fraction not applied: its distance from the whole offset counts into the std
        dt_err = np.hypot(dt_std, dt - frac) * step if np.isfinite(dt_std) else 0.0
        std = float(np.hypot(whole_std, dt_err))
        rate, rate_std, drift_note = 1.0, float("nan"), ""
        if drift:
            if c in drifts:
                b, b_std, u0, u0_std = drifts[c]
                rate_std = b_std
                if np.isfinite(b_std) and abs(b) > FRACTION_Z * b_std:
                    rate = 1.0 + b
                    offset, std = u0 * step + given[0], u0_std * step
                elif np.isfinite(b_std):
                    drift_note = (f"clock rate 1 {b:+.1e} +- {b_std:.1e}: not significant, "
                                  "kept at 1")
                else:
                    drift_note = "clock rate not determined by the people: kept at 1"
            else:
                drift_note = "clock rate not searched (no fraction on the rig): kept at 1"
        note = ""
        if o[c] != rel[c] or frac != 0 and round(offset) != given[c]:
            edge = " (the edge of the search window)" if abs(o[c] - rel[c]) == reach else ""
            note = (f"the people put it at {offset / unit:+.2f} +- {std / unit:.2f} frames{edge} "
                    f"against the rig file's frame_offset = {said(given[c])}")
        elif not near:
            note = (f"poorly fixed by the people (their best offsets spread by "
                    f"{std / unit:.1f} frames): kept as given ({said(given[c])})")
        if drift_note:
            note = f"{note}; {drift_note}" if note else drift_note
        out[c] = ClockEstimate(offset=float(offset), std=std, source="search",
                               given=int(given[c]), scan=scans.get(c), note=note, unit=unit,
                               rate=float(rate), rate_std=float(rate_std))
    return out


#: Stretches of a camera's frames whose fractions give its clock rate (a line through
#: their offsets against time).
DRIFT_STRETCHES = 4


#: Rounds of the clock rates over the cameras (each camera's against the others' lines).
DRIFT_ROUNDS = 3


def _drift(tracks: list, P: dict, at: dict, o: np.ndarray, c: int, f: float, r0: float
           ) -> tuple[float, float, float, float]:
    """Camera ``c``'s clock drift: its fractional offset (:func:`_rig_fraction`, the others
    at ``at``: per camera an offset or ``(length,)`` one a row) in each of
    :data:`DRIFT_STRETCHES` stretches of its rows (equal counts), a line through them
    weighted by their stds. Returns ``(b, b_std, u0, u0_std)``: the slope (the rate less
    1: samples of offset per sample of time) and the offset at grid row ``r0`` (the rig's
    frame 0; its std the line's there), the stds conditional on the others; NaN where
    fewer than three stretches are measured."""
    rows = np.sort(tracks[c].rows(o[c])[0])
    nan = (float("nan"),) * 4
    if len(rows) < DRIFT_STRETCHES * MIN_CORRESPONDENCES // 10:
        return nan
    cuts = np.quantile(rows, np.linspace(0, 1, DRIFT_STRETCHES + 1)).round().astype(int)
    cuts[-1] = tracks[c].length
    got = []
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        u, sd, r = _rig_fraction(tracks, P, at, o, c, f, stretch=(int(lo), int(hi)))
        if np.isfinite(u) and np.isfinite(sd) and sd > 0:
            got.append((r, u, sd))
    if len(got) < 3:
        return nan
    r, u, sd = map(np.array, zip(*got))
    w = 1 / sd ** 2
    rm = np.sum(w * r) / np.sum(w)
    sxx = np.sum(w * (r - rm) ** 2)
    b = float(np.sum(w * (r - rm) * (u - np.sum(w * u) / np.sum(w))) / sxx)
    a = float(np.sum(w * u) / np.sum(w))
    u0 = a + b * (r0 - rm)
    return b, float(1 / np.sqrt(sxx)), float(u0), float(np.sqrt(1 / np.sum(w) +
                                                                  (r0 - rm) ** 2 / sxx))


def _rig_drifts(tracks: list, P: dict, o: np.ndarray, fractions: dict, focal: list,
                r0: float) -> dict[int, tuple[float, float, float, float]]:
    """Every measured camera's clock drift (:func:`_drift`) against the others placed on
    their latest lines (offset at grid row ``r0``, the rig's frame 0, and slope; the
    others' drifts otherwise pass into each camera's through the triangulation), for
    :data:`DRIFT_ROUNDS` rounds; the stds propagated through the cameras' coupling as the
    fractions' (:func:`_rig_fractions`). Returns per camera ``(b, b_std, u0, u0_std)``
    (samples)."""
    grid = np.arange(tracks[0].length, dtype=float)
    lines = {k: (float(o[k]), 0.0) for k in P}
    lines.update({k: (float(v[0]), 0.0) for k, v in fractions.items()})
    out: dict[int, tuple[float, float, float, float]] = {}
    for _ in range(DRIFT_ROUNDS):
        for c in fractions:
            at = {k: u + b * (grid - r0) for k, (u, b) in lines.items()}
            got = _drift(tracks, P, at, o, c, focal[c], r0)
            if np.isfinite(got[1]):
                out[c] = got
                lines[c] = (got[2], got[0])
    if not out:
        return {}
    keys = list(out)
    m = len(P)
    A = np.full((len(keys), len(keys)), 1.0 / (m - 1))
    np.fill_diagonal(A, 0.0)
    G2 = np.linalg.inv(np.eye(len(keys)) - A) ** 2
    b_std = np.sqrt(G2 @ np.array([out[c][1] for c in keys]) ** 2)
    u_std = np.sqrt(G2 @ np.array([out[c][3] for c in keys]) ** 2)
    return {c: (out[c][0], float(bs), out[c][2], float(us))
            for c, bs, us in zip(keys, b_std, u_std)}


def _draws(scan: ShiftScan, weights: np.ndarray) -> np.ndarray:
    """``(R,)`` the best shift of each bootstrap draw of a scan (``weights``: ``(R, B)``
    block weights)."""
    boot = _bootstrap_costs(scan, weights)
    boot = np.where(np.isfinite(boot), boot, np.inf)
    return scan.shifts[np.argmin(boot, axis=1)]


def _rig_total(seqs: list, P: dict, o: np.ndarray, focal: list) -> float:
    """The summed median reprojection error (pixels) of every camera of ``P`` at its
    offset ``o`` against the others' triangulation (:func:`_rig_scan`)."""
    total = 0.0
    for c in P:
        cost = _rig_scan(seqs, P, o, c, [int(o[c])], focal[c])[0].cost[0]
        total += float(cost) if np.isfinite(cost) else np.inf
    return total


def _rig_fractions(tracks: list, P: dict, o: np.ndarray, measured: list[int], focal: list
                   ) -> dict[int, tuple[float, float]]:
    """The fractional offsets (samples) of the cameras ``measured`` and their stds, on the
    reference camera's clock: every measured camera's fraction against the others at
    theirs (:func:`_rig_fraction`; the reference at its whole offset), in turn, for
    :data:`FRACTION_ROUNDS` rounds or until none moves :data:`FRACTION_TOL`; the stds
    propagated through that coupling (below)."""
    at = {k: float(o[k]) for k in P}
    stds: dict[int, float] = {}
    for _ in range(FRACTION_ROUNDS):
        change = 0.0
        for c in measured:
            u, std, _ = _rig_fraction(tracks, P, at, o, c, focal[c])
            if np.isfinite(u) and abs(u - o[c]) <= FRACTION_REACH:
                change = max(change, abs(u - at[c]))
                at[c], stds[c] = u, std
        if change < FRACTION_TOL:
            break
    got = [c for c in measured if c in stds]
    if not got:
        return {}
    # each camera's std is conditional on the others' offsets; each offset follows the
    # mean of the others' (the triangulation's time, weighted alike over the rig's other
    # cameras, the reference fixed): u = (I - A)^-1 (own errors), whose covariance
    # propagates the conditional stds (their common part the reference alone fixes)
    m = len(P)
    A = np.full((len(got), len(got)), 1.0 / (m - 1))
    np.fill_diagonal(A, 0.0)
    G = np.linalg.inv(np.eye(len(got)) - A)
    std = np.sqrt((G ** 2) @ np.array([stds[c] for c in got]) ** 2)
    return {c: (at[c], float(s)) for c, s in zip(got, std)}


def _rig_offsets(seqs: list, tracks: list, live: list[int], rel: np.ndarray,
                 start: np.ndarray, windows: list, focal: list, weights: np.ndarray, seed: int):
    """The offsets (samples) of the cameras ``live`` against the rig (see the module
    docstring, steps 2 and 3): the whole ones searched (:func:`_rig_search`), then the
    fractions (:func:`_rig_fractions`), each move from the rig file's ``rel`` tested on
    the camera's whole-shift scan with the others at their fractions. Returns
    ``(offsets, draws, scans, fractions, poses)``: the whole offsets, the bootstrap draws' best
    whole offsets and the scans per camera, and per camera ``(offset, std)``, its
    fractional offset (absent for a camera kept as given), and the cameras' poses;
    ``None`` where the rig's poses cannot be found."""
    o = np.where(np.isin(np.arange(len(rel)), live), start, rel)
    kept: set[int] = set()
    last: dict[int, ShiftScan] = {}
    while True:
        moving = [c for c in live if c not in kept]
        # a camera kept for want of evidence says nothing of the others' offsets, where
        # two others remain to triangulate from
        members = [0] + (moving if len(moving) >= 2 else list(live))
        # from the pairs' coarse offsets, and from the rig file's where they fit the rig
        # better as they stand than the first search's result does: a coordinate search may
        # settle where two groups of cameras agree among themselves (a periodic motion's
        # other minimum); the one the rig fits better
        found = None
        trial = _rig_search(seqs, members, moving, o, windows, focal, seed)
        if trial is not None:
            found = (_rig_total(seqs, trial[1], trial[0], focal),) + trial
        if not kept and (found is None or np.any(found[1] != rel)):
            # the rig file's offsets judged with the result's poses (each camera's refitted)
            if found is None or _rig_total(seqs, found[2], rel, focal) < found[0]:
                trial = _rig_search(seqs, members, moving, rel, windows, focal, seed)
                if trial is not None:
                    total = _rig_total(seqs, trial[1], trial[0], focal)
                    if found is None or total < found[0]:
                        found = (total,) + trial
        if found is None:
            return None
        _, o, P = found
        fractions = _rig_fractions(tracks, P, o, moving, focal)
        at = {k: float(o[k]) for k in P}
        for c, (u, _) in fractions.items():
            at[c] = u
            o[c] = int(np.clip(np.round(u), windows[c][0], windows[c][-1]))
        fails = set()
        for c in moving:
            if o[c] == rel[c] and c in fractions:
                continue                  # nothing to test; the fraction's std is its own
            # the others at their fractional offsets, the camera at whole shifts: those
            # about the offset and the given one, every third farther (the draws' spread)
            w = windows[c]
            shifts = w[(np.abs(w - o[c]) <= 3) | (w == rel[c]) | ((w - w[0]) % 3 == 0)]
            scan = _rig_scan(seqs, P, {**at, c: 0.0}, c, shifts, focal[c], tracks)[0]
            last[c] = scan
            if o[c] == rel[c]:
                continue
            boot = _bootstrap_costs(scan, weights)
            boot = np.where(np.isfinite(boot), boot, np.inf)
            here = boot[:, int(np.flatnonzero(scan.shifts == o[c])[0])]
            was = boot[:, int(np.flatnonzero(scan.shifts == rel[c])[0])]
            draws = scan.shifts[np.argmin(boot, axis=1)]
            # significantly better than the given offset (the whole shifts' draws, or
            # the fraction's offset beyond FRACTION_Z of its stds from it), and an
            # offset the draws agree on (their best shifts' RMS deviation within
            # MOVE_SPREAD), not one a draw may put anywhere in the window
            u, std = fractions.get(c, (np.nan, np.nan))
            better = np.mean(here < was) >= ACCEPT_LEVEL or \
                abs(u - rel[c]) > FRACTION_Z * std
            if not better or np.sqrt(np.mean((draws - o[c]) ** 2.0)) > MOVE_SPREAD:
                fails.add(c)
        if not fails:
            break
        kept |= fails
        o[list(fails)] = rel[list(fails)]
        if kept >= set(live):
            fractions = {}
            break
    fractions = {c: fractions[c] for c in fractions if c not in kept}
    return o, {c: _draws(last[c], weights) for c in last}, last, fractions, P


def _pair_offsets(seqs: list, live: list[int], rel: np.ndarray, windows: list,
                  coarse: dict, focal: list, weights: np.ndarray, seed: int, reach: int):
    """The whole offsets (samples) of the cameras ``live`` from the pairs' epipolar
    costs (:func:`scan_shifts`, :func:`joint_offsets`; a rig of two cameras, or one
    whose poses the rig's search cannot find), each move from the rig file's ``rel``
    tested: ``(offsets, draws, scans, None, None)`` as :func:`_rig_offsets`."""
    N = len(rel)
    scans: dict[tuple[int, int], ShiftScan] = {}
    start = rel.copy()
    for c in live:
        f = 0.5 * (focal[0] + focal[c])
        scans[(0, c)] = scan_shifts(seqs[c], seqs[0], f, windows[c], seed=seed,
                                    coarse=coarse[c])
        start[c] = scans[(0, c)].best
    for i, a in enumerate(live):                 # the pairs without the reference
        for b in live[i + 1:]:
            centre = int(start[b] - start[a])
            f = 0.5 * (focal[a] + focal[b])
            scan = scan_shifts(seqs[b], seqs[a], f, range(centre - reach, centre + reach + 1),
                               seed=seed)
            if np.isfinite(scan.cost).any():
                scans[(a, b)] = scan
    curves = _PairCurves(scans, weights)
    fixed = {0} | {c for c in range(1, N) if c not in live}
    kept: set[int] = set()
    while True:
        # a camera kept for want of evidence says nothing of the others' offsets
        o = joint_offsets(curves, np.where([c in fixed | kept for c in range(N)], rel, start),
                          windows, fixed | kept, kept)
        alt = joint_offsets(curves, rel, windows, fixed | kept, kept)
        if _total(curves, alt, kept) < _total(curves, o, kept):
            o = alt
        fails = set()
        for c in live:
            if c in kept or o[c] == rel[c]:
                continue
            others = [0] + [k for k in live if k != c and k not in kept]
            if _preferred(c, o, rel[c], others, seqs, focal, weights, seed) < ACCEPT_LEVEL:
                fails.add(c)
                continue
            # a move the draws do not agree on (their best shifts' RMS deviation from it
            # over MOVE_SPREAD frames) is no offset the people fix: the given one stays
            draws = windows[c][np.argmin(curves.camera(c, o, windows[c], kept - {c})[1:],
                                         axis=1)]
            if np.sqrt(np.mean((draws - o[c]) ** 2.0)) > MOVE_SPREAD:
                fails.add(c)
        if not fails:
            break
        kept |= fails
    draws = {c: windows[c][np.argmin(curves.camera(c, o, windows[c], kept - {c})[1:], axis=1)]
             for c in live}
    return o, draws, {c: scans[(0, c)] for c in live}, None, None


def _refit_distances(camera: np.ndarray, reference: np.ndarray, s: int, f: float, seed: int
                     ) -> tuple[np.ndarray, np.ndarray] | None:
    """``camera``'s sample ``t + s`` against ``reference``'s ``t`` judged by essential
    matrices fitted at that shift itself, cross-fitted (each parity of blocks by the
    other's): ``(n,)`` Sampson distances (pixels) and their samples ``t``."""
    xa, xb, rows = _pairs(camera, reference, int(s))
    keep = _evenly(len(xa), MAX_CORRESPONDENCES)
    xa, xb, rows = xa[keep], xb[keep], rows[keep]
    odd = (rows // BOOTSTRAP_BLOCK) % 2 == 1
    Es = []
    for h in (False, True):
        sel = np.flatnonzero(odd == h)
        if len(sel) < MIN_CORRESPONDENCES:
            return None
        Es.append(_essential(xa[sel], xb[sel], seed)[0])
    if Es[0] is None or Es[1] is None:
        return None
    d = np.where(odd, sampson_distances(Es[0], xa, xb), sampson_distances(Es[1], xa, xb))
    return np.nan_to_num(np.abs(d), nan=np.inf) * f, rows


def _preferred(c: int, o: np.ndarray, given: int, others: list[int], seqs, focal,
               weights: np.ndarray, seed: int) -> float:
    """The share of the bootstrap draws (``weights``, ``(R, B)``) in which camera ``c``
    at ``o[c]`` fits the cameras ``others`` (at ``o``) better than at ``given``: the
    medians of every pair, each relative to its value at ``o[c]`` on the full data,
    summed; every shift judged by essential matrices fitted at it (cross-fitted), so
    neither is favoured for the matrix."""
    totals = np.zeros((2, len(weights)))
    for k in others:
        a, b = (k, c) if k < c else (c, k)
        sign = 1 if b == c else -1
        f = 0.5 * (focal[a] + focal[b])
        found = []
        for oc in (o[c], given):
            rel = sign * (oc - o[k])
            found.append(_refit_distances(seqs[b], seqs[a], rel, f, seed))
        if found[0] is None or found[1] is None:
            continue
        scale = float(np.median(found[0][0]))
        for i, (d, rows) in enumerate(found):
            totals[i] += _weighted_medians(d, rows // BOOTSTRAP_BLOCK, weights) / scale
    return float(np.mean(totals[0] < totals[1]))


def _total(curves: _PairCurves, o: np.ndarray, skip: set[int]) -> float:
    """The summed relative cost of every pair at offsets ``o`` (full data; the pairs
    with a camera of ``skip`` left out)."""
    return float(sum(curves.value(a, b, np.array([o[b] - o[a]]))[0, 0]
                     for (a, b) in curves.terms if a not in skip and b not in skip))


# --- the rig's witness: each camera against the triangulation of all the others -------

#: Rounds of the joint search over the cameras (each camera scanned against the others at
#: their current offsets; it stops earlier where no camera moves).
RIG_ROUNDS = 4
#: Shifts either way of a camera's current offset scanned after the first round.
RIG_REACH = 2
#: Least-squares rounds of a camera's pose against the others' points (each refits on the
#: correspondences within :data:`INLIER_SCALES` robust stds of the last).
RESECT_ROUNDS = 3


def _shifted(a: np.ndarray, s: int) -> np.ndarray:
    """``a`` (``(T, ...)``) with its row ``t + s`` at row ``t`` (NaN outside)."""
    out = np.full_like(a, np.nan)
    T = len(a)
    if abs(s) >= T:
        return out
    if s >= 0:
        out[:T - s] = a[s:]
    else:
        out[-s:] = a[:T + s]
    return out


def _errors(X: np.ndarray, x: np.ndarray, rvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    """``(n,)`` reprojection errors (normalised) of points ``X`` (``(n, 3)``) seen at
    ``x`` (``(n, 2)``, normalised) by the pose ``(rvec, tvec)`` (world to camera)."""
    Xc = X @ _rotation(rvec).T + np.ravel(tvec)
    z = Xc[:, 2:]
    e = np.linalg.norm(Xc[:, :2] / np.where(z > 0, z, np.nan) - x, axis=1)
    return np.nan_to_num(e, nan=np.inf)


#: OpenCV's Levenberg-Marquardt of a pose from a near start: ten iterations at most.
_LM_STOP = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 10, 1e-10)
#: ... and to convergence, where the cost must be smooth in the observations.
_LM_CONVERGE = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 50, 1e-14)


def _resect(X: np.ndarray, x: np.ndarray, rvec: np.ndarray, tvec: np.ndarray,
            inliers: np.ndarray | None = None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """A camera's pose from points ``X`` (``(n, 3)``) it sees at ``x`` (``(n, 2)``,
    normalised), from a start: Levenberg-Marquardt (OpenCV's) on the correspondences
    within :data:`INLIER_SCALES` robust stds (1.4826 times the median error) of the last
    pose, :data:`RESECT_ROUNDS` times; on the ``(n,)`` ``inliers`` alone, once, where
    given (the pose then a smooth function of the observations). ``(rvec, tvec,
    errors)``, the ``(n,)`` errors normalised; ``None`` where fewer than
    :data:`MIN_CORRESPONDENCES`."""
    if len(X) < MIN_CORRESPONDENCES:
        return None
    rvec, tvec = np.asarray(rvec, float).reshape(3, 1), np.asarray(tvec, float).reshape(3, 1)
    if inliers is not None:
        rvec, tvec = cv2.solvePnPRefineLM(X[inliers], x[inliers], np.eye(3), None,
                                          rvec.copy(), tvec.copy(), _LM_CONVERGE)
        return rvec, tvec, _errors(X, x, rvec, tvec)
    for _ in range(RESECT_ROUNDS):
        e = _errors(X, x, rvec, tvec)
        keep = e < INLIER_SCALES * 1.4826 * np.median(e)
        if keep.sum() < MIN_CORRESPONDENCES:
            break
        rvec, tvec = cv2.solvePnPRefineLM(X[keep], x[keep], np.eye(3), None, rvec.copy(),
                                          tvec.copy(), _LM_STOP)
    return rvec, tvec, _errors(X, x, rvec, tvec)


def _seen(X: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The joints both triangulated (``X``, ``(T, J, 3)``) and seen (``x``, ``(T, J,
    2)``): ``(n, 3)``, ``(n, 2)`` and their ``(n,)`` rows."""
    ok = np.isfinite(X).all(-1) & np.isfinite(x).all(-1)
    rows = np.nonzero(ok)[0]
    return X[ok], x[ok], rows


def _triangulated(P: dict, seqs: dict, min_views: int = 2) -> np.ndarray:
    """``(T, J, 3)`` the joints triangulated from the cameras ``P`` (``(3, 4)`` world to
    normalised camera) seeing them at ``seqs`` (``(T, J, 2)``), NaN where fewer than two
    see one."""
    from ..geometry import triangulate

    keys = list(P)
    try:
        return triangulate([P[k] for k in keys], [seqs[k] for k in keys],
                           min_views=min_views)[0]
    except np.linalg.LinAlgError:       # degenerate poses (a camera seeing someone else)
        return np.full(seqs[keys[0]].shape[:-1] + (3,), np.nan)


def _pose(rvec: np.ndarray, tvec: np.ndarray) -> np.ndarray:
    return np.hstack([_rotation(rvec), np.reshape(tvec, (3, 1))])


def _rig_poses(aligned: dict, seed: int) -> dict | None:
    """Every camera's ``(3, 4)`` pose (world to normalised camera; the first key's the
    identity) from its joints on the rig's clock (``aligned``: camera to ``(T, J, 2)``):
    the essential matrix of the first camera and one other, its points triangulated, the
    others resected against them (EPnP in RANSAC, then :func:`_resect`); of every choice
    of that other camera the one whose cameras reproject best; then twice the points
    triangulated from every camera and each camera resected against them."""
    keys = list(aligned)
    ref = keys[0]
    best, best_score = None, np.inf
    for k in keys[1:]:
        xk, x0, _ = _pairs(aligned[k], aligned[ref], 0)
        if len(x0) < MIN_CORRESPONDENCES:
            continue
        keep = _evenly(len(x0), MAX_CORRESPONDENCES)
        E, med = _essential(x0[keep], xk[keep], seed)
        if E is None:
            continue
        _, R, t, _ = cv2.recoverPose(E, x0[keep], xk[keep], np.eye(3))
        P = {ref: np.hstack([np.eye(3), np.zeros((3, 1))]), k: np.hstack([R, t])}
        X = _triangulated(P, {ref: aligned[ref], k: aligned[k]})
        errs = []
        for c in keys[1:]:
            if c == k:
                continue
            Xs, xs, _ = _seen(X, aligned[c])
            if len(Xs) < MIN_CORRESPONDENCES:
                break
            cv2.setRNGSeed(int(seed))
            ok, rvec, tvec, _ = cv2.solvePnPRansac(
                Xs, xs, np.eye(3), None, reprojectionError=max(8.0 * med, 1e-4),
                iterationsCount=200, flags=cv2.SOLVEPNP_EPNP)
            fit = _resect(Xs, xs, rvec, tvec) if ok else None
            if fit is None:
                break
            P[c] = _pose(fit[0], fit[1])
            errs.append(float(np.median(fit[2])))
        if len(P) < len(keys):
            continue
        score = float(np.mean(errs)) if errs else float(med)
        if score < best_score:
            best, best_score = P, score
    if best is None:
        return None
    for _ in range(2):
        X = _triangulated(best, aligned)
        for c in keys[1:]:
            Xs, xs, _ = _seen(X, aligned[c])
            fit = _resect(Xs, xs, cv2.Rodrigues(best[c][:, :3])[0], best[c][:, 3])
            if fit is not None:
                best[c] = _pose(fit[0], fit[1])
    return best


def _placed(seqs: list, tracks: list | None, k: int, offset: float) -> np.ndarray:
    """``(T, J, 2)``: camera ``k``'s samples on the rig's rows at its ``offset`` (samples):
    shifted (:func:`_shifted`) where whole, its local quadratics there
    (:meth:`_Track.smoothed`) where fractional."""
    whole = int(np.round(offset))
    if offset == whole or tracks is None:
        return _shifted(seqs[k], whole)
    return tracks[k].smoothed(whole, offset)


def _rig_scan(seqs: list, P: dict, o, c: int, shifts, f: float, tracks: list | None = None
              ) -> tuple[ShiftScan, dict]:
    """Camera ``c``'s reprojection error per whole shift against the joints triangulated
    from the other cameras of ``P`` at their offsets ``o`` (samples, whole or fractional:
    :func:`_placed`, from ``tracks``): at each shift its
    pose resected anew from its current one (:func:`_resect`; at most
    :data:`MAX_CORRESPONDENCES` taken evenly), so that no shift is favoured for the pose. Returns the scan (costs: median errors, pixels at focal
    length ``f``) and its poses per shift."""
    others = {k: P[k] for k in P if k != c}
    X = _triangulated(others, {k: _placed(seqs, tracks, k, o[k]) for k in others})
    shifts = np.asarray(list(shifts), int)
    S = len(shifts)
    scan = ShiftScan(shifts=shifts, cost=np.full(S, np.nan), correspondences=np.zeros(S, int),
                     distances=[None] * S, rows=[None] * S)
    poses = {}
    r0, t0 = cv2.Rodrigues(P[c][:, :3])[0], P[c][:, 3]
    for i, s in enumerate(shifts):
        Xs, xs, rows = _seen(X, _shifted(seqs[c], int(s)))
        scan.correspondences[i] = len(rows)
        take = _evenly(len(rows), MAX_CORRESPONDENCES)
        Xs, xs, rows = Xs[take], xs[take], rows[take]
        fit = _resect(Xs, xs, r0, t0)
        if fit is None:
            continue
        d = fit[2] * f
        scan.cost[i] = float(np.median(d))
        scan.distances[i], scan.rows[i] = d, rows
        poses[int(s)] = _pose(fit[0], fit[1])
    return scan, poses


def _rig_search(seqs: list, members: list[int], searched: list[int], start: np.ndarray,
                windows: list, focal: list, seed: int) -> tuple[np.ndarray, dict] | None:
    """Whole offsets (samples) of the cameras ``searched`` against the rig of the cameras
    ``members`` (the first the reference; the others not searched stay at ``start``):
    from ``start``, every searched camera's
    reprojection error scanned against the others' triangulation at their current
    offsets (:func:`_rig_scan`), its whole window first, then :data:`RIG_REACH` either
    way, for :data:`RIG_ROUNDS` rounds or until none moves. Returns the offsets and the
    cameras' poses at them; ``None`` where the rig's poses cannot be found."""
    o = np.asarray(start, int).copy()
    P = _rig_poses({k: _shifted(seqs[k], int(o[k])) for k in members}, seed)
    if P is None:
        return None
    live = [c for c in members[1:] if c in searched]
    for r in range(RIG_ROUNDS):
        moved = False
        for c in live:
            w = windows[c]
            shifts = w if r == 0 else w[np.abs(w - o[c]) <= RIG_REACH]
            scan, poses = _rig_scan(seqs, P, o, c, shifts, focal[c])
            best = scan.best
            if best is None:
                continue
            moved |= best != o[c]
            o[c], P[c] = best, poses[best]
        if not moved:
            break
    return o, P


#: The rig's fractions are scanned on this grid of samples about the whole offset.
FRACTION_GRID = np.linspace(-1.5, 1.5, 13)
#: The finer grid of the rig's fractions: seven points this far apart (samples) about the
#: coarse grid's minimum.
FRACTION_FINE = 1.0 / 16
#: Correspondences of a camera's fraction on the rig at most (taken evenly).
FRACTION_CORRESPONDENCES = 2000
#: Rounds of the rig's fractions over the cameras at most (each camera against the others
#: at their latest fractions).
FRACTION_ROUNDS = 6
#: The rounds stop where no camera's fraction moved more than this (samples).
FRACTION_TOL = 0.02


def _rig_fraction(tracks: list, P: dict, at: dict, centre: np.ndarray, c: int, f: float,
                  stretch: tuple[int, int] | None = None) -> tuple[float, float, float]:
    """Camera ``c``'s fractional offset against the joints triangulated from the other
    cameras of ``P`` at their offsets ``at`` (samples, fractional), and its std. Every
    camera's trajectories are the local quadratics of its own samples about its whole
    offset ``centre`` (:meth:`_Track.smoothed`; one window for every fraction, so that
    the cost is continuous in the fractions; a camera at another frame rate than the
    grid's on its own samples, at its own instants).

    At each point ``u`` of :data:`FRACTION_GRID` about its whole offset, its
    trajectories are evaluated at ``t + u`` (its residuals scaled to one noise at every
    ``u``) and its pose resected on one set of inliers (:func:`_resect`); the cost
    ``C(u)`` is the summed Huber loss of its reprojection errors, turning linear at the
    robust std of the best grid point, the correspondences farther than
    :data:`INLIER_SCALES` of it at every point left out. On a finer grid
    (:data:`FRACTION_FINE` apart) about the coarse minimum, ``C`` is fitted by a
    quadratic: its minimum is the offset, and its std the M-estimator's sandwich, the
    root of the summed squares of the gradients of blocks of :data:`BOOTSTRAP_BLOCK`
    samples at the minimum over the curvature (the cost profiled over the pose; the
    detector's errors and the motion are correlated over neighbouring frames): a flat
    cost gives a large std.

    Args:
        stretch: the grid's rows ``[start, stop)`` measured (default all).

    Returns:
        the offset and its std (samples), and the mean row measured; NaN where too few
        correspondences.
    """
    others = {k: P[k] for k in P if k != c}
    placed = {k: tracks[k].smoothed(int(centre[k]), at[k]) for k in others}
    X = _triangulated(others, placed, min_views=len(others))
    base = int(centre[c])
    r0, t0 = cv2.Rodrigues(P[c][:, :3])[0], P[c][:, 3]
    v0 = _noise_factor(0.0)
    nan = (float("nan"), float("nan"), float("nan"))
    # the camera's own samples about each row that every u weighs (the local quadratic's)
    window, pos = tracks[c].window(base)
    per = tracks[c].per
    seen = np.isfinite(X).all(-1) & np.isfinite(window).all((0, -1))
    if stretch is not None:
        seen[:stretch[0]] = False
        seen[stretch[1]:] = False
    Xs, W, rows = X[seen], window[:, seen], np.nonzero(seen)[0]
    if len(rows) < MIN_CORRESPONDENCES:
        return nan
    if len(rows) > FRACTION_CORRESPONDENCES:
        take = _evenly(len(rows), FRACTION_CORRESPONDENCES)
        Xs, W, rows = Xs[take], W[:, take], rows[take]
    p0 = pos[rows]                       # each row's instant on the camera's own samples

    def scale(u):
        return f * np.sqrt(2 * v0 / (v0 + _noise_factor(p0 + u / per)))

    def moved(u):                        # the camera at offset base + u (samples)
        return _at(W, p0 + u / per)

    # one set of inliers (of the pose at the offset rounded) for every u: the cost a
    # smooth function of u
    first = _resect(Xs, moved(0.0), r0, t0)
    if first is None:
        return nan
    r0, t0, e0 = first
    inliers = e0 < INLIER_SCALES * 1.4826 * np.median(e0)
    if inliers.sum() < MIN_CORRESPONDENCES:
        return nan

    def errors(grid):
        out = []
        for u in grid:
            fit = _resect(Xs, moved(u), r0, t0, inliers)
            out.append(None if fit is None else fit[2] * scale(u))
        ok = np.array([e is not None for e in out], bool)
        return np.asarray(grid)[ok], [e for e in out if e is not None]

    def fine(u0):
        g, Ef = errors([u for u in u0 + FRACTION_FINE * np.arange(-3, 4)
                        if abs(u) <= FRACTION_GRID[-1]])
        return g, (np.stack(Ef) if len(g) >= 3 else None)

    blocks = rows // BOOTSTRAP_BLOCK

    def per_block(E, k_px, keep):
        nb = int(blocks.max()) + 1
        return np.stack([np.bincount(blocks, weights=_huber(e, k_px) * keep, minlength=nb)
                         for e in E], axis=1)                                  # (B, G)

    grid, E = errors(FRACTION_GRID)
    if len(grid) < 3:
        return nan
    E = np.stack(E)                                                           # (G, n)
    # the scale and the inliers from every grid point alike: none favoured
    k_px = 1.4826 * float(np.min(np.median(E, axis=1)))
    keep = E.min(0) < INLIER_SCALES * k_px
    fine_grid, Ef = fine(_parabola_min(grid, np.sum(_huber(E, k_px) * keep, axis=1)))
    if Ef is None:
        return nan
    # the cost C(u) a quadratic over the fine grid: its minimum; the M-estimator's
    # (sandwich) std, the blocks' gradients at the minimum over the curvature, of that
    # quadratic and of one over the whole coarse grid (a cost flat or with another
    # minimum within it is no offset fixed to the fine grid's precision), the larger
    x0 = fine_grid.mean()
    u, std = _sandwich(fine_grid - x0, per_block(Ef, k_px, keep))
    if not np.isfinite(u):
        return float(base + _parabola_min(fine_grid, np.sum(_huber(Ef, k_px) * keep, axis=1))), \
            float("inf"), float(np.mean(rows))
    u = float(np.clip(u, fine_grid[0] - x0 - FRACTION_FINE, fine_grid[-1] - x0 + FRACTION_FINE))
    wide = _sandwich(grid, per_block(E, k_px, keep), at=u + x0)[1]
    return float(base + x0 + u), float(max(std, wide)), float(np.mean(rows))


def _sandwich(x: np.ndarray, Cb: np.ndarray, at: float | None = None) -> tuple[float, float]:
    """A cost's minimum and its M-estimator std from its blocks' values ``Cb`` (``(B,
    G)``) on the grid ``x`` (``(G,)``): each block's cost a least-squares quadratic, the
    minimum of their sum, and the root of the blocks' summed squared gradients there
    over the sum's curvature (at ``at`` instead of the minimum, where given). ``(NaN,
    inf)`` where the sum does not curve up."""
    coef = np.linalg.lstsq(np.vander(x, 3), Cb.T, rcond=None)[0]              # (3, B)
    a, b = coef[0].sum(), coef[1].sum()
    if not a > 0:
        return float("nan"), float("inf")
    xm = -b / (2 * a) if at is None else float(at)
    g = 2 * coef[0] * xm + coef[1]                                           # (B,)
    return float(xm), float(np.sqrt(np.sum(g ** 2)) / (2 * a))



def rig_instants(frame_ids: np.ndarray, rate: float, clock: ClockEstimate) -> np.ndarray:
    """``(T_c,)`` the rig frames (fractional) a camera's own frames ``frame_ids`` show:
    ``(rate g - offset) / clock_rate`` (``rate``: the rig's frames per own frame)."""
    return (float(rate) * np.asarray(frame_ids, float) - clock.offset) / clock.rate


def on_rig_clock(a: np.ndarray, frame_ids: np.ndarray, rate: float, clock: ClockEstimate
                 ) -> tuple[np.ndarray, np.ndarray]:
    """A camera's ``(T_c, J, C)`` keypoints on its own frames ``frame_ids`` placed on the
    rig's clock (``rate``: the rig's frames per own frame; ``clock``: its offset and
    clock rate): each own frame at the rig frame nearest the instant it shows
    (:func:`rig_instants`; of several on one rig frame, the nearest), the keypoints at
    that rig frame's instant interpolated linearly between the camera's two frames
    around it (the confidence, last channel, the smaller of theirs; NaN coordinates and
    confidence 0 where either lacks the joint; its own frame where the instant falls on
    it). Returns ``(m,)`` rig frames (increasing) and ``(m, J, C)`` keypoints."""
    a = np.asarray(a, float)
    ids = np.asarray(frame_ids, np.int64)
    if not len(ids):
        return ids, a
    x = rig_instants(ids, rate, clock)
    r = np.round(x).astype(np.int64)
    order = np.lexsort((np.abs(x - r), r))
    keep = order[np.r_[True, np.diff(r[order]) != 0]]
    r = r[keep]
    # the rig frame's instant on the camera's own frames
    kappa = (r * clock.rate + clock.offset) / float(rate)
    step = frame_step(ids)
    g0 = int(ids.min())
    n = int((ids.max() - g0) // step) + 1
    own = np.full((n,) + a.shape[1:], np.nan)
    own[..., -1] = 0.0
    on = (ids - g0) % step == 0
    own[(ids[on] - g0) // step] = a[on]
    pos = (kappa - g0) / step
    k = np.round(pos).astype(np.int64)
    exact = np.abs(pos - k) < 1e-9
    out = np.full((len(r),) + a.shape[1:], np.nan)
    out[..., -1] = 0.0
    out[exact] = own[np.clip(k[exact], 0, n - 1)]
    lo = np.floor(pos).astype(np.int64)
    between = ~exact & (lo >= 0) & (lo + 1 < n)
    w = (pos - lo)[between][:, None, None]
    p, q = own[lo[between]], own[lo[between] + 1]
    xy = (1 - w) * p[..., :-1] + w * q[..., :-1]
    conf = np.minimum(np.nan_to_num(p[..., -1]), np.nan_to_num(q[..., -1]))
    seen = np.isfinite(xy).all(-1) & (conf > 0)
    out[between, ..., :-1] = np.where(seen[..., None], xy, np.nan)
    out[between, ..., -1] = np.where(seen, conf, 0.0)
    return r, out
