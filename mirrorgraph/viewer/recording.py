"""A Rerun recording of a calibration: cameras, mirrors, the 3D motion and its reflection.

``mirrorgraph view CALIBRATION [--joints3d FILE] [--video FILE] [--save OUT.rrd]`` and
``--view`` on ``calibrate`` / ``calibrate-rig`` build a recording with the Rerun SDK
(``rerun-sdk``, the ``view`` extra; imported only here, only when called) and open it in
Rerun's viewer, or save it as an ``.rrd`` file. Everything is offline.

Entity paths (world frame: the real camera's, or the rig's first camera's: x right,
y down, z forward, lengths in the calibration's unit):

* ``world/cameras/<name>``: each real camera's pose (camera to world) and pinhole;
* ``world/virtual_cameras/<name>``: each mirror's virtual camera, drawn as the camera of
  the horizontally flipped image (the convention of :mod:`mirrorgraph.export`);
* ``world/mirrors/<name>``: the mirror plane's ``surface`` and ``outline``, over the part
  the reflections were seen in;
* ``world/person/joints``, ``world/person/bones``: the 3D motion (timeline ``frame``,
  ``time`` in seconds where the frame rate is known);
* ``world/reflections/<mirror>/...``: the skeleton reflected across each mirror;
* ``world/person/uncertainty``: one-sigma ellipsoids of each joint's two-view
  triangulation (single mirror; a lower bound without the mirror's own uncertainty);
* ``world/cameras/<real>/image`` (with ``--video``): the frames, keypoints, reflection,
  epipolar lines and epipole;
* ``summary``: the calibration's summary.

:func:`record` builds it from a :class:`~.scene.ViewScene`
(:func:`~.scene.scene_from_calibration`, :func:`~.scene.scene_from_rig`) and opens it
(:func:`open_viewer`); :func:`~.files.view_file` does what the command does. Each entity
in full: ``docs/internals.md``.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from ..errors import InputError, extra_hint, require_extra
from .drawing import clip_lines, mirror_quad, reflect
from .scene import ViewScene

__all__ = ["INSTALL_HINT", "blueprint", "open_viewer", "record", "require_rerun"]

#: How to get the viewer's dependency.
INSTALL_HINT = extra_hint("view")

PERSON = (60, 200, 90)
REFLECTION = (240, 140, 40)
REAL_CAMERA = (90, 160, 255)
VIRTUAL_CAMERA = (240, 140, 40)
MIRROR = (150, 200, 255, 70)
MIRROR_EDGE = (150, 200, 255)


def require_rerun():
    """The ``rerun`` module, or :class:`MissingExtraError` saying how to install it."""
    return require_extra("rerun", "view", "the viewer", what="the Rerun SDK")


# --------------------------------------------------------------------------- the recording
def record(scene: ViewScene, *, save: str | os.PathLike | None = None,
           video: str | os.PathLike | None = None, max_video_frames: int = 300,
           application_id: str = "mirrorgraph") -> Path:
    """Log ``scene`` into a Rerun recording saved to ``save`` (an ``.rrd``, written
    atomically, no window), or else to a temporary ``.rrd`` opened in Rerun's viewer
    (the one of the installed ``rerun-sdk``, ``python -m rerun``).

    Args:
        scene: what to draw.
        save: the ``.rrd`` file to write, or ``None`` to open the viewer.
        video: the video of the first camera (frames drawn under its image plane with
            the 2D keypoints and epipolar lines), or ``None``.
        max_video_frames: at most this many video frames, evenly spaced over the
            frames with keypoints (the 2D keypoints are drawn in every frame).

    Returns:
        The recording written (``save``, or the temporary file the viewer opened).

    Raises:
        InputError: the Rerun SDK missing, a video that cannot be read, a viewer that
            exits at once (no display: the message names the recording to open elsewhere).
    """
    rr = require_rerun()
    from ..io.atomic import atomic_path

    out = Path(save) if save is not None else \
        Path(tempfile.mkdtemp(prefix="mirrorgraph-view-")) / "recording.rrd"
    rec = rr.RecordingStream(application_id)
    layout = blueprint(scene, with_image=scene.keypoints is not None or video is not None)
    with atomic_path(out) as tmp:
        rec.save(str(tmp), default_blueprint=layout)
        _log(rr, rec, scene, video, max_video_frames)
        rec.flush()
        rec.disconnect()
    if save is None:
        open_viewer(out)
    return out


def open_viewer(path: str | os.PathLike, wait: float = 5.0) -> None:
    """Open ``path`` in the Rerun viewer of this Python's ``rerun-sdk``, detached. No
    display (Linux without ``DISPLAY`` or ``WAYLAND_DISPLAY``), or a viewer that exits with
    an error within ``wait`` seconds, raises :class:`InputError` naming the recording."""
    def no_display(why: str) -> InputError:
        return InputError(f"Rerun's viewer did not open ({why}): the recording is {path}; open "
                          f"it where there is a display with 'rerun {path}', or write it to a "
                          "file instead", fix=("save",))

    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                 or os.environ.get("WAYLAND_DISPLAY")):
        raise no_display("no display: neither DISPLAY nor WAYLAND_DISPLAY is set")
    proc = subprocess.Popen([sys.executable, "-m", "rerun", str(path)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        code = proc.wait(timeout=wait)
    except subprocess.TimeoutExpired:
        return                                  # running: the window is open
    if code:
        raise no_display(f"exit status {code}")


def blueprint(scene: ViewScene, *, with_image: bool):
    """The recording's default layout: the 3D scene (seen from above and behind the first
    camera, looking at the middle of the cameras, mirrors and person), beside it the
    first camera's image with its keypoints (where there are some) over the summary."""
    import rerun.blueprint as rrb

    marks = [c.pose[:3, 3] for c in scene.cameras if not c.virtual]
    marks += [m.distance * np.asarray(m.normal, float) for m in scene.mirrors]
    if scene.joints3d is not None and scene.valid.any():
        marks.append(np.median(scene.joints3d[scene.valid], axis=0))
    marks = np.array(marks)
    target = marks.mean(axis=0)
    reach = max(float(np.linalg.norm(marks - target, axis=1).max()), 1.0)
    first = next(c for c in scene.cameras if not c.virtual).pose[:3, :3]
    # to the right of the first camera, above it (-y: the world is y down), a little behind
    offset = first @ np.array([1.0, -1.2, -0.8])
    eye = target + 2.4 * reach * offset / np.linalg.norm(offset)   # all of it in view
    view3d = rrb.Spatial3DView(origin="world", name="cameras, mirrors and person",
                               eye_controls=rrb.EyeControls3D(position=eye, look_target=target,
                                                              eye_up=first @ [0.0, -1.0, 0.0]))
    side = [rrb.TextDocumentView(origin="summary", name="summary")]
    if with_image:
        side.insert(0, rrb.Spatial2DView(origin=_image_path(scene), name="camera image"))
    return rrb.Blueprint(rrb.Horizontal(view3d, rrb.Vertical(*side), column_shares=[3, 2]),
                         collapse_panels=True)


