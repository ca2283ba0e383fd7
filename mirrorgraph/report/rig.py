"""Figures of a calibrated rig (:class:`mirrorgraph.result.rig.RigCalibration`).

* :func:`rig_top_view` -- the rig seen from above: every camera (centre and viewing
  direction, its 1-sigma position uncertainty as a circle), every mirror (its
  trace at the subject's mean height), the subject's path;
* :func:`rig_residuals` -- reprojection RMS and number of observations per view.

"From above" is along the world ``y`` axis (the first camera's "down"): exact for a
level first camera, a slanted top view otherwise. Lengths in the rig's unit.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from ..progress import Progress
from .backend import require_matplotlib
from .figures import significant

__all__ = ["rig_top_view", "rig_residuals", "write_rig_report"]

CAMERA = "#1f77b4"
MIRROR = "#7f7f7f"
PERSON = "#ff7f0e"


def _path(calib) -> np.ndarray:
    """``(T, 3)`` per-frame mean of the estimated joints (NaN where none)."""
    X = np.where(calib.valid[..., None], calib.joints3d, np.nan)
    with warnings.catch_warnings():            # frames without any joint
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(X, axis=1)


def rig_top_view(calib):
    """Top view of cameras, mirrors and the subject's path (a matplotlib Figure)."""
    plt = require_matplotlib()
    fig, ax = plt.subplots(figsize=(8, 7), layout="constrained")
    path = _path(calib)
    ok = np.isfinite(path).all(1)
    pts = [c.pose[:3, 3] for c in calib.cameras] + list(path[ok])
    cam_labels = []
    circles = False
    P = np.asarray(pts)
    span = float(np.ptp(P[:, [0, 2]], axis=0).max()) or 1.0
    if ok.any():
        ax.plot(path[ok, 0], path[ok, 2], "-", color=PERSON, lw=1, alpha=0.8,
                label="subject (mean of the joints)")
    for k, c in enumerate(calib.cameras):
        x, _, z = c.pose[:3, 3]
        fwd = c.pose[:3, 2]
        ax.plot([x], [z], "o", color=CAMERA, ms=7)
        ax.annotate("", xy=(x + 0.12 * span * fwd[0], z + 0.12 * span * fwd[2]), xytext=(x, z),
                    arrowprops=dict(arrowstyle="->", color=CAMERA, lw=1.5))
        has_std = bool(np.isfinite(c.position_std) and c.position_std > 0)
        # a circle where one can see it (wider than the camera's dot), else the words only
        if has_std and c.position_std > 0.03 * span:
            ax.add_patch(plt.Circle((x, z), c.position_std, fill=False, ec=CAMERA, lw=1.0,
                                    alpha=0.7))
            circles = True
        # the first camera is the world frame: fixed, no uncertainty of its own
        unit = "m" if calib.scale == "subject_height" else "subject heights"
        what = ("world frame (fixed)" if k == 0 else f"rot std {c.rotation_std_deg:.2f} deg"
                + (f"\npos std {significant(c.position_std, 2)} {unit}" if has_std else ""))
        cam_labels.append((np.array([x, z]), f"{c.name}\n{what}"))
    y0 = float(np.nanmean(path[ok, 1])) if ok.any() else 0.0
    centre = np.nanmean(path[ok][:, [0, 2]], axis=0) if ok.any() else P[:, [0, 2]].mean(0)
    anchors, labels = [], []
    for m in calib.mirrors:
        n, d = np.asarray(m.normal, float), float(m.distance)
        nh = np.array([n[0], n[2]])
        if np.linalg.norm(nh) < 1e-9:
            continue                            # a horizontal mirror has no trace here
        # trace at the subject's height: nh . (x, z) = d - n_y y0; anchor nearest the subject
        c0 = d - n[1] * y0
        anchor = centre + (c0 - nh @ centre) / (nh @ nh) * nh
        direction = np.array([-nh[1], nh[0]]) / np.linalg.norm(nh)
        t = np.linspace(-3 * span, 3 * span, 2)
        seg = anchor[None, :] + t[:, None] * direction[None, :]
        ax.plot(seg[:, 0], seg[:, 1], "-", color=MIRROR, lw=4, alpha=0.6)
        ax.annotate("", xy=anchor + 0.1 * span * nh / np.linalg.norm(nh), xytext=anchor,
                    arrowprops=dict(arrowstyle="->", color=MIRROR))
        anchors.append(anchor)
        labels.append((anchor, f"{m.name}\nrot std {m.rotation_std_deg:.3f} deg"))
    Q = np.vstack([P[:, [0, 2]]] + [a[None] for a in anchors])
    lo, hi = Q.min(0) - 0.25 * span, Q.max(0) + 0.25 * span
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ratio = (hi[0] - lo[0]) / max(hi[1] - lo[1], 1e-9)     # a figure of the data's shape
    fig.set_size_inches(float(np.clip(6.2 * ratio + 2.2, 5.5, 12.0)), 7.0)
    mid_x = (lo[0] + hi[0]) / 2
    for (anchor, text), colour in ([(a, "k") for a in labels]
                                   + [(a, CAMERA) for a in cam_labels]):
        right = anchor[0] > mid_x     # on the side of the anchor that stays in the axes
        ax.annotate(text, anchor, textcoords="offset points", xytext=(-6 if right else 6, -4),
                    ha="right" if right else "left", va="top", fontsize=8, color=colour)
    from matplotlib.lines import Line2D  # the plot extra: lazy, as in require_matplotlib
    handles = [Line2D([], [], color=CAMERA, marker="o", ls="none", label="camera (arrow: view)")]
    if labels:
        handles.append(Line2D([], [], color=MIRROR, lw=4, alpha=0.6,
                              label="mirror (at the subject's height)"))
    if ok.any():
        handles.append(Line2D([], [], color=PERSON, lw=1, label="subject (mean of the joints)"))
    unit = "m" if calib.scale == "subject_height" else "subject heights"
    ax.set_xlabel(f"x ({unit}, world = camera {calib.cameras[0].name})")
    ax.set_ylabel(f"z ({unit})")
    scale = ("unit: metres" if calib.scale == "subject_height" else
             "unit: subject heights (no metric scale:\nsubject_height or --subject-height "
             "gives metres)")
    parts = "cameras (arrow: viewing direction" + (
        ", circle: 1-sigma position)" if circles else ")")
    parts += ", mirrors, subject" if calib.mirrors else ", subject"
    ax.set_title(f"Rig from above: {parts};\n{scale}", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(handles=handles, loc="best", fontsize=8)
    return fig


def rig_residuals(calib):
    """Reprojection RMS and observations per view (a matplotlib Figure)."""
    plt = require_matplotlib()
    views = calib.refinement.get("views", {})
    names = list(views)
    rms = [views[v]["rms_px"] for v in names]
    count = [views[v]["observations"] for v in names]
    fig, ax = plt.subplots(figsize=(max(5, 1.1 * len(names) + 2), 4), layout="constrained")
    bars = ax.bar(range(len(names)), rms, color=[CAMERA if "/" not in v else MIRROR for v in names])
    for b, n in zip(bars, count):
        ax.text(b.get_x() + b.get_width() / 2, b.get_height(), f"{n}", ha="center", va="bottom",
                fontsize=8)
    ax.set_xticks(range(len(names)), names, rotation=30, ha="right")
    ax.set_ylabel("reprojection RMS (px)")
    ax.set_title("Residual per view (number: observations; grey: through a mirror)",
                 fontsize=10)
    ax.grid(axis="y", alpha=0.3)
    return fig


def write_rig_report(calib, out_dir, *, progress_bar: bool = True) -> list[Path]:
    """Write the rig's figures as PNG files into ``out_dir``; returns their paths.

    Args:
        calib (mirrorgraph.result.rig.RigCalibration): the calibrated rig.
        out_dir (str | os.PathLike): folder to write into (created if missing).
        progress_bar: draw a progress bar on stderr (only on a terminal).
    """
    plt = require_matplotlib()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    makers = (("rig_top_view.png", rig_top_view), ("rig_residuals.png", rig_residuals))
    with Progress("drawing the report", total=len(makers), enabled=progress_bar) as bar:
        for name, make in makers:
            fig = make(calib)
            p = out / name
            fig.savefig(p, dpi=110)
            plt.close(fig)
            paths.append(p)
            bar.update(info=name)
    return paths
