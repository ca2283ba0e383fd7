"""The focal length from the scene's straight lines: vanishing points of orthogonal directions.

Parallel 3D lines of direction ``d`` image to lines through one vanishing point
``v ~ K d``; two orthogonal directions give, for a camera of square pixels, no skew
and principal point ``c``, ``(v1 - c) . (v2 - c) + f^2 w1 w2 = 0`` for homogeneous
``v = (x, y, w)`` (Hartley and Zisserman, sec. 8.8: the image of the absolute conic).
A room (walls, floor tiles, door and window frames, the mirror's own frame) has three
orthogonal families of lines; the reflected room obeys the same camera and the same
orthogonality (the mirror maps orthogonal directions to orthogonal ones, and
directions along its normal to themselves: their vanishing point is the epipole
``e ~ K n``).

The steps, on line segments of a static camera's frames (:mod:`mirrorgraph.video.lines`):

* vanishing points by sequential RANSAC over segment pairs
  (:func:`~mirrorgraph.initial.ransac.ransac`: two segments' lines meet at a candidate;
  a segment's residual is the distance of its endpoint from the line through its
  midpoint and the candidate, pixels), each refitted by least squares on its inliers;
* segments of one physical edge (a detector splits an edge into pieces) grouped into
  edges; a vanishing point needs :data:`MIN_EDGES` edges;
* every pair of vanishing points whose orthogonality gives a focal length in the
  searched field of view is a hypothesis of a Manhattan frame; the one that most
  edges' vanishing points agree with (within ``tol_deg`` of one of its three axes)
  wins, and the focal length minimises the squared cosines of every pair of its
  vanishing points on different axes;
* the standard deviation by a bootstrap: the edges of each vanishing point resampled
  (a cluster bootstrap: one edge's pieces move together) and the principal point drawn
  from its prior (the image centre with the spread of real cameras); where the pairs'
  orthogonality misfits more than that scatter explains (three axes: three pairs for
  one unknown), the std widens by the misfit's Birge ratio.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from .ransac import RansacOptions, ransac

__all__ = ["LinesFocal", "VanishingPoint", "detect_vanishing_points", "focal_from_lines",
           "orthogonal_focal", "segment_lines", "vp_residuals", "MIN_EDGES"]

#: Fewest distinct edges (segments grouped by the line they lie on) a vanishing point
#: needs: with one or two it is barely localised along their common line, and the
#: cluster bootstrap cannot see its spread.
MIN_EDGES = 3

#: Fewest segments the focal length is attempted on.
MIN_SEGMENTS = 12


@dataclass(frozen=True)
class VanishingPoint:
    """A vanishing point and the segments that meet there.

    Attributes:
        point: ``(3,)`` unit homogeneous point in normalised image coordinates
            (``(x - cx) / s``, ``(y - cy) / s`` with the image centre ``c`` and half the
            larger side ``s``); ``w = 0``: a direction parallel to the image.
        segments: ``(k,)`` indices of its inlier segments.
        edges: ``(k,)`` the edge (group of collinear segments) of each.
    """

    point: np.ndarray
    segments: np.ndarray
    edges: np.ndarray

    @property
    def num_edges(self) -> int:
        """Distinct edges among its segments."""
        return int(len(np.unique(self.edges)))


@dataclass
class LinesFocal:
    """The focal length from the scene's lines (:func:`focal_from_lines`).

    Attributes:
        focal_px: the estimate, px; ``None`` where the lines do not give one.
        std_px: its standard deviation (bootstrap), px.
        n_segments: segments offered.
        n_vps: vanishing points of the chosen frame (on its three axes).
        n_axes: its axes with a vanishing point (2 or 3).
        reason: why there is no estimate (``None`` where there is one).
        vanishing_points_px: the chosen frame's vanishing points in pixels (``None``
            for one at infinity), with their axis and their edges' count.
        segments_used: segments of the chosen vanishing points.
        principal_point: the principal point assumed (the prior's centre), px.
        misfit: the orthogonality's misfit at the estimate, the sum over the pairs on
            different axes of their squared cosine over its bootstrap variance, per
            degree of freedom (pairs - 1); above 1 it widens ``std_px`` by its square
            root (a Birge ratio); nan with one pair.
    """

    focal_px: float | None
    std_px: float | None
    n_segments: int
    n_vps: int = 0
    n_axes: int = 0
    reason: str | None = None
    vanishing_points_px: list = field(default_factory=list)
    segments_used: int = 0
    principal_point: tuple[float, float] | None = None
    misfit: float = float("nan")

    @property
    def usable(self) -> bool:
        """An estimate with a finite positive standard deviation."""
        return (self.focal_px is not None and self.std_px is not None
                and np.isfinite(self.std_px) and self.std_px > 0)

    def to_dict(self) -> dict:
        """``{f, std, n_segments, n_vps, n_axes, ...}``, or ``{reason, n_segments}``."""
        if not self.usable:
            return {"reason": self.reason or "no estimate", "n_segments": int(self.n_segments)}
        return {"f": float(self.focal_px), "std": float(self.std_px),
                "n_segments": int(self.n_segments), "n_vps": int(self.n_vps),
                "n_axes": int(self.n_axes), "segments_used": int(self.segments_used),
                "misfit": None if not np.isfinite(self.misfit) else float(self.misfit),
                "vanishing_points_px": self.vanishing_points_px}


# --------------------------------------------------------------------------- segments
def segment_lines(seg: np.ndarray) -> np.ndarray:
    """``(N, 3)`` homogeneous lines ``(a, b, c)`` with ``a^2 + b^2 = 1`` through the
    ``(N, 4)`` segments ``x1, y1, x2, y2``."""
    seg = np.asarray(seg, dtype=float)
    p1 = np.column_stack([seg[:, 0], seg[:, 1], np.ones(len(seg))])
    p2 = np.column_stack([seg[:, 2], seg[:, 3], np.ones(len(seg))])
    lines = np.cross(p1, p2)
    return lines / np.maximum(np.hypot(lines[:, 0], lines[:, 1]), 1e-300)[:, None]


def vp_residuals(v: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """``(N,)`` distance of each segment's first endpoint from the line through its
    midpoint and the homogeneous point ``v`` (the segments' unit: how far the segment
    must turn about its midpoint to point at ``v``)."""
    seg = np.asarray(seg, dtype=float)
    n = len(seg)
    mid = np.column_stack([0.5 * (seg[:, 0] + seg[:, 2]), 0.5 * (seg[:, 1] + seg[:, 3]),
                           np.ones(n)])
    line = np.cross(mid, np.broadcast_to(v, (n, 3)))
    norm = np.hypot(line[:, 0], line[:, 1])
    num = np.abs(line[:, 0] * seg[:, 0] + line[:, 1] * seg[:, 1] + line[:, 2])
    return np.where(norm > 1e-15, num / np.maximum(norm, 1e-300), 0.0)


def _refit(v0: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """The unit homogeneous point minimising the squared residuals (:func:`vp_residuals`)
    of the segments, from ``v0`` (a chart on the sphere about it)."""
    from scipy.optimize import least_squares
    v0 = np.asarray(v0, float) / np.linalg.norm(v0)
    if len(seg) < 2:
        return v0
    basis = np.linalg.svd(v0[None, :])[2][1:].T            # (3, 2) tangent of the sphere

    def fun(t):
        return vp_residuals(v0 + basis @ t, seg)

    sol = least_squares(fun, np.zeros(2), method="lm", xtol=1e-12, ftol=1e-12)
    v = v0 + basis @ sol.x
    return v / np.linalg.norm(v)


def _edges(seg: np.ndarray, v: np.ndarray, tol: float) -> np.ndarray:
    """``(N,)`` edge labels of segments meeting at ``v``: segments whose lines through
    ``v`` pass within ``tol`` of each other's midpoints are one edge (connected
    components)."""
    n = len(seg)
    if n == 0:
        return np.zeros(0, dtype=int)
    mid = np.column_stack([0.5 * (seg[:, 0] + seg[:, 2]), 0.5 * (seg[:, 1] + seg[:, 3]),
                           np.ones(n)])
    line = np.cross(mid, np.broadcast_to(v, (n, 3)))
    line = line / np.maximum(np.hypot(line[:, 0], line[:, 1]), 1e-300)[:, None]
    dist = np.abs(line @ mid.T)                             # (N, N) line i to midpoint j
    near = np.maximum(dist, dist.T) < tol
    from scipy.sparse.csgraph import connected_components   # at first use: start-up

    return connected_components(near, directed=False)[1].astype(int)


def detect_vanishing_points(seg: np.ndarray, threshold: float, *, max_vps: int = 8,
                            min_segments: int = 6, edge_tol: float | None = None,
                            seed: int = 0) -> list[VanishingPoint]:
    """Vanishing points of the ``(N, 4)`` segments by sequential RANSAC over segment pairs.

    Args:
        seg: segments ``x1, y1, x2, y2`` (normalised coordinates).
        threshold: a segment's residual (:func:`vp_residuals`) under which it meets a
            vanishing point, in the segments' unit.
        max_vps: most vanishing points sought.
        min_segments: fewest inliers of a vanishing point; the search stops at the
            first with fewer.
        edge_tol: distance within which segments on one line through the point are one
            edge (default ``2 threshold``).
        seed: RANSAC's seed.

    Returns:
        Vanishing points with at least :data:`MIN_EDGES` edges, most supported first.
    """
    seg = np.asarray(seg, dtype=float)
    lines = segment_lines(seg)
    edge_tol = 2.0 * threshold if edge_tol is None else edge_tol
    left = np.arange(len(seg))
    out: list[VanishingPoint] = []
    for k in range(max_vps):
        if len(left) < max(min_segments, 2):
            break
        sub, sub_lines = seg[left], lines[left]

        def solver(idx, sub_lines=sub_lines):
            v = np.cross(sub_lines[idx[0]], sub_lines[idx[1]])
            n = np.linalg.norm(v)
            return [] if n < 1e-12 else [v / n]

        def residuals(v, idx, sub=sub):
            return vp_residuals(v, sub if idx is None else sub[idx])

        def refit(inl, v, sub=sub):
            return _refit(v, sub[inl])

        res = ransac(len(sub), 2, solver, residuals,
                     RansacOptions(threshold=threshold, seed=seed + k, min_iterations=200,
                                   max_iterations=3000), refit=refit)
        if res is None or np.count_nonzero(res.inliers) < min_segments:
            break
        idx = left[res.inliers]
        edges = _edges(seg[idx], res.model, edge_tol)
        vp = VanishingPoint(point=res.model, segments=idx, edges=edges)
        if vp.num_edges >= MIN_EDGES:
            out.append(vp)
        left = left[~res.inliers]
    return out


# --------------------------------------------------------------------------- focal
def _directions(points: np.ndarray, F: float) -> np.ndarray:
    """``(k, 3)`` unit ray directions of the ``(k, 3)`` homogeneous points (normalised
    coordinates about the principal point) for the normalised focal length ``F``."""
    d = np.column_stack([points[:, 0], points[:, 1], F * points[:, 2]])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _frame_axes(d: np.ndarray, a: int, b: int) -> np.ndarray:
    """``(3, 3)`` rows: the orthonormal frame of directions ``a`` and ``b`` of ``d``."""
    x = d[a]
    y = d[b] - (d[b] @ x) * x
    y = y / np.linalg.norm(y)
    return np.stack([x, y, np.cross(x, y)])


def _pair_focal(p: np.ndarray, q: np.ndarray) -> float:
    """The normalised focal length that makes the homogeneous points ``p, q`` orthogonal
    directions (nan where none)."""
    den = p[2] * q[2]
    if abs(den) < 1e-12:
        return float("nan")
    F2 = -(p[0] * q[0] + p[1] * q[1]) / den
    return float(np.sqrt(F2)) if F2 > 0 else float("nan")


def _pairs(axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices ``(i, j)``, ``i < j``, of the pairs on different ``axes``."""
    i, j = np.nonzero(axes[:, None] != axes[None, :])
    keep = i < j
    return i[keep], j[keep]


