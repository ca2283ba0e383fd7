"""The report's figures, one function each; every function takes a
:class:`~mirrorgraph.report.ReportData` and returns a matplotlib ``Figure``.

Colours are shared: the person (direct view) blue, the reflection orange,
inliers green, outliers red, "before refinement" grey, "after" blue.
"""

from __future__ import annotations

import numpy as np

from .. import geometry as geo
from .backend import require_matplotlib

REAL = "#1f77b4"
MIRROR = "#ff7f0e"
INLIER = "#2ca02c"
OUTLIER = "#d62728"
BEFORE = "#8c8c8c"
AFTER = "#1f77b4"
THIRD = "#9467bd"


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
    xlim, ylim, shown = image_limits(data)
    aspect = abs(ylim[0] - ylim[1]) / max(abs(xlim[1] - xlim[0]), 1e-9)
    fig, ax = plt.subplots(figsize=(9, float(np.clip(7.6 * aspect + 1.9, 4.5, 9.5))),
                           layout="constrained")
    w, h = data.image_size
    ax.add_patch(plt.Rectangle((0, 0), w, h, fill=False, ec="k", lw=1.2))
    ax.text(4, h - 8, f"image {w}x{h}", fontsize=8, va="bottom")
    pick_in = _sample(data.inlier, sample, rng)
    pick_out = _sample(~data.inlier, max(sample // 3, 1), rng)
    e = data.epipole
    # outliers first, thin and faint, so that the inliers' lines stay visible on top
    for idx, colour, label in ((pick_out, OUTLIER, "outlier pair"), (pick_in, INLIER, "inlier pair")):
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
        ax.add_collection(LineCollection(segs, colors=colour,
                                         lw=0.7 if colour == INLIER else 0.5,
                                         alpha=0.45 if colour == INLIER else 0.5))
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
def _hist_pair(ax, before, after, label, unit="px", ylabel="joint pairs", *,
               names=("before: initial mirror", "after: refined mirror"), third=None):
    """Histograms of ``before`` (filled) and ``after`` (outline; ``None``: not refined),
    and optionally ``third = (values, name)`` (a dashed outline)."""
    series = [(before, BEFORE, names[0], dict(alpha=0.55)),
              (after, AFTER, names[1], dict(histtype="step", lw=1.8))]
    if after is None:
        after = before[:0]
        series = [(before, BEFORE, "initial estimate (not refined)", dict(alpha=0.55))]
    if third is not None:
        series.append((third[0], THIRD, third[1], dict(histtype="step", lw=1.4, ls="--")))
    finite = [v[np.isfinite(v)] for v, *_ in series]
    both = np.concatenate(finite)
    if both.size == 0:
        ax.text(0.5, 0.5, "no data", ha="center", transform=ax.transAxes)
        return
    top = float(np.percentile(both, 99))
    top = top if top > 0 else 1.0
    bins = np.linspace(0, top, 40)
    for vals, (_, colour, name, kw) in zip(finite, series):
        med = float(np.median(vals)) if vals.size else np.nan
        over = int(np.count_nonzero(vals > top))
        ax.hist(np.clip(vals, 0, top), bins=bins, color=colour, **kw,
                label=f"{name}: median {med:.2f} {unit}" + (f", {over} beyond" if over else ""))
        ax.axvline(med, color=colour, ls="--", lw=1)
    ax.set_xlabel(f"{label} ({unit})")
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=8)


def residuals(data):
    """Histograms of the inlier pairs' residuals with the initial and with the refined
    mirror, like with like: the epipolar distance to either epipole, and the reprojection
    error of each pair triangulated on its own with either mirror. The reprojection of
    the factor graph's joints is a third series: they are held to rigid bones and smooth
    motion, not fitted pair by pair, so their residual is larger by construction."""
    plt = _plt()
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(12, 4.8), layout="constrained")
    m = data.inlier
    refined = data.refined
    _hist_pair(a1, data.epi_before[m], data.epi_after[m] if refined else None,
               "epipolar distance")
    a1.set_title("Epipolar distance (how far a pair is from being\n"
                 "collinear with the epipole)")
    rb = data.reproj_before[m].ravel()
    ra = data.reproj_after[m].ravel()
    graph = data.reproj_graph[m].ravel() if refined else None
    _hist_pair(a2, rb, ra if refined else None, "reprojection error",
               ylabel="joint observations (2 per pair)",
               names=("before: initial mirror, pairs triangulated",
                      "after: refined mirror, pairs triangulated"),
               third=None if graph is None else
               (graph, "the graph's 3D joints (rigid bones, smooth motion)"))
    a2.set_title("Reprojection error (both views pooled): each pair triangulated\n"
                 "on its own with either mirror; dashed: the joints the run returns",
                 fontsize=11)
    fig.suptitle(f"Residuals of the {int(np.count_nonzero(m))} inlier pairs, 99th percentile "
                 "range (larger values counted in the last bin)"
                 + ("" if data.refined else " - the refinement did not run"),
                 fontsize=10)
    return fig