def _times(rr, scene: ViewScene, frames: np.ndarray) -> list:
    cols = [rr.TimeColumn("frame", sequence=frames)]
    if scene.fps:
        cols.append(rr.TimeColumn("time", duration=frames / scene.fps))
    return cols


def _set_time(rec, scene: ViewScene, frame: int) -> None:
    rec.set_time("frame", sequence=int(frame))
    if scene.fps:
        rec.set_time("time", duration=float(frame) / scene.fps)


def _log(rr, rec, scene: ViewScene, video, max_video_frames: int) -> None:
    rec.log("world", rr.ViewCoordinates.RDF, static=True)
    if scene.summary:
        rec.log("summary", rr.TextDocument(scene.summary), static=True)
    # a sense of scale for the image planes: a tenth of the farthest mirror or camera
    reach = [m.distance for m in scene.mirrors] + [float(np.linalg.norm(c.pose[:3, 3]))
                                                   for c in scene.cameras if not c.virtual]
    plane = max(0.1 * max(reach), 0.05)
    for cam in scene.cameras:
        path = f"world/{'virtual_cameras' if cam.virtual else 'cameras'}/{cam.name}"
        rec.log(path, rr.Transform3D(translation=cam.pose[:3, 3], mat3x3=cam.pose[:3, :3]),
                static=True)
        rec.log(f"{path}/image", rr.Pinhole(image_from_camera=cam.K, resolution=cam.resolution,
                                            camera_xyz=rr.ViewCoordinates.RDF,
                                            image_plane_distance=plane,
                                            color=VIRTUAL_CAMERA if cam.virtual else REAL_CAMERA),
                static=True)
    pts = None
    if scene.joints3d is not None:
        pts = scene.joints3d[scene.valid]
    for m in scene.mirrors:
        quad = mirror_quad(m, pts)
        rec.log(f"world/mirrors/{m.name}/surface",
                rr.Mesh3D(vertex_positions=quad, triangle_indices=[[0, 1, 2], [0, 2, 3]],
                          vertex_colors=[MIRROR] * 4), static=True)
        rec.log(f"world/mirrors/{m.name}/outline",
                rr.LineStrips3D([np.vstack([quad, quad[:1]])], colors=[MIRROR_EDGE]),
                static=True)
    if scene.joints3d is not None and len(scene.frame_ids):
        _log_skeleton(rr, rec, scene, "world/person", scene.joints3d, PERSON)
        for m in scene.mirrors:
            _log_skeleton(rr, rec, scene, f"world/reflections/{m.name}",
                          reflect(scene.joints3d, m.normal, m.distance), REFLECTION)
        if scene.joint_cov is not None:
            _log_uncertainty(rr, rec, scene)
    if scene.keypoints is not None:
        _log_keypoints(rr, rec, scene)
    if video is not None:
        _log_video(rr, rec, scene, video, max_video_frames)