def _fit_focal(points: np.ndarray, axes: np.ndarray, lo: float, hi: float) -> float:
    """The normalised focal length in ``[lo, hi]`` minimising the squared cosines between
    every pair of ``points`` on different ``axes``."""
    from scipy.optimize import minimize_scalar
    i, j = _pairs(axes)

    def cost(logF):
        d = _directions(points, float(np.exp(logF)))
        return float(np.sum(np.einsum("ij,ij->i", d[i], d[j]) ** 2))

    sol = minimize_scalar(cost, bounds=(np.log(lo), np.log(hi)), method="bounded",
                          options={"xatol": 1e-7})
    return float(np.exp(sol.x))


def orthogonal_focal(vps: list[VanishingPoint], lo: float, hi: float, tol_deg: float = 3.0
                     ) -> tuple[float, np.ndarray, np.ndarray] | None:
    """The Manhattan frame most vanishing points agree with, and its focal length.

    Args:
        vps: vanishing points (normalised coordinates about the principal point).
        lo, hi: the normalised focal lengths searched.
        tol_deg: a vanishing point agrees with a frame where its direction lies within
            this angle of one of the frame's axes.

    Returns:
        ``(F, chosen, axes)``: the normalised focal length, the indices of the agreeing
        vanishing points and their axes (0, 1, 2); ``None`` where no pair of vanishing
        points is orthogonal for a focal length in ``[lo, hi]``.
    """
    if len(vps) < 2:
        return None
    pts = np.array([vp.point for vp in vps])
    weight = np.array([vp.num_edges for vp in vps], dtype=float)
    cos_tol = np.cos(np.radians(tol_deg))
    best = None
    for a in range(len(vps)):
        for b in range(a + 1, len(vps)):
            F = _pair_focal(pts[a], pts[b])
            if not (lo <= F <= hi):
                continue
            d = _directions(pts, F)
            R = _frame_axes(d, a, b)
            cos = np.abs(d @ R.T)                           # (k, 3)
            axis = np.argmax(cos, axis=1)
            ok = cos[np.arange(len(vps)), axis] >= cos_tol
            ok[[a, b]] = True
            axis[a], axis[b] = 0, 1
            score = (float(weight[ok].sum()), len(np.unique(axis[ok])))
            if best is None or score > best[0]:
                best = (score, np.nonzero(ok)[0], axis[ok])
    if best is None:
        return None
    chosen, axes = best[1], best[2]
    F = _fit_focal(pts[chosen], axes, lo, hi)
    return F, chosen, axes


