"""Overlays on the video: joints, their reflections and the epipolar lines (OpenCV).

The keypoints of a run are undistorted; the video is not. Points and lines are
distorted back with the camera's coefficients before drawing, so an epipolar
line of a camera with distortion is drawn as the curve it is in the image.

Frame ``k`` of the video carries the keypoints whose frame id is ``k``; video
frames without keypoints are written unchanged.
"""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from .. import geometry as geo
from ..errors import InputError
from ..io.video_out import open_video_writer
from ..keypoints import DEFAULT_MIN_CONFIDENCE
from ..progress import Progress

# BGR, the report's palette
REAL = (180, 119, 31)
MIRROR = (14, 127, 255)
INLIER = (44, 160, 44)
OUTLIER = (40, 39, 214)
EPIPOLE = (0, 215, 255)


def distort(intr, pts: np.ndarray) -> np.ndarray:
    """Undistorted (pinhole) pixels ``(N, 2)`` -> pixels of the real lens."""
    pts = np.asarray(pts, float).reshape(-1, 2)
    if not intr.has_distortion or len(pts) == 0:
        return pts
    rays = np.hstack([pts, np.ones((len(pts), 1))]) @ np.linalg.inv(intr.K).T
    out, _ = cv2.projectPoints(rays.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), intr.K,
                               np.asarray(intr.dist, float))
    return out.reshape(-1, 2)


def _line_in_image(e_h: np.ndarray, u: np.ndarray, size) -> np.ndarray | None:
    """Two end points of the line through ``e`` (homogeneous) and ``u`` within the image."""
    w, h = size
    line = np.cross(e_h, np.array([u[0], u[1], 1.0]))
    a, b, c = line
    hits = []
    for x in (0.0, float(w)):
        if abs(b) > 1e-12:
            y = -(a * x + c) / b
            if -1 <= y <= h + 1:
                hits.append((x, y))
    for y in (0.0, float(h)):
        if abs(a) > 1e-12:
            x = -(b * y + c) / a
            if -1 <= x <= w + 1:
                hits.append((x, y))
    if len(hits) < 2:
        return None
    hits = np.array(hits)
    i, j = np.unravel_index(np.argmax(np.linalg.norm(hits[:, None] - hits[None], axis=-1)),
                            (len(hits), len(hits)))
    return hits[[i, j]]


def _ipt(p) -> tuple[int, int]:
    return int(round(float(p[0]))), int(round(float(p[1])))


def draw_overlay(frame: np.ndarray, real: np.ndarray, mirror: np.ndarray, inlier: np.ndarray,
                 valid: np.ndarray, run, *, label: str = "",
                 legend_points: np.ndarray | None = None) -> np.ndarray:
    """Draw one frame's pairs on a BGR image (in place; also returned).

    Args:
        frame: ``(H, W, 3)`` uint8 BGR.
        real, mirror: ``(J, 2)`` undistorted pixels of the joints and reflections.
        inlier, valid: ``(J,)`` bool: pair kept by the run / pair usable.
        run: the :class:`~mirrorgraph.pipelines.mirror.CalibrationRun` (intrinsics, skeleton).
        label: text written first in the legend (drawn in the corner that hides fewest
            of ``legend_points``, :func:`legend_corner`).
        legend_points: ``(N, 2)`` px the legend avoids (default: this frame's joints and
            reflections; a video passes every frame's, :func:`joints_everywhere`, so that
            its legend stays in one corner).
    """
    intr = run.calibration.intrinsics
    size = (frame.shape[1], frame.shape[0])
    scale = max(1, round(min(size) / 540))
    e_h = geo.epipole_from_normal(intr.K, run.calibration.normal)
    for j in np.flatnonzero(valid):
        ends = _line_in_image(e_h, real[j], size)
        if ends is None:
            continue
        s = np.linspace(0, 1, 48)[:, None]
        pts = distort(intr, ends[0] * (1 - s) + ends[1] * s)
        cv2.polylines(frame, [np.round(pts).astype(np.int32).reshape(-1, 1, 2)], False,
                      INLIER if inlier[j] else OUTLIER, scale, cv2.LINE_AA)
    for P, colour in ((real, REAL), (mirror, MIRROR)):
        Q = np.full_like(P, np.nan)
        ok = np.isfinite(P).all(1)
        Q[ok] = distort(intr, P[ok])
        for a, b in run.paired.skeleton.bone_index:
            if ok[a] and ok[b]:
                cv2.line(frame, _ipt(Q[a]), _ipt(Q[b]), colour, 2 * scale, cv2.LINE_AA)
        for j in np.flatnonzero(ok):
            cv2.circle(frame, _ipt(Q[j]), 3 * scale, colour, -1, cv2.LINE_AA)
    e_px = geo.epipole_pixels(e_h)
    if e_px is not None and 0 <= e_px[0] < size[0] and 0 <= e_px[1] < size[1]:
        cv2.drawMarker(frame, _ipt(distort(intr, e_px[None])[0]), EPIPOLE, cv2.MARKER_STAR,
                       20 * scale, 2 * scale)
    _legend(frame, label, scale,
            np.vstack([real, mirror]) if legend_points is None else legend_points)
    return frame