def _log_skeleton(rr, rec, scene: ViewScene, path: str, X: np.ndarray, colour) -> None:
    ok = scene.valid
    times = _times(rr, scene, scene.frame_ids)
    rec.send_columns(f"{path}/joints", indexes=times,
                     columns=rr.Points3D.columns(positions=X[ok]).partition(ok.sum(1)))
    rec.log(f"{path}/joints", rr.Points3D.from_fields(colors=[colour], radii=[0.02]),
            static=True)
    if len(scene.bones):
        a, b = scene.bones[:, 0], scene.bones[:, 1]
        both = ok[:, a] & ok[:, b]                                    # (T, B)
        strips = np.stack([X[:, a], X[:, b]], axis=2)[both]          # (N, 2, 3)
        rec.send_columns(f"{path}/bones", indexes=times,
                         columns=rr.LineStrips3D.columns(strips=list(strips))
                         .partition(both.sum(1)))
        rec.log(f"{path}/bones", rr.LineStrips3D.from_fields(colors=[colour], radii=[0.008]),
                static=True)


def _log_uncertainty(rr, rec, scene: ViewScene) -> None:
    from scipy.spatial.transform import Rotation

    ok = scene.valid & np.isfinite(scene.joint_cov).all((-1, -2))
    cov = scene.joint_cov[ok]
    w, V = np.linalg.eigh(cov)                                      # ascending eigenvalues
    V[np.linalg.det(V) < 0, :, 0] *= -1                              # proper rotations
    q = Rotation.from_matrix(V).as_quat()                            # x, y, z, w
    rec.send_columns("world/person/uncertainty", indexes=_times(rr, scene, scene.frame_ids),
                     columns=rr.Ellipsoids3D.columns(
                         centers=scene.joints3d[ok], half_sizes=np.sqrt(np.maximum(w, 0)),
                         quaternions=q).partition(ok.sum(1)))
    rec.log("world/person/uncertainty",
            rr.Ellipsoids3D.from_fields(colors=[(*PERSON, 110)], fill_mode="solid"), static=True)


def _image_path(scene: ViewScene) -> str:
    real = next(c for c in scene.cameras if not c.virtual)
    return f"world/cameras/{real.name}/image"


def _log_keypoints(rr, rec, scene: ViewScene) -> None:
    real, mirror = scene.keypoints
    ids = scene.frame_ids
    if real.shape[0] != len(ids):
        raise InputError(f"{real.shape[0]} frames of keypoints for {len(ids)} frames of joints",
                         field="keypoints")
    base = _image_path(scene)
    times = _times(rr, scene, ids)
    ok_r = np.isfinite(real[..., :2]).all(-1)
    ok_m = np.isfinite(mirror[..., :2]).all(-1)
    for name, kp, ok, colour in (("keypoints", real, ok_r, PERSON),
                                 ("reflection", mirror, ok_m, REFLECTION)):
        rec.send_columns(f"{base}/{name}", indexes=times,
                         columns=rr.Points2D.columns(positions=kp[..., :2][ok])
                         .partition(ok.sum(1)))
        rec.log(f"{base}/{name}", rr.Points2D.from_fields(colors=[colour], radii=[4.0]),
                static=True)
    W, H = next(c for c in scene.cameras if not c.virtual).resolution
    both = ok_r & ok_m
    if scene.epipole is None:
        both[:] = False
    u = np.concatenate([real[..., :2], np.ones(real.shape[:2] + (1,))], -1)[both]
    # the epipolar line of each joint: through the joint and the epipole, F u = e x u
    seg, inside = clip_lines(np.cross(np.broadcast_to(scene.epipole, u.shape), u), W, H)
    per_frame = np.zeros(both.shape, bool)
    per_frame[both] = inside
    rec.send_columns(f"{base}/epipolar_lines", indexes=times,
                     columns=rr.LineStrips2D.columns(strips=list(seg[inside]))
                     .partition(per_frame.sum(1)))
    rec.log(f"{base}/epipolar_lines",
            rr.LineStrips2D.from_fields(colors=[(255, 255, 255, 90)], radii=[1.0]), static=True)
    if scene.epipole_px is not None:
        rec.log(f"{base}/epipole", rr.Points2D([scene.epipole_px], colors=[(255, 60, 60)],
                                               radii=[8.0], labels=["epipole"]), static=True)


def _log_video(rr, rec, scene: ViewScene, video, max_video_frames: int) -> None:
    import cv2

    from ..video.reader import frames, probe

    probe(video)                                  # one error line if it cannot be read
    ids = scene.frame_ids if scene.frame_ids is not None else np.arange(max_video_frames)
    if len(ids) > max_video_frames:
        ids = ids[np.unique(np.linspace(0, len(ids) - 1, max_video_frames).round().astype(int))]
    wanted = {int(f) for f in ids}
    base = _image_path(scene)
    last = max(wanted) + 1 if wanted else 0
    for f, rgb in frames(video, end=last):
        if f not in wanted:
            continue
        ok, jpeg = cv2.imencode(".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR),
                                [cv2.IMWRITE_JPEG_QUALITY, 80])
        if not ok:
            continue
        _set_time(rec, scene, f)
        rec.log(base, rr.EncodedImage(contents=jpeg.tobytes(), media_type="image/jpeg"))