# --------------------------------------------------------------------------- (3)
def _frustum(depth: float, K: np.ndarray, size) -> np.ndarray:
    """``(5, 3)`` apex + 4 image corners at ``depth``, camera frame."""
    w, h = size
    corners = np.array([[0, 0, 1], [w, 0, 1], [w, h, 1], [0, h, 1]], float)
    rays = corners @ np.linalg.inv(K).T
    return np.vstack([np.zeros(3), depth * rays])


def pick_frames(data, count: int) -> np.ndarray:
    """``count`` frame indices spread over the run, each with the most 3D joints nearby."""
    ok = np.isfinite(data.joints_after).all(-1).sum(1)
    good = np.flatnonzero(ok >= max(1, 0.6 * ok.max())) if ok.max() > 0 else np.array([], int)
    if len(good) == 0:
        return good
    return np.unique(good[np.linspace(0, len(good) - 1, min(count, len(good))).round().astype(int)])


def mirror_gap(data) -> np.ndarray | None:
    """``(P,)`` median over frames of each person's distance in front of the mirror,
    ``d - n.X`` of the mean of each frame's 3D joints of that person (the report's unit;
    one person per entry of :func:`~mirrorgraph.skeletons.people_skeleton`'s layout), or
    ``None`` where no person has a 3D joint."""
    from ..skeletons import person_of

    X = data.joints_after
    tags = [person_of(n) for n in data.skeleton.joints]
    gaps = []
    for tag in dict.fromkeys(tags):
        cols = np.array([t == tag for t in tags])
        ok = np.isfinite(X[:, cols]).all(-1)
        rows = np.flatnonzero(ok.any(1))
        if len(rows):
            sums = np.where(ok[rows, :, None], X[rows][:, cols], 0.0).sum(1)
            means = sums / ok[rows].sum(1, keepdims=True)
            gaps.append(float(np.median(data.distance - means @ data.normal)))
    return np.array(gaps) if gaps else None


