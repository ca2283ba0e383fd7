"""Figures of a calibrated rig (:class:`mirrorgraph.rigs.RigCalibration`).

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

from . import require_matplotlib

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
    P = np.asarray(pts)
    span = float(np.ptp(P[:, [0, 2]], axis=0).max()) or 1.0
    if ok.any():
        ax.plot(path[ok, 0], path[ok, 2], "-", color=PERSON, lw=1, alpha=0.8,
                label="subject (mean of the joints)")
    for c in calib.cameras:
        x, _, z = c.pose[:3, 3]
        fwd = c.pose[:3, 2]
        ax.plot([x], [z], "o", color=CAMERA, ms=7)
        ax.annotate("", xy=(x + 0.12 * span * fwd[0], z + 0.12 * span * fwd[2]), xytext=(x, z),
                    arrowprops=dict(arrowstyle="->", color=CAMERA, lw=1.5))
        if np.isfinite(c.position_std) and c.position_std > 0:
            ax.add_patch(plt.Circle((x, z), c.position_std, fill=False, ec=CAMERA, lw=0.8, ls=":"))
        ax.text(x, z, f"  {c.name}\n  rot std {c.rotation_std_deg:.2f} deg", fontsize=8,
                color=CAMERA, va="top")
    y0 = float(np.nanmean(path[ok, 1])) if ok.any() else 0.0
    centre = np.nanmean(path[ok][:, [0, 2]], axis=0) if ok.any() else P[:, [0, 2]].mean(0)
    anchors = []
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
        ax.text(*anchor, f"  {m.name}\n  rot std {m.rotation_std_deg:.3f} deg", fontsize=8,
                color="k")
        anchors.append(anchor)
    Q = np.vstack([P[:, [0, 2]]] + [a[None] for a in anchors])
    lo, hi = Q.min(0) - 0.25 * span, Q.max(0) + 0.25 * span
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    unit = "m" if calib.scale == "subject_height" else "subject heights"
    ax.set_xlabel(f"x ({unit}, world = camera {calib.cameras[0].name})")
    ax.set_ylabel(f"z ({unit})")
    ax.set_title("Rig from above: cameras (arrow: viewing direction, dotted: 1-sigma position), "
                 "mirrors, subject", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
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


def write_rig_report(calib, out_dir) -> list[Path]:
    """Write the rig's figures as PNG files into ``out_dir``; returns their paths."""
    plt = require_matplotlib()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, make in (("rig_top_view.png", rig_top_view), ("rig_residuals.png", rig_residuals)):
        fig = make(calib)
        p = out / name
        fig.savefig(p, dpi=110)
        plt.close(fig)
        paths.append(p)
    return paths
