"""What ``mirrorgraph view`` does with its files: :func:`view_file`.

The calibration (a single mirror's JSON, a rig's JSON or the ``calibration.toml`` beside
it), the 3D joints (a ``--joints3d`` ``.npz``, or the run kept beside a single mirror's
calibration with its 2D keypoints) and the video, made into a
:class:`~.scene.ViewScene` and recorded (:func:`~.recording.record`).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError
from .recording import record, require_rerun
from .scene import scene_from_calibration, scene_from_rig

__all__ = ["view_file"]


def view_file(calibration: str | os.PathLike, *, joints3d: str | os.PathLike | None = None,
              video: str | os.PathLike | None = None, save: str | os.PathLike | None = None,
              fps: float | None = None, max_video_frames: int = 300) -> Path:
    """What ``mirrorgraph view`` does: the recording of a calibration file.

    Args:
        calibration: a single mirror's ``calibration.json``, a rig's JSON, or a rig's
            ``calibration.toml`` (the JSON beside it is read).
        joints3d: a ``--joints3d`` ``.npz``; without it a single mirror's joints come
            from the run kept beside the calibration (``c.report.npz``) where there is
            one, with its 2D keypoints.
        video: the video of the (first) camera: single mirror only.
        save: ``.rrd`` to write instead of opening the viewer.
        fps: frame rate of the timeline ``time`` (default: the joints file's).

    Raises:
        InputError: an unreadable or unknown calibration, joints that do not belong to it,
            a video with a rig.
    """
    require_rerun()
    path = Path(calibration)
    if path.suffix.lower() == ".toml":
        json_path = path.with_suffix(".json")
        if not json_path.is_file():
            raise InputError("a rig's calibration.toml is drawn from the JSON calibrate-rig "
                             f"writes beside it: no {json_path.name}", source=path)
        path = json_path
    from ..io._common import load_json
    doc = load_json(path)
    if not isinstance(doc, dict) or not ("mirror" in doc or "cameras" in doc):
        raise InputError("neither a mirrorgraph calibration.json nor a rig's JSON", source=path)
    motion = _read_motion(joints3d) if joints3d is not None else None
    if motion is not None and fps is None:
        fps = motion["fps"]
    if "cameras" in doc:
        if video is not None:
            raise InputError("draws the video of a single-mirror calibration, not of a rig",
                             field="video")
        kw = {} if motion is None else {k: motion[k] for k in ("joints3d", "valid", "frame_ids",
                                                               "joint_names")}
        scene = scene_from_rig(doc, fps=fps, **kw)
        return record(scene, save=save, max_video_frames=max_video_frames)
    from ..result.mirror import read_calibration
    calib = read_calibration(path)
    keypoints = None
    run = _read_kept_run(path, calib)
    if motion is not None and run is not None \
            and np.array_equal(np.asarray(motion["frame_ids"]), run.paired.frame_ids):
        keypoints = (run.paired.real, run.paired.mirror)     # the same frames: their 2D
    if motion is None:
        if run is not None and run.joints3d is not None:
            motion = {"joints3d": run.joints3d, "valid": run.valid3d,
                      "frame_ids": run.paired.frame_ids, "joint_names": run.paired.skeleton.joints,
                      "fps": run.fps if run.fps else run.paired.fps,
                      "unit": "m" if calib.distance is not None else "mirror distance"}
            keypoints = (run.paired.real, run.paired.mirror)
            if fps is None:
                fps = motion["fps"]
    if motion is not None:
        if motion.get("unit") and calib.distance is not None and motion["unit"] != "m":
            raise InputError(f"the joints are in {motion['unit']!r}, the calibration in metres: "
                             "not the joints of this calibration", source=joints3d)
    scene = scene_from_calibration(
        calib, keypoints=keypoints, fps=fps,
        **({} if motion is None else {k: motion[k] for k in ("joints3d", "valid", "frame_ids",
                                                              "joint_names")}))
    if video is not None and not Path(video).is_file():
        raise InputError("no such video file", source=video)
    return record(scene, save=save, video=video, max_video_frames=max_video_frames)


def _read_kept_run(path: Path, calib):
    from ..report.store import report_data_path, read_run
    kept = report_data_path(path)
    if not kept.is_file():
        return None
    try:
        return read_run(kept, calib)
    except InputError:
        return None


def _read_motion(path) -> dict[str, Any]:
    """A ``--joints3d`` ``.npz`` (:func:`mirrorgraph.io.motion.write_joints3d_npz`)."""
    path = Path(path)
    if path.suffix.lower() != ".npz":
        raise InputError("give the .npz of the 3D joints that a calibration writes (it holds "
                         "the joint names, the unit and the frame)", source=path)
    try:
        with np.load(path, allow_pickle=False) as z:
            d = {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise InputError("no such file", source=path) from None
    except (OSError, ValueError, EOFError) as exc:
        raise InputError(f"cannot be read as a .npz ({type(exc).__name__})", source=path) from None
    missing = [k for k in ("joints3d", "joint_names") if k not in d]
    if missing:
        raise InputError(f"missing {', '.join(missing)} (not a .npz of 3D joints?)",
                         source=path)
    X = d["joints3d"]
    fps = float(d["fps"]) if "fps" in d else float("nan")
    return {"joints3d": X, "valid": d.get("valid"), "frame_ids": d.get("frame_ids"),
            "joint_names": [str(n) for n in d["joint_names"]],
            "fps": fps if np.isfinite(fps) else None,
            "unit": str(d["unit"]) if "unit" in d else None}