def _mirror_basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors in the mirror plane: ``up`` (closest to the camera's -y) and ``side``."""
    up = np.array([0.0, -1.0, 0.0]) - n * (-n[1])
    up = up / np.linalg.norm(up) if np.linalg.norm(up) > 1e-6 else np.array([1.0, 0, 0])
    return up, np.cross(n, up)


def _trace(n: np.ndarray, d: float, fixed: int, value: float, free: int, lo: float,
           hi: float) -> np.ndarray | None:
    """``(2, 3)`` ends of the mirror's trace on the plane ``X[fixed] = value``, the
    coordinate ``free`` running over ``[lo, hi]`` (``None`` if the plane is parallel)."""
    other = ({0, 1, 2} - {fixed, free}).pop()
    if abs(n[other]) < 1e-9:
        return None
    ends = np.zeros((2, 3))
    ends[:, fixed] = value
    ends[:, free] = (lo, hi)
    ends[:, other] = (d - n[fixed] * value - n[free] * ends[:, free]) / n[other]
    return ends


def scene3d(data, *, frames: int = 4):
    """Cameras, mirror and skeleton at a few frames, in two orthographic views.

    * from above: the real camera's ``x`` (right) and ``z`` (forward), the mirror
      as its trace at the subject's mean height;
    * along the mirror: the distance from the camera along the mirror normal
      against the height in the mirror plane, so the mirror is seen edge-on, as a
      line at its distance, and the gap between the person and the mirror (and
      the reflection as far behind it) reads as it is.

    Both views have equal scales on their two axes. Lengths in metres with a
    metric scale, else in units of the mirror distance (the figure says which).
    """
    plt = _plt()
    from matplotlib.lines import Line2D

    n, d = data.normal, data.distance
    metric = data.unit == "m"
    u = "m" if metric else "x mirror distance"
    F = _frustum(0.12 * d, data.K, data.image_size)
    Fv = geo.reflect_points(F, n, d)
    picks = pick_frames(data, frames)
    cmap = plt.get_cmap("viridis")
    colours = [cmap(k / max(len(picks) - 1, 1) * 0.85) for k in range(len(picks))]
    skel = [data.joints_after[t] for t in picks]
    refl = [geo.reflect_points(X, n, d) for X in skel]
    body = np.vstack([X[np.isfinite(X).all(1)] for X in skel]) if len(skel) else np.zeros((0, 3))
    if len(body) == 0:
        body = (d * n)[None]
    centre = body.mean(0)
    allpts = np.vstack([F, Fv, body] + [R[np.isfinite(R).all(1)] for R in refl])
    bones = data.skeleton.bone_index
    up, side_dir = _mirror_basis(n)

    fig, (top, edge) = plt.subplots(1, 2, figsize=(13.5, 6.4), layout="constrained")
    # projections (horizontal, vertical) of camera-frame points
    proj_top = lambda P: (np.asarray(P)[..., 0], np.asarray(P)[..., 2])  # noqa: E731
    proj_edge = lambda P: (np.asarray(P) @ n, np.asarray(P) @ up)       # noqa: E731
    for ax, proj in ((top, proj_top), (edge, proj_edge)):
        for Fr, colour in ((F, "k"), (Fv, "#9467bd")):
            x, y = proj(Fr)
            for i in range(1, 5):
                ax.plot([x[0], x[i]], [y[0], y[i]], color=colour, lw=1)
            ax.plot(x[0], y[0], "o", color=colour, ms=5)
        for X, R, colour in zip(skel, refl, colours):
            for P, ls, alpha, lw, gid in ((X, "-", 1.0, 1.8, "skeleton"),
                                          (R, ":", 0.7, 1.0, "reflection")):
                for a, b in bones:
                    if np.isfinite(P[[a, b]]).all():
                        x, y = proj(P[[a, b]])
                        ax.plot(x, y, color=colour, ls=ls, alpha=alpha, lw=lw, gid=gid)
        x, y = proj(allpts)
        lo, hi = np.array([x.min(), y.min()]), np.array([x.max(), y.max()])
        mid, half = (lo + hi) / 2, 0.56 * (hi - lo).max()
        ax.set_xlim(mid[0] - half, mid[0] + half)
        ax.set_ylim(mid[1] - half, mid[1] + half)
        ax.set_aspect("equal", adjustable="box")
        ax.grid(alpha=0.3)
        for P, text, colour in ((np.zeros(3), "camera", "k"), (Fv[0], "virtual camera", "#9467bd")):
            px, py = proj(P)
            right = px > mid[0]            # label towards the middle: it stays in the axes
            ax.annotate(text, (px, py), textcoords="offset points", xytext=(-6 if right else 6, -12),
                        ha="right" if right else "left", fontsize=8, color=colour)
    # the mirror: from above its trace at the subject's mean height, edge-on a line at d
    (x0, x1), (z0, z1) = top.get_xlim(), top.get_ylim()
    tr = _trace(n, d, 1, centre[1], 0, x0 - (x1 - x0), x1 + (x1 - x0))
    if tr is None:
        tr = _trace(n, d, 1, centre[1], 2, z0 - (z1 - z0), z1 + (z1 - z0))
    if tr is not None:
        top.plot(tr[:, 0], tr[:, 2], "-", color="#3182bd", lw=4, alpha=0.55,
                 solid_capstyle="butt", gid="mirror")
        top.set_xlim(x0, x1)
        top.set_ylim(z0, z1)
    edge.axvline(d, color="#3182bd", lw=4, alpha=0.55, gid="mirror")
    gaps = mirror_gap(data)
    gap = None if gaps is None else float(gaps.min())         # the nearest person's
    if gap is not None:
        # above the body's top, the label a few points higher still: off the skeleton
        # however small it is drawn (a far virtual camera widens the axes)
        h = float(np.max(body @ up))
        edge.annotate("", xy=(d, h), xytext=(d - gap, h),
                      arrowprops=dict(arrowstyle="<->", color="0.3", lw=1))
        edge.annotate(f"{gap:.2f} {'m' if metric else ''}".strip(), (d - gap / 2, h),
                      textcoords="offset points", xytext=(0, 4), ha="center", va="bottom",
                      fontsize=8, color="0.2", gid="gap")
    top.set_xlabel(f"x, right ({u})")
    top.set_ylabel(f"z, forward ({u})")
    top.set_title("From above (real camera's x and z); mirror at the subject's height",
                  fontsize=10)
    edge.set_xlabel(f"distance from the camera along the mirror normal ({u})")
    edge.set_ylabel(f"height along the mirror ({u})")
    edge.set_title("Along the mirror (seen edge-on): camera, person, mirror, reflection",
                   fontsize=10)

    handles = [Line2D([], [], color="k", lw=1.5, label="real camera"),
               Line2D([], [], color="#9467bd", lw=1.5, label="virtual (mirror) camera"),
               Line2D([], [], color="#3182bd", lw=4, alpha=0.55, label="mirror")]
    handles += [Line2D([], [], color=c, lw=2, label=f"skeleton, frame {int(data.frame_ids[t])}")
                for c, t in zip(colours, picks)]
    if len(picks):
        handles.append(Line2D([], [], color="0.4", ls=":", label="its reflection"))
    edge.legend(handles=handles, loc="upper left", fontsize=8, framealpha=0.9)
    if metric:
        where = f"unit: metres; the mirror is {d:.3f} m from the camera"
        if gaps is not None and len(gaps) == 1:
            where += f", the person about {gap:.2f} m in front of it"
        elif gaps is not None:
            where += (f", {len(gaps)} people {gaps.min():.2f}-{gaps.max():.2f} m in front "
                      "of it")
    else:
        where = ("unit: the camera-to-mirror distance (no metric scale: --subject-height "
                 "gives metres)")
        if gap is not None:
            where += f"; the person {gap:.2f} of it in front of the mirror"
    stage = "after refinement" if data.refined else "initial estimate, not refined"
    fig.suptitle(f"Cameras, mirror and skeleton (real camera frame, {stage})\n"
                 + where, fontsize=11)
    return fig


# --------------------------------------------------------------------------- (4)
def significant(value: float, digits: int) -> str:
    """``value`` with ``digits`` significant digits, trailing zeros kept (``0.150``,
    ``0.0020``, ``43.5``); integers of more digits are written whole."""
    value = float(value)
    if value == 0 or not np.isfinite(value):
        return f"{value:g}"
    decimals = max(digits - 1 - int(np.floor(np.log10(abs(value)))), 0)
    return f"{value:.{decimals}f}"


def _spread(values: np.ndarray, unit: str) -> str:
    """``"sd 0.42 cm (1.0 %)"``: standard deviation over frames, absolute (2 significant
    digits) and relative to the median."""
    fin = values[np.isfinite(values)]
    if fin.size == 0:
        return ""
    sd, med = float(np.std(fin)), float(np.median(fin))
    rel = f" ({100 * sd / med:.1f} %)" if med > 0 else ""
    return f"sd {significant(sd, 2)}{unit}{rel}"


def bone_lengths(data):
    """Every bone's length over time, before (initial normal) and after refinement.

    Lengths are in centimetres with a metric scale, else in units of the mirror
    distance; legends give the standard deviation over frames in that unit (two
    significant digits) and in % of the bone's median length, and the length the
    refinement estimated (three significant digits).
    """
    plt = _plt()
    B = len(data.bone_names)
    cols = 5 if B > 6 else max(B, 1)
    rows = max(1, int(np.ceil(B / cols)))
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.6 * rows + 0.9),
                             sharex=True, squeeze=False, layout="constrained")
    metric = data.unit == "m"
    scale = 100.0 if metric else 1.0
    unit = " cm" if metric else ""
    fr = data.frame_ids
    for k, ax in enumerate(axes.ravel()):
        if k >= B:
            ax.axis("off")
            continue
        b0, b1 = data.bones_before[:, k] * scale, data.bones_after[:, k] * scale
        fin = np.concatenate([b0[np.isfinite(b0)], b1[np.isfinite(b1)]])
        lo, hi = np.percentile(fin, [1, 99]) if fin.size else (0.0, 1.0)
        pad = 0.15 * (hi - lo) + 1e-6 * max(abs(hi), 1e-12)
        ylim = (lo - pad, hi + pad + 0.35 * (hi - lo))          # room for the legend

        def label(name: str, v: np.ndarray) -> str:
            if not np.isfinite(v).any():
                return name
            off = int(np.count_nonzero((v < ylim[0]) | (v > ylim[1])))
            return f"{name}: {_spread(v, unit)}" + (f", {off} off the axes" if off else "")
        if data.refined:
            ax.plot(fr, b0, ".", ms=2.5, color=BEFORE, label=label("before", b0))
            ax.plot(fr, b1, "-", lw=1.4, color=AFTER, label=label("after", b1))
        else:                   # before = after: one series
            ax.plot(fr, b0, ".", ms=2.5, color=BEFORE, label=label("initial", b0))
        ref = data.bone_reference.get(data.bone_names[k]) if data.bone_reference else None
        if ref is not None:
            ax.axhline(ref * scale, color="k", ls="--", lw=1,
                       label=f"refined length {significant(ref * scale, 3)}{unit}")
        ax.set_title(data.bone_names[k].replace("_", " "), fontsize=10)
        ax.legend(fontsize=7, loc="upper right")
        if fin.size:
            ax.set_ylim(*ylim)
        if k % cols == 0:
            ax.set_ylabel("length (cm)" if metric else "length (x mirror distance)")
        if k >= B - cols:
            ax.set_xlabel("frame")
    scale_note = ("" if metric else "; no metric scale: lengths in units of the mirror "
                  "distance (--subject-height gives metres)")
    what = ("before = each pair triangulated with the initial mirror, after = the 3D joints "
            "the run returns (the factor graph's; sd counts the frames off the axes too)"
            if data.refined else "the refinement did not run: the inlier pairs triangulated "
            "with the initial normal")
    fig.suptitle("Bone lengths over time: a rigid bone should be a flat line\n"
                 f"{what};\nsd = standard deviation over frames, and in % of the median"
                 + scale_note, fontsize=10)
    return fig


