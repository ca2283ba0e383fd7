"""The report's figures, one function each; every function takes a
:class:`~mirrorgraph.report.ReportData` and returns a matplotlib ``Figure``.

Colours are shared: the person (direct view) blue, the reflection orange,
inliers green, outliers red, "before refinement" grey, "after" blue.
"""

from __future__ import annotations

import numpy as np

from .. import geometry as geo
from . import require_matplotlib

REAL = "#1f77b4"
MIRROR = "#ff7f0e"
INLIER = "#2ca02c"
OUTLIER = "#d62728"
BEFORE = "#8c8c8c"
AFTER = "#1f77b4"


def _plt():
    return require_matplotlib()


def _sample(mask: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    idx = np.flatnonzero(mask)
    if len(idx) > count:
        idx = np.sort(rng.choice(idx, count, replace=False))
    return idx


def image_limits(data, margin: float = 0.06, far: float = 4.0):
    """``(xlim, ylim, epipole_shown)``: the image plus the epipole unless it is
    more than ``far`` image diagonals from the image centre."""
    w, h = data.image_size
    lo, hi = np.array([0.0, 0.0]), np.array([float(w), float(h)])
    shown = False
    e = data.epipole
    if e is not None and np.linalg.norm(e - hi / 2) < far * np.hypot(w, h):
        lo, hi, shown = np.minimum(lo, e), np.maximum(hi, e), True
    pad = margin * (hi - lo).max()
    return (lo[0] - pad, hi[0] + pad), (hi[1] + pad, lo[1] - pad), shown


# --------------------------------------------------------------------------- (1)
def image_plane(data, *, sample: int = 150, seed: int = 0):
    """Image plane: epipole, a sample of joint-to-reflection lines, inliers and outliers."""
    plt = _plt()
    rng = np.random.default_rng(seed)
    fig, ax = plt.subplots(figsize=(9, 6.5), layout="constrained")
    w, h = data.image_size
    ax.add_patch(plt.Rectangle((0, 0), w, h, fill=False, ec="k", lw=1.2))
    ax.text(4, h - 8, f"image {w}x{h}", fontsize=8, va="bottom")
    xlim, ylim, shown = image_limits(data)
    pick_in = _sample(data.inlier, sample, rng)
    pick_out = _sample(~data.inlier, max(sample // 3, 1), rng)
    e = data.epipole
    for idx, colour, label in ((pick_in, INLIER, "inlier pair"), (pick_out, OUTLIER, "outlier pair")):
        if len(idx) == 0:
            continue
        u, um = data.u[idx], data.um[idx]
        if e is not None and shown:
            # from the epipole through the farther of the two points
            far = np.where((np.linalg.norm(u - e, axis=1) > np.linalg.norm(um - e, axis=1))[:, None],
                           u, um)
            segs = np.stack([np.broadcast_to(e, far.shape), far], axis=1)
        else:
            # epipole off the figure: extend the joint-reflection segment across the image
            dvec = um - u
            dvec /= np.maximum(np.linalg.norm(dvec, axis=1, keepdims=True), 1e-9)
            L = np.hypot(w, h)
            segs = np.stack([u - L * dvec, u + L * dvec], axis=1)
        from matplotlib.collections import LineCollection
        ax.add_collection(LineCollection(segs, colors=colour, lw=0.6,
                                         alpha=0.35 if colour == INLIER else 0.6))
        ax.plot([], [], color=colour, lw=1.5, label=f"{label}: line from the epipole "
                f"({len(idx)} drawn of {int(np.count_nonzero(data.inlier if colour == INLIER else ~data.inlier))})")
    show = np.concatenate([pick_in, pick_out])
    ax.scatter(data.u[show, 0], data.u[show, 1], s=7, c=REAL, label="joint (person)", zorder=3)
    ax.scatter(data.um[show, 0], data.um[show, 1], s=9, c=MIRROR, marker="^",
               label="joint (reflection)", zorder=3)
    if e is not None and shown:
        ax.plot(*e, marker="*", ms=16, color="k", mfc="gold", ls="none", zorder=4,
                label=f"epipole ({e[0]:.0f}, {e[1]:.0f}) px")
    elif e is not None:
        ax.text(0.5, 0.02, f"epipole far outside: ({e[0]:.0f}, {e[1]:.0f}) px",
                transform=ax.transAxes, ha="center", fontsize=9,
                bbox=dict(fc="w", ec="0.6"))
    else:
        ax.text(0.5, 0.02, "epipole at infinity (mirror parallel to the optical axis)",
                transform=ax.transAxes, ha="center", fontsize=9, bbox=dict(fc="w", ec="0.6"))
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    ax.set_aspect("equal")
    ax.set_xlabel("x (px)")
    ax.set_ylabel("y (px, down)")
    n_in, n_all = int(np.count_nonzero(data.inlier)), len(data.inlier)
    ax.set_title("Image plane: every joint, its reflection and the epipole are collinear\n"
                 f"{n_in} inlier pairs of {n_all} ({100 * n_in / max(n_all, 1):.1f}%); "
                 "a random sample is drawn")
    ax.legend(loc="best", fontsize=8, framealpha=0.9)
    return fig


# --------------------------------------------------------------------------- (2)
def _hist_pair(ax, before, after, label, unit="px", ylabel="joint pairs"):
    before, after = before[np.isfinite(before)], after[np.isfinite(after)]
    both = np.concatenate([before, after])
    if both.size == 0:
        ax.text(0.5, 0.5, "no data", ha="center", transform=ax.transAxes)
        return
    top = float(np.percentile(both, 99))
    top = top if top > 0 else 1.0
    bins = np.linspace(0, top, 40)
    for vals, colour, name, kw in ((before, BEFORE, "before (initial normal)", dict(alpha=0.55)),
                                   (after, AFTER, "after refinement",
                                    dict(histtype="step", lw=1.8))):
        med = float(np.median(vals)) if vals.size else np.nan
        over = int(np.count_nonzero(vals > top))
        ax.hist(np.clip(vals, 0, top), bins=bins, color=colour, **kw,
                label=f"{name}: median {med:.2f} {unit}" + (f", {over} beyond" if over else ""))
        ax.axvline(med, color=colour, ls="--", lw=1)
    ax.set_xlabel(f"{label} ({unit})")
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=8)


def residuals(data):
    """Histograms of epipolar and reprojection residuals (inlier pairs), before and after."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.6), layout="constrained")
    m = data.inlier
    _hist_pair(a1, data.epi_before[m], data.epi_after[m], "epipolar distance")
    a1.set_title("Epipolar distance (how far a pair is from being\n"
                 "collinear with the epipole)")
    rb = data.reproj_before[m].ravel()
    ra = data.reproj_after[m].ravel()
    _hist_pair(a2, rb, ra, "reprojection error", ylabel="joint observations (2 per pair)")
    a2.set_title("Reprojection error of the 3D joints (both views pooled);\n"
                 "after: joints held to rigid bones and smooth motion", fontsize=11)
    fig.suptitle(f"Residuals of the {int(np.count_nonzero(m))} inlier pairs, 99th percentile "
                 "range (larger values counted in the last bin)"
                 + ("" if data.refined else " - refinement did not run: before = after"),
                 fontsize=10)
    return fig


# --------------------------------------------------------------------------- (3)
def _frustum(depth: float, K: np.ndarray, size) -> np.ndarray:
    """``(5, 3)`` apex + 4 image corners at ``depth``, camera frame."""
    w, h = size
    corners = np.array([[0, 0, 1], [w, 0, 1], [w, h, 1], [0, h, 1]], float)
    rays = corners @ np.linalg.inv(K).T
    return np.vstack([np.zeros(3), depth * rays])


def _view(P: np.ndarray) -> np.ndarray:
    """Camera frame (x right, y down, z forward) -> plot axes (x, z, up)."""
    P = np.asarray(P, float)
    return np.stack([P[..., 0], P[..., 2], -P[..., 1]], axis=-1)


def _draw_frustum(ax, F: np.ndarray, colour: str, label: str):
    V = _view(F)
    for i in range(1, 5):
        ax.plot(*zip(V[0], V[i]), color=colour, lw=1)
    ring = V[[1, 2, 3, 4, 1]]
    ax.plot(ring[:, 0], ring[:, 1], ring[:, 2], color=colour, lw=1.5, label=label)


def pick_frames(data, count: int) -> np.ndarray:
    """``count`` frame indices spread over the run, each with the most 3D joints nearby."""
    ok = np.isfinite(data.joints_after).all(-1).sum(1)
    good = np.flatnonzero(ok >= max(1, 0.6 * ok.max())) if ok.max() > 0 else np.array([], int)
    if len(good) == 0:
        return good
    return np.unique(good[np.linspace(0, len(good) - 1, min(count, len(good))).round().astype(int)])


def scene3d(data, *, frames: int = 4):
    """3D view: the real and the virtual camera, the mirror and the skeleton at a few frames."""
    plt = _plt()
    fig = plt.figure(figsize=(9, 7.5), layout="constrained")
    ax = fig.add_subplot(projection="3d")
    n, d = data.normal, data.distance
    depth = 0.12 * d
    F = _frustum(depth, data.K, data.image_size)
    _draw_frustum(ax, F, "k", "real camera")
    _draw_frustum(ax, geo.reflect_points(F, n, d), "#9467bd", "virtual (mirror) camera")
    picks = pick_frames(data, frames)
    cmap = plt.get_cmap("viridis")
    pts = [np.zeros((1, 3)), geo.reflect_points(np.zeros((1, 3)), n, d)]
    bones = data.skeleton.bone_index
    for k, t in enumerate(picks):
        X = data.joints_after[t]
        Xr = geo.reflect_points(X, n, d)
        colour = cmap(k / max(len(picks) - 1, 1) * 0.85)
        for a, b in bones:
            for P, ls, alpha in ((X, "-", 1.0), (Xr, ":", 0.6)):
                seg = _view(P[[a, b]])
                if np.isfinite(seg).all():
                    ax.plot(seg[:, 0], seg[:, 1], seg[:, 2], color=colour, ls=ls, alpha=alpha,
                            lw=2 if ls == "-" else 1)
        V = _view(X)
        ax.scatter(V[:, 0], V[:, 1], V[:, 2], color=colour, s=8)
        ax.plot([], [], color=colour, lw=2, label=f"skeleton, frame {int(data.frame_ids[t])}")
        pts += [X[np.isfinite(X).all(1)], Xr[np.isfinite(Xr).all(1)]]
    if len(picks):
        ax.plot([], [], color="0.4", ls=":", label="its reflection (behind the mirror)")
    P = np.vstack(pts)
    # the mirror: a rectangle in the plane around the people, "up" = -y projected on it
    up = np.array([0.0, -1.0, 0.0]) - n * (-n[1])
    up = up / np.linalg.norm(up) if np.linalg.norm(up) > 1e-6 else np.array([1.0, 0, 0])
    side = np.cross(n, up)
    body = np.vstack(pts[2:]) if len(pts) > 2 else P
    foot = body - np.outer(body @ n - d, n)
    cu, cs = foot @ up, foot @ side
    pad = 0.25 * d
    c0 = d * n
    rect = np.array([c0 + a * up + b * side
                     for a, b in ((cu.min() - pad, cs.min() - pad), (cu.max() + pad, cs.min() - pad),
                                  (cu.max() + pad, cs.max() + pad), (cu.min() - pad, cs.max() + pad))])
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection
    ax.add_collection3d(Poly3DCollection([_view(rect)], facecolor="#9ecae1", edgecolor="#3182bd",
                                         alpha=0.25))
    ax.plot([], [], color="#9ecae1", lw=8, alpha=0.6, label="mirror plane")
    A = _view(np.vstack([P, rect, F]))
    lo, hi = A.min(0), A.max(0)
    mid, half = (lo + hi) / 2, (hi - lo).max() / 2
    ax.set_xlim(mid[0] - half, mid[0] + half)
    ax.set_ylim(mid[1] - half, mid[1] + half)
    ax.set_zlim(mid[2] - half, mid[2] + half)
    ax.set_box_aspect((1, 1, 1))
    u = data.unit
    ax.set_xlabel(f"x, right ({u})")
    ax.set_ylabel(f"z, forward ({u})")
    ax.set_zlabel(f"up = -y ({u})")
    ax.view_init(elev=22, azim=-60)
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title("Cameras, mirror and skeleton (real camera frame, refined)\n"
                 f"mirror distance {d:.3f} {u}", fontsize=11)
    return fig


# --------------------------------------------------------------------------- (4)
def bone_lengths(data):
    """Every bone's length over time, before (initial normal) and after refinement."""
    plt = _plt()
    B = len(data.bone_names)
    cols = 5 if B > 6 else max(B, 1)
    rows = max(1, int(np.ceil(B / cols)))
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows + 0.8),
                             sharex=True, squeeze=False, layout="constrained")
    scale = 100.0 if data.unit == "m" else 1.0
    unit = "cm" if data.unit == "m" else "x mirror distance"
    fr = data.frame_ids
    for k, ax in enumerate(axes.ravel()):
        if k >= B:
            ax.axis("off")
            continue
        b0, b1 = data.bones_before[:, k] * scale, data.bones_after[:, k] * scale
        ax.plot(fr, b0, ".", ms=2.5, color=BEFORE,
                label=f"before: sd {np.nanstd(b0):.1f}" if np.isfinite(b0).any() else "before")
        ax.plot(fr, b1, "-", lw=1.4, color=AFTER,
                label=f"after: sd {np.nanstd(b1):.1f}" if np.isfinite(b1).any() else "after")
        ref = data.bone_reference.get(data.bone_names[k]) if data.bone_reference else None
        if ref is not None:
            ax.axhline(ref * scale, color="k", ls="--", lw=1,
                       label=f"refined length {ref * scale:.1f}")
        ax.set_title(data.bone_names[k].replace("_", " "), fontsize=10)
        ax.legend(fontsize=7, loc="upper right")
        fin = np.concatenate([b0[np.isfinite(b0)], b1[np.isfinite(b1)]])
        if fin.size:
            lo, hi = np.percentile(fin, [1, 99])
            pad = 0.15 * (hi - lo) + 1e-6
            ax.set_ylim(lo - pad, hi + pad)
        if k % cols == 0:
            ax.set_ylabel(f"length ({unit})")
        if k >= B - cols:
            ax.set_xlabel("frame")
    fig.suptitle("Bone lengths over time: a rigid bone should be a flat line "
                 "(before = triangulated with the initial normal; sd in the same unit)",
                 fontsize=10)
    return fig