def focal_from_lines(segments: np.ndarray, image_size: tuple[int, int], *,
                     fov_range_deg: tuple[float, float] = (20.0, 120.0),
                     principal_point_sigma_px: float = 0.0,
                     threshold_px: float = 1.5, tol_deg: float = 3.0,
                     bootstrap: int = 200, seed: int = 0) -> LinesFocal:
    """The focal length from line segments of one static camera (see the module docstring).

    Args:
        segments: ``(N, 4)`` segments ``x1, y1, x2, y2``, undistorted pixels.
        image_size: ``(width, height)`` px; the principal point is assumed at its centre.
        fov_range_deg: horizontal fields of view searched, degrees.
        principal_point_sigma_px: the principal point's spread about the centre (each
            coordinate, px), drawn in the bootstrap.
        threshold_px: a segment meets a vanishing point within this residual, px.
        tol_deg: a vanishing point agrees with a Manhattan frame within this angle.
        bootstrap: resamples of the standard deviation.
        seed: RANSAC's and the bootstrap's seed.

    Returns:
        :class:`LinesFocal`: the estimate with its bootstrap standard deviation, or the
        reason there is none.
    """
    seg_px = np.asarray(segments, dtype=float).reshape(-1, 4)
    n = len(seg_px)
    w, h = float(image_size[0]), float(image_size[1])
    cx, cy, s = 0.5 * w, 0.5 * h, 0.5 * max(w, h)
    base = LinesFocal(None, None, n, principal_point=(cx, cy))
    if n < MIN_SEGMENTS:
        base.reason = f"{n} line segments (need {MIN_SEGMENTS})"
        return base
    seg = (seg_px - np.array([cx, cy, cx, cy])) / s
    vps = detect_vanishing_points(seg, threshold_px / s, seed=seed)
    if len(vps) < 2:
        base.reason = (f"{len(vps)} vanishing point(s) with {MIN_EDGES} or more edges among "
                       f"{n} segments (need two orthogonal directions)")
        return base
    lo, hi = (0.5 * w / np.tan(0.5 * np.radians(f)) / s for f in sorted(fov_range_deg)[::-1])
    found = orthogonal_focal(vps, lo, hi, tol_deg)
    if found is None:
        base.reason = (f"no two of {len(vps)} vanishing points are orthogonal for a field of "
                       f"view within {fov_range_deg[0]:g}-{fov_range_deg[1]:g} deg")
        return base
    F, chosen, axes = found
    if len(np.unique(axes)) < 2:
        base.reason = "the vanishing points found lie along one direction"
        return base
    used = [vps[i] for i in chosen]
    pi, pj = _pairs(axes)
    rng = np.random.default_rng(seed)
    draws = np.full(bootstrap, np.nan)
    cosines = np.full((bootstrap, len(pi)), np.nan)
    for b in range(bootstrap):
        shift = rng.normal(0.0, principal_point_sigma_px / s, 2)
        pts = []
        for vp in used:
            labels = np.unique(vp.edges)
            pick = rng.choice(labels, size=len(labels), replace=True)
            idx = np.concatenate([vp.segments[vp.edges == e] for e in pick])
            v = _refit(vp.point, seg[idx])
            pts.append([v[0] - shift[0] * v[2], v[1] - shift[1] * v[2], v[2]])
        pts = np.array(pts)
        draws[b] = _fit_focal(pts, axes, lo, hi)
        d = _directions(pts, F)
        cosines[b] = np.einsum("ij,ij->i", d[pi], d[pj])
    draws = draws[np.isfinite(draws)]
    std = float(np.std(draws, ddof=1) * s) if len(draws) > 2 else float("nan")
    # the orthogonality's misfit at the estimate against its bootstrap spread (a Birge
    # ratio): pairs that disagree more than their vanishing points' scatter explains
    # (lens distortion, lines not quite at right angles) widen the std
    d = _directions(np.array([vp.point for vp in used]), F)
    c = np.einsum("ij,ij->i", d[pi], d[pj])
    sc = np.nanstd(cosines, axis=0, ddof=1)
    dof = len(pi) - 1
    misfit = (float(np.sum((c / np.maximum(sc, 1e-12)) ** 2)) / dof) if dof > 0 else float("nan")
    if np.isfinite(misfit) and misfit > 1.0:
        std *= np.sqrt(misfit)
    vps_px = []
    for vp, ax in zip(used, axes):
        p = vp.point
        px = None if abs(p[2]) < 1e-9 else [float(p[0] / p[2] * s + cx), float(p[1] / p[2] * s + cy)]
        vps_px.append({"point_px": px, "axis": int(ax), "edges": vp.num_edges,
                       "segments": int(len(vp.segments))})
    return LinesFocal(focal_px=float(F * s), std_px=std, n_segments=n, n_vps=len(used),
                      misfit=misfit,
                      n_axes=int(len(np.unique(axes))), vanishing_points_px=vps_px,
                      segments_used=int(sum(len(vp.segments) for vp in used)),
                      principal_point=(cx, cy))