# --------------------------------------------------------------------------- (5)
#: An epipole ellipse longer than this many times its width is drawn in its own axes.
ELONGATED = 6.0


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
    vals, vecs = np.linalg.eigh(cov)
    ratio = float(np.sqrt(vals[1] / max(vals[0], 1e-300)))
    # an ellipse many times longer than wide is a sliver at equal scales: then draw it in
    # its own axes (along the major and the minor axis, px), each axis at its own scale
    along = ratio > ELONGATED
    if along:
        major, minor = vecs[:, 1], vecs[:, 0]
        to_axes = lambda P: np.column_stack([(P - e) @ major, (P - e) @ minor])  # noqa: E731
    else:
        to_axes = lambda P: P  # noqa: E731
    pts = [to_axes(e[None])]
    for k, ls in ((1, "-"), (2, "--"), (3, ":")):
        E = to_axes(e + _ellipse_points(cov, k))
        ax.plot(E[:, 0], E[:, 1], color=AFTER, ls=ls, lw=1.5,
                label=f"{k} sigma ({[39.3, 86.5, 98.9][k - 1]}% for a 2D Gaussian)")
        pts.append(E)
    mc = getattr(data, "marginal_epipole_cov", None)
    if mc is not None:
        E = to_axes(e + _ellipse_points(mc, 1))
        ax.plot(E[:, 0], E[:, 1], color="0.5", lw=1.0,
                label="1 sigma of the marginals alone (iid noise)")
        pts.append(E)
    ax.plot(*to_axes(e[None])[0], "*", ms=15, mfc="gold", mec="k",
            label=f"refined epipole ({e[0]:.1f}, {e[1]:.1f})")
    e0 = data.initial_epipole
    if e0 is not None:
        ax.plot(*to_axes(e0[None])[0], "o", ms=8, mfc="none", mec=BEFORE, mew=2,
                label=f"initial epipole ({e0[0]:.1f}, {e0[1]:.1f})")
        pts.append(to_axes(e0[None]))
    P = np.vstack(pts)
    lo, hi = P.min(0), P.max(0)
    if along:      # each axis its own scale, room for the legend above
        mid, half = (lo + hi) / 2, 0.6 * np.maximum(hi - lo, 1e-3)
        ax.set_xlim(mid[0] - half[0], mid[0] + half[0])
        ax.set_ylim(mid[1] - 1.7 * half[1], mid[1] + 1.9 * half[1])   # legend, text box
        ang = np.degrees(np.arctan2(major[1], major[0]))
        ax.set_xlabel(f"along the major axis (px; {ang:+.0f} deg from the image's x, y down)")
        ax.set_ylabel("along the minor axis (px)")
        ax.axhline(0, color="0.8", lw=0.8)
        ax.axvline(0, color="0.8", lw=0.8)
    else:
        mid, half = (lo + hi) / 2, 0.6 * max((hi - lo).max(), 1e-3)
        ax.set_xlim(mid[0] - half, mid[0] + half)
        ax.set_ylim(mid[1] + half, mid[1] - half)
        ax.set_aspect("equal")
        ax.set_xlabel("x (px)")
        ax.set_ylabel("y (px, down)")
    sd = np.sqrt(np.linalg.eigvalsh(cov))
    txt = [f"epipole std: {sd[1]:.1f} px (major), {sd[0]:.1f} px (minor)"]
    if data.rotation_std_deg is not None:
        txt.append(f"virtual camera rotation std: {data.rotation_std_deg:.3f} deg")
    if getattr(data, "marginal_rotation_std_deg", None) is not None:
        txt.append(f"  (marginals alone: {data.marginal_rotation_std_deg:.3f} deg)")
    if data.distance_std is not None:
        txt.append(f"mirror distance: {data.distance:.3f} +- {data.distance_std:.3f} {data.unit}")
    ax.text(0.02, 0.02, "\n".join(txt), transform=ax.transAxes, fontsize=9, va="bottom",
            bbox=dict(fc="w", ec="0.6"))
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    stretch = (f"\nthe ellipse is {ratio:.0f} times longer than wide: drawn in its own axes, "
               "the minor axis stretched" if along else "")
    ax.set_title("Uncertainty of the mirror normal, seen as the epipole\n"
                 "(the reported covariance of n: errors correlated over time and per joint "
                 "pair included)" + stretch, fontsize=10 if along else 11)
    return fig


