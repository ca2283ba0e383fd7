"""Figures of a calibrated rig (:class:`mirrorgraph.result.rig.RigCalibration`).

* :func:`rig_top_view` -- the rig seen from above: every camera (centre and viewing
  direction, its 1-sigma position uncertainty as a circle), every mirror (its
  trace at the subject's mean height), every person's path and, where the joints are
  at hand (not a rig drawn from its JSON), their skeletons at one frame;
* :func:`rig_residuals` -- per view the reprojection RMS and its observations, per
  camera the share of its keypoints the solve kept; per person where the rig holds
  several (``calibrate-rig --people all``: ``refinement["people"]["views"]``).

People are named as :mod:`mirrorgraph.io.people_motion` names them (``P0``, ``P1``,
...; ``P0`` is the subject the scale is measured on) and keep one colour throughout.
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

__all__ = ["people_tracks", "rig_top_view", "rig_residuals", "people_view_table",
           "write_rig_report"]

CAMERA = "#1f77b4"
MIRROR = "#7f7f7f"
PERSON = "#ff7f0e"
#: One colour a person, ``P0`` first (the subject's :data:`PERSON`); no camera blue or
#: mirror grey; repeated past ten people.
PEOPLE = (PERSON, "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#bcbd22",
          "#17becf", "#393b79", "#637939")


def person_colour(p: int) -> str:
    """The colour of person ``p`` in every rig figure."""
    return PEOPLE[p % len(PEOPLE)]


def _mean(X: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """``(T, 3)`` per-frame mean of the valid joints ``(T, J, 3)`` (NaN where none)."""
    X = np.where(ok[..., None], X, np.nan)
    with warnings.catch_warnings():            # frames without any joint
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmean(X, axis=1)


def people_tracks(calib) -> tuple[np.ndarray, np.ndarray]:
    """Every person's joints and validity, ``(P, T, J, 3)`` and ``(P, T, J)``: the rig's
    ``people_joints3d`` where it holds several people, else its one ``joints3d`` as
    ``P = 1`` (``J = 1`` for a rig read from its JSON: the paths)."""
    if calib.people_joints3d is not None:
        return (np.asarray(calib.people_joints3d, float),
                np.asarray(calib.people_valid, bool))
    return np.asarray(calib.joints3d, float)[None], np.asarray(calib.valid, bool)[None]


def _skeleton_frame(X: np.ndarray, ok: np.ndarray) -> int | None:
    """The frame row where the most people show at least half of their joints (then the
    most joints), or ``None`` where no one does."""
    seen = ok & np.isfinite(X).all(-1)                                   # (P, T, J)
    J = seen.shape[2]
    whole = (seen.sum(2) >= 0.5 * J).sum(0)                              # (T,)
    if not whole.any():
        return None
    score = whole * (J * len(seen) + 1) + seen.sum((0, 2))
    return int(np.argmax(score))


def rig_top_view(calib):
    """Top view of cameras, mirrors and every person's path (a matplotlib Figure); the
    skeletons at one frame where the joints are at hand."""
    plt = require_matplotlib()
    fig, ax = plt.subplots(figsize=(8, 7), layout="constrained")
    X, okj = people_tracks(calib)
    P = len(X)
    paths = [_mean(X[p], okj[p]) for p in range(P)]
    oks = [np.isfinite(q).all(1) for q in paths]
    seen_path = np.vstack([q[o] for q, o in zip(paths, oks)]) if P else np.zeros((0, 3))
    pts = [c.pose[:3, 3] for c in calib.cameras] + list(seen_path)
    cam_labels = []
    circles = False
    Pts = np.asarray(pts)
    span = float(np.ptp(Pts[:, [0, 2]], axis=0).max()) or 1.0
    names = [f"P{p}" for p in range(P)]
    one = P == 1
    frame = None
    bones = np.zeros((0, 2), int)
    if calib.skeleton and X.shape[2] > 1:     # the joints at hand: skeletons at one frame
        from ..errors import InputError
        from ..skeletons import skeleton_by_name
        try:
            sk = skeleton_by_name(calib.skeleton)
        except InputError:
            sk = None
        if sk is not None and sk.num_joints == X.shape[2]:
            frame = _skeleton_frame(X, okj)
            bones = sk.bone_index
    for p, (path, ok) in enumerate(zip(paths, oks)):
        if ok.any():
            ax.plot(path[ok, 0], path[ok, 2], "-", color=person_colour(p), lw=1,
                    alpha=0.8 if frame is None else 0.45, gid=f"path {names[p]}")
            if not one:                       # the name at the path's end
                end = path[ok][-1]
                ax.plot([end[0]], [end[2]], "o", color=person_colour(p), ms=3)
                ax.annotate(names[p], (end[0], end[2]), textcoords="offset points",
                            xytext=(4, 4), fontsize=8, color=person_colour(p),
                            fontweight="bold")
    if frame is not None:
        for p in range(P):
            S = np.where(okj[p, frame, :, None], X[p, frame], np.nan)
            for a, b in bones:
                if np.isfinite(S[[a, b]]).all():
                    ax.plot(S[[a, b], 0], S[[a, b], 2], "-", color=person_colour(p), lw=2.2,
                            solid_capstyle="round", gid=f"skeleton {names[p]}")
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
    sub, sub_ok = paths[0], oks[0]           # the mirrors at the subject's height
    y0 = float(np.nanmean(sub[sub_ok, 1])) if sub_ok.any() else 0.0
    centre = (np.nanmean(sub[sub_ok][:, [0, 2]], axis=0) if sub_ok.any()
              else Pts[:, [0, 2]].mean(0))
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
    Q = np.vstack([Pts[:, [0, 2]]] + [a[None] for a in anchors])
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
    for p in range(P):
        if oks[p].any():
            label = ("subject (mean of the joints)" if one else
                     f"{names[p]}" + (" (the subject)" if p == 0 else ""))
            handles.append(Line2D([], [], color=person_colour(p), lw=1, label=label))
    if frame is not None:
        at = f"{'skeleton' if one else 'skeletons'} at frame {int(calib.frame_ids[frame])}"
        handles.append(Line2D([], [], color="0.25", lw=2.2, label=at))
    unit = "m" if calib.scale == "subject_height" else "subject heights"
    ax.set_xlabel(f"x ({unit}, world = camera {calib.cameras[0].name})")
    ax.set_ylabel(f"z ({unit})")
    scale = ("unit: metres" if calib.scale == "subject_height" else
             "unit: subject heights (no metric scale:\nsubject_height or --subject-height "
             "gives metres)")
    parts = "cameras (arrow: viewing direction" + (
        ", circle: 1-sigma position)" if circles else ")")
    who = "subject" if one else f"{P} people (paths: mean of the joints)"
    parts += f", mirrors, {who}" if calib.mirrors else f", {who}"
    if frame is not None:
        parts += f";\n{at}"
    ax.set_title(f"Rig from above: {parts};\n{scale}", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(handles=handles, loc="best", fontsize=8)
    return fig


def people_view_table(calib) -> list[dict[str, dict]]:
    """Per person, view name -> ``{"rms_px", "observations", "offered"}``: the rig's
    ``refinement["people"]["views"]`` where it holds several people, else its one
    ``refinement["views"]`` (every person pooled, which is the one person's)."""
    people = (calib.refinement or {}).get("people") or {}
    table = people.get("views")
    if people.get("mode") == "all" and isinstance(table, list) and table:
        return [dict(t or {}) for t in table]
    return [dict((calib.refinement or {}).get("views") or {})]


def rig_residuals(calib):
    """Per view the reprojection RMS and its observations, per camera the share of its
    keypoints the solve kept; one bar a person (a matplotlib Figure)."""
    from ..rigs.failure import MIN_FIT_SHARE, fit_shares

    plt = require_matplotlib()
    table = people_view_table(calib)
    P = len(table)
    views = list(dict.fromkeys(v for t in table for v in t))
    cams = [c.name for c in calib.cameras]
    width = 0.8 / P
    fig, (ax, keep) = plt.subplots(
        1, 2, figsize=(float(np.clip(0.3 * P * (len(views) + len(cams)) + 5.0, 8.5, 16.0)), 4.4),
        layout="constrained", width_ratios=[max(len(views), 1), max(len(cams), 1)])
    for p, t in enumerate(table):
        x = np.arange(len(views)) + (p - (P - 1) / 2) * width
        rms = [t[v]["rms_px"] if v in t else np.nan for v in views]
        colour = [person_colour(p) if P > 1 else CAMERA for _ in views]
        if P == 1:                                     # one person: grey through a mirror
            colour = [CAMERA if "/" not in v else MIRROR for v in views]
        bars = ax.bar(x, rms, width=width, color=colour,
                      label=f"P{p}" if P > 1 else None, gid=f"rms P{p}")
        for bar, v in zip(bars, views):
            if v in t:
                ax.text(bar.get_x() + bar.get_width() / 2, bar.get_height(),
                        f"{t[v]['observations']}", ha="center", va="bottom",
                        fontsize=7 if P > 1 else 8, rotation=90 if P > 2 else 0)
        shares = fit_shares(cams, list(t), [t[v]["observations"] for v in t],
                            [t[v]["offered"] for v in t])
        share = [100.0 * k / n if n else np.nan for k, n in (shares[c] for c in cams)]
        xc = np.arange(len(cams)) + (p - (P - 1) / 2) * width
        kb = keep.bar(xc, share, width=width, color=person_colour(p) if P > 1 else CAMERA,
                      gid=f"keep P{p}")
        for bar, k in zip(kb, share):
            if np.isfinite(k):
                keep.text(bar.get_x() + bar.get_width() / 2, bar.get_height(), f"{k:.0f}",
                          ha="center", va="bottom", fontsize=7 if P > 1 else 8,
                          rotation=90 if P > 2 else 0)
    ax.set_xticks(range(len(views)), views, rotation=30, ha="right")
    ax.set_ylabel("reprojection RMS (px)")
    ax.set_title("Residual per view\n(number: observations"
                 + ("; grey: through a mirror)" if P == 1 else ")"), fontsize=10)
    ax.grid(axis="y", alpha=0.3)
    ax.margins(y=0.15)
    keep.axhline(100 * MIN_FIT_SHARE, color="0.3", ls="--", lw=1)
    keep.set_xticks(range(len(cams)), cams, rotation=30, ha="right")
    keep.set_ylim(0, 112)
    keep.set_ylabel("keypoints kept (% of those offered)")
    keep.set_title("Keypoints kept per camera\n(direct and through mirrors;\ndashed: a "
                   "camera fails under it)", fontsize=10)
    keep.grid(axis="y", alpha=0.3)
    if P > 1:
        ax.legend(title="person", fontsize=8, title_fontsize=8, loc="lower right",
                  framealpha=0.9)
        mirrored = "; views through a mirror: the subject's reflection alone" if any(
            "/" in v for v in views) else ""
        fig.suptitle(f"Every person's residuals: {P} people (P0 the subject{mirrored})",
                     fontsize=10)
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