# --------------------------------------------------------------------------- (5)
def _ellipse_points(cov: np.ndarray, k: float, num: int = 200) -> np.ndarray:
    vals, vecs = np.linalg.eigh(cov)
    a = np.linspace(0, 2 * np.pi, num)
    circ = np.stack([np.cos(a), np.sin(a)], 1)
    return k * circ * np.sqrt(np.maximum(vals, 0)) @ vecs.T


def uncertainty(data):
    """Covariance of the normal, as 1-2-3 sigma ellipses of the epipole (pixels)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 6.5), layout="constrained")
    e, cov = data.epipole, data.epipole_cov
    if e is None or cov is None:
        why = ("the epipole is at infinity" if e is None
               else "no covariance: the refinement did not run")
        ax.text(0.5, 0.5, f"No uncertainty ellipse: {why}.", ha="center", va="center",
                transform=ax.transAxes)
        ax.set_axis_off()
        return fig
    pts = [e[None]]
    for k, ls in ((1, "-"), (2, "--"), (3, ":")):
        E = e + _ellipse_points(cov, k)
        ax.plot(E[:, 0], E[:, 1], color=AFTER, ls=ls, lw=1.5,
                label=f"{k} sigma ({[39.3, 86.5, 98.9][k - 1]}% for a 2D Gaussian)")
        pts.append(E)
    ax.plot(*e, "*", ms=15, mfc="gold", mec="k", label=f"refined epipole ({e[0]:.1f}, {e[1]:.1f})")
    e0 = data.initial_epipole
    if e0 is not None:
        ax.plot(*e0, "o", ms=8, mfc="none", mec=BEFORE, mew=2,
                label=f"initial epipole ({e0[0]:.1f}, {e0[1]:.1f})")
        pts.append(e0[None])
    P = np.vstack(pts)
    lo, hi = P.min(0), P.max(0)
    mid, half = (lo + hi) / 2, 0.6 * max((hi - lo).max(), 1e-3)
    ax.set_xlim(mid[0] - half, mid[0] + half)
    ax.set_ylim(mid[1] + half, mid[1] - half)
    ax.set_aspect("equal")
    ax.set_xlabel("x (px)")
    ax.set_ylabel("y (px, down)")
    sd = np.sqrt(np.linalg.eigvalsh(cov))
    txt = [f"epipole std: {sd[1]:.1f} px (major), {sd[0]:.1f} px (minor)"]
    if data.rotation_std_deg is not None:
        txt.append(f"normal direction std: {data.rotation_std_deg:.3f} deg")
    if data.distance_std is not None:
        txt.append(f"mirror distance: {data.distance:.3f} +- {data.distance_std:.3f} {data.unit}")
    ax.text(0.02, 0.02, "\n".join(txt), transform=ax.transAxes, fontsize=9, va="bottom",
            bbox=dict(fc="w", ec="0.6"))
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    ax.set_title("Uncertainty of the mirror normal, seen as the epipole\n"
                 "(first-order propagation of the 3x3 marginal covariance of n)", fontsize=11)
    return fig