def sensitivity(data):
    """What the calibration rests on: leave one joint pair or segment out, each segment's
    information, and the std predicted for other numbers of frames."""
    plt = _plt()
    sens = getattr(data, "sensitivity", None) or {}
    if not sens.get("leave_out"):
        fig, ax = plt.subplots(figsize=(7, 3), layout="constrained")
        ax.text(0.5, 0.5, "No sensitivity report: the refinement did not run.", ha="center",
                va="center", transform=ax.transAxes)
        ax.set_axis_off()
        return fig
    fig, axes = plt.subplots(2, 2, figsize=(13, 8.5), layout="constrained")
    std = data.rotation_std_deg
    pairs = sens["leave_out"]["joint_pairs"]
    ax = axes[0, 0]
    names = [" / ".join(p["joints"]).replace("left_", "L ").replace("right_", "R ")
             for p in pairs]
    ax.barh(names, [p["rotation_change_deg"] for p in pairs], color=AFTER)
    if std:
        ax.axvline(std, color="k", ls="--", lw=1, label=f"reported std {std:.3f} deg")
        ax.legend(fontsize=8, loc="lower right")
    ax.set_xlabel("rotation of the virtual camera, deg")
    ax.set_title("The mirror's move with one pair of joints left out", fontsize=10)
    ax.invert_yaxis()
    segs = sens["leave_out"]["segments"]
    labels = [f"{s['frames'][0]}-{s['frames'][1]}" for s in segs]
    ax = axes[0, 1]
    ax.bar(labels, [s["rotation_change_deg"] for s in segs], color=AFTER)
    if std:
        ax.axhline(std, color="k", ls="--", lw=1, label=f"reported std {std:.3f} deg")
        ax.legend(fontsize=8)
    ax.set_ylabel("rotation, deg")
    ax.set_title("... with one segment of frames left out", fontsize=10)
    ax.tick_params(axis="x", rotation=45, labelsize=8)
    ax = axes[1, 0]
    share = [100 * (s["information_share"] or 0.0) for s in segs]
    ax.bar(labels, share, color=BEFORE)
    ax.axhline(100.0 / max(len(segs), 1), color="k", ls=":", lw=1, label="equal shares")
    ax.set_ylim(0, 1.25 * max(max(share), 100.0 / max(len(segs), 1)))   # the legend above
    ax.set_ylabel("share of the normal's information, %")
    ax.set_xlabel("frames")
    ax.set_title("Which parts of the video carry the calibration", fontsize=10)
    ax.tick_params(axis="x", rotation=45, labelsize=8)
    ax.legend(fontsize=8)
    fn = sens["frames_needed"]
    ax = axes[1, 1]
    ax.loglog(fn["frames"], fn["rotation_std_deg"], "o-", color=AFTER, lw=2.2, zorder=2,
              label="reported model: 1/sqrt(frames) down to a floor\n"
                    "(errors shared across frames do not average out)")
    ax.loglog(fn["frames"], fn["iid_rotation_std_deg"], "s--", color="0.35", ms=4, lw=1.2,
              zorder=3, label="if every error were independent: 1/sqrt(frames), no floor")
    if fn.get("floor_rotation_std_deg"):
        ax.axhline(fn["floor_rotation_std_deg"], color=AFTER, ls=":", lw=1,
                   label=f"floor {fn['floor_rotation_std_deg']:.3f} deg")
    n_now = len(data.frame_ids)
    if std:
        ax.plot([n_now], [std], "*", ms=14, mfc="gold", mec="k",
                label=f"this video: {n_now} frames, {std:.3f} deg")
    ax.set_xlabel("frames of this kind of motion")
    ax.set_ylabel("rotation std, deg")
    ax.set_title("How many frames for a given accuracy", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.suptitle("What the mirror calibration rests on (linearised at the solution)", fontsize=12)
    return fig