def joints_everywhere(run) -> np.ndarray:
    """``(N, 2)`` px: the joints and reflections of every frame of a run (undistorted)."""
    p = run.paired
    return np.concatenate([p.real[..., :2].reshape(-1, 2), p.mirror[..., :2].reshape(-1, 2)])


def legend_corner(size: tuple[int, int], box: tuple[int, int], points: np.ndarray
                  ) -> tuple[int, int]:
    """Top-left pixel of a ``box = (w, h)`` legend in the image corner (of ``size =
    (W, H)``) that covers fewest of ``points`` ``(N, 2)`` (NaN ignored), widened by a
    margin so that a skeleton's edge is not hidden; ties go to the top-left."""
    W, H = size
    w, h = box
    P = np.asarray(points, float).reshape(-1, 2)
    P = P[np.isfinite(P).all(1)]
    m = 0.05 * min(W, H)
    corners = [(4, 4), (W - w - 4, 4), (4, H - h - 4), (W - w - 4, H - h - 4)]
    counts = [int(np.count_nonzero((P[:, 0] > x - m) & (P[:, 0] < x + w + m)
                                   & (P[:, 1] > y - m) & (P[:, 1] < y + h + m)))
              for x, y in corners]
    return corners[int(np.argmin(counts))]


def _legend(frame: np.ndarray, label: str, scale: int, points: np.ndarray) -> None:
    """The legend in the corner where it hides fewest joints (:func:`legend_corner`)."""
    rows = [(label, (255, 255, 255)), ("person", REAL), ("reflection", MIRROR),
            ("epipolar line, inlier", INLIER), ("epipolar line, outlier", OUTLIER)]
    rows = [r for r in rows if r[0]]
    fs, th, dy = 0.5 * scale, max(1, scale), int(22 * scale)
    w, h = int(230 * scale) - 4, 6 + dy * len(rows)
    x0, y0 = legend_corner((frame.shape[1], frame.shape[0]), (w, h), points)
    cv2.rectangle(frame, (x0, y0), (x0 + w, y0 + h), (0, 0, 0), -1)
    for i, (text, colour) in enumerate(rows):
        cv2.putText(frame, text, (x0 + 6, int(y0 + dy * (i + 0.8))), cv2.FONT_HERSHEY_SIMPLEX,
                    fs, colour, th, cv2.LINE_AA)


def _open(video) -> tuple[cv2.VideoCapture, int, tuple[int, int], float]:
    cap = cv2.VideoCapture(str(video))
    if not cap.isOpened():
        raise InputError("cannot be read as a video (OpenCV)", source=str(video), field="video")
    count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    size = (int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
    fps = float(cap.get(cv2.CAP_PROP_FPS)) or 30.0
    return cap, count, size, fps


def check_size(run, size, video) -> None:
    want = run.calibration.intrinsics.image_size or run.paired.image_size
    if want is not None and tuple(want) != tuple(size):
        raise InputError(f"is {size[0]}x{size[1]} but the keypoints and intrinsics are "
                         f"{want[0]}x{want[1]}: is it the video they come from?",
                         source=str(video), field="video")


def _frame_rows(run) -> dict[int, int]:
    return {int(f): i for i, f in enumerate(run.paired.frame_ids)}


def _pairs(run, row: int, data=None) -> tuple[np.ndarray, ...]:
    p = run.paired
    conf = run.calibration.input.get("min_confidence", DEFAULT_MIN_CONFIDENCE)
    valid = p.valid(conf)[row]
    mask = np.zeros_like(valid)
    mask[np.asarray(run.joints, int)] = True
    valid &= mask
    real = np.where((p.real[row, :, 2] > conf)[:, None], p.real[row, :, :2], np.nan)
    mirror = np.where((p.mirror[row, :, 2] > conf)[:, None], p.mirror[row, :, :2], np.nan)
    return real, mirror, np.asarray(run.inliers, bool)[row], valid


def overlay_samples(video: str | os.PathLike, run, out_dir: str | os.PathLike, *,
                    count: int = 6, data=None, progress_bar: bool = True) -> dict[str, Path]:
    """Draw the overlay on ``count`` frames spread over the video; PNG per frame.

    Seeking a compressed video decodes from the previous key frame, so each
    sample can take seconds: a progress bar is drawn on stderr when it is a
    terminal and ``progress_bar`` is set.

    Returns:
        ``overlay_<frame>`` -> path of each PNG written.
    """
    cap, nframes, size, _fps = _open(video)
    try:
        check_size(run, size, video)
        rows = _frame_rows(run)
        p = run.paired
        have = [f for f, r in rows.items() if p.valid(0.0)[r].any() and (nframes <= 0 or f < nframes)]
        if not have:
            raise InputError("no frame of the video has keypoints (frame ids "
                             f"{int(p.frame_ids[0])}..{int(p.frame_ids[-1])}, video of "
                             f"{nframes} frames)", source=str(video), field="video")
        have = np.array(sorted(have))
        everywhere = joints_everywhere(run)
        picks = np.unique(have[np.linspace(0, len(have) - 1, min(count, len(have)))
                               .round().astype(int)])
        out = {}
        with Progress("sampling video frames", total=len(picks), enabled=progress_bar) as bar:
            for f in picks:
                cap.set(cv2.CAP_PROP_POS_FRAMES, int(f))
                ok, img = cap.read()
                bar.update(info=f"frame {int(f)}")
                if not ok:
                    continue
                real, mirror, inl, valid = _pairs(run, rows[int(f)])
                draw_overlay(img, real, mirror, inl, valid, run, label=f"frame {int(f)}",
                             legend_points=everywhere)
                path = Path(out_dir) / f"overlay_{int(f):06d}.png"
                cv2.imwrite(str(path), img)
                out[f"overlay_{int(f):06d}"] = path
        return out
    finally:
        cap.release()


def render_video(video: str | os.PathLike, run, out: str | os.PathLike, *, data=None,
                 progress_bar: bool = True, warn=None) -> Path:
    """Write the whole video with the overlay to ``out``: H.264 in ``.mp4`` where the
    OpenCV build has it (browsers play it), else ``mp4v`` with a note to ``warn``; VP9 in
    ``.webm`` (:func:`mirrorgraph.io.video_out.open_video_writer`).

    Frames are written as read (same size and frame rate); a progress bar is
    drawn on stderr when it is a terminal. The file appears only when complete.
    ``warn(line)`` receives what a browser will not play (default: ignored).
    """
    cap, nframes, size, fps = _open(video)
    out = Path(out)
    tmp = out.with_name(f".{out.stem}.part{out.suffix}")
    writer = None
    try:
        check_size(run, size, video)
        rows = _frame_rows(run)
        everywhere = joints_everywhere(run)
        writer, _, note = open_video_writer(tmp, fps, size)
        if note is not None and warn is not None:
            warn(note.replace(tmp.name, out.name))
        with Progress("rendering overlay", total=nframes if nframes > 0 else None,
                      enabled=progress_bar) as bar:
            k = 0
            while True:
                ok, img = cap.read()
                if not ok:
                    break
                if k in rows:
                    real, mirror, inl, valid = _pairs(run, rows[k])
                    draw_overlay(img, real, mirror, inl, valid, run, label=f"frame {k}",
                                 legend_points=everywhere)
                writer.write(img)
                k += 1
                bar.update()
        writer.release()
        writer = None
        os.replace(tmp, out)
        return out
    finally:
        cap.release()
        if writer is not None:
            writer.release()
        if tmp.exists():
            tmp.unlink()
