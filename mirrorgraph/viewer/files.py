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

__all__ = ["view_file", "MAX_COORDINATE", "MIN_DEPTH"]

#: The largest coordinate a joint may have (metres or mirror distances / subject heights):
#: beyond it a joints file is no person's motion.
MAX_COORDINATE = 1e4
#: The nearest a joint may be to a single mirror's camera (depth, the calibration's unit:
#: a millimetre, or a thousandth of the mirror's distance).
MIN_DEPTH = 1e-3


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
    from ..io.calibration import read_calibration_document
    from ..result.mirror import SCHEMA_VERSION
    doc = read_calibration_document(path, SCHEMA_VERSION)
    if not isinstance(doc, dict) or not ("mirror" in doc or "cameras" in doc):
        raise InputError("neither a mirrorgraph calibration.json nor a rig's JSON", source=path)
    if video is not None and "cameras" in doc:
        raise InputError("draws the video of a single-mirror calibration, not of a rig",
                         field="video")
    if video is not None:
        if Path(video).is_dir():
            raise InputError("is a folder, not a video file", source=video, field="video")
        if not Path(video).is_file():
            raise InputError("no such video file", source=video, field="video")
    motion = _read_motion(joints3d) if joints3d is not None else None
    if motion is not None and fps is None:
        fps = motion["fps"]
    if "cameras" in doc:
        if motion is not None:
            _check_belongs(motion, joints3d, path, skeleton=doc.get("skeleton"),
                           frames=doc.get("frames"), metric=doc.get("scale") == "subject_height",
                           what="rig")
        kw = {} if motion is None else {k: motion[k] for k in ("joints3d", "valid", "frame_ids",
                                                               "joint_names")}
        scene = scene_from_rig(doc, fps=fps, **kw)
        return record(scene, save=save, max_video_frames=max_video_frames)
    from ..result.mirror import read_calibration
    calib = read_calibration(path)
    keypoints = None
    if motion is not None:
        _check_belongs(motion, joints3d, path, skeleton=calib.input.get("skeleton"),
                       frames=calib.frames_read,            # a row for every frame read
                       metric=calib.distance is not None,
                       what="single mirror", in_front=True)
    run = _read_kept_run(path, calib, needed=motion is None)
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
    scene = scene_from_calibration(
        calib, keypoints=keypoints, fps=fps,
        **({} if motion is None else {k: motion[k] for k in ("joints3d", "valid", "frame_ids",
                                                              "joint_names")}))
    return record(scene, save=save, video=video, max_video_frames=max_video_frames)


def _read_kept_run(path: Path, calib, needed: bool):
    """The run kept beside the calibration (``c.report.npz``), or ``None`` where there is
    none. One that does not belong to the calibration (stale, damaged) is refused where
    its joints are ``needed`` (no ``--joints3d``), else left aside."""
    from ..report.store import report_data_path, read_run
    kept = report_data_path(path)
    if not kept.is_file():
        return None
    try:
        return read_run(kept, calib)
    except InputError as exc:
        if needed:
            raise InputError(f"{exc.reason}: its joints are not drawn; give --joints3d FILE "
                             "or calibrate again", source=kept) from None
        return None


def _check_belongs(motion: dict, joints3d, calibration: Path, *, skeleton, frames, metric: bool,
                   what: str, in_front: bool = False) -> None:
    """Refuse 3D joints that are not the calibration's: another skeleton, another number
    of frames, another unit; for a single mirror, a joint on or behind the camera.

    Raises:
        InputError: naming the joints file and what disagrees with the calibration.
    """
    from ..skeletons import skeleton_by_name

    names = list(motion["joint_names"])
    X = motion["joints3d"]
    if skeleton:
        try:
            want = list(skeleton_by_name(str(skeleton)).joints)
        except ValueError:
            want = None
        if want is not None and names != want:
            raise InputError(f"joints of another skeleton ({len(names)} joints, the "
                             f"{what} calibration {calibration.name} is {skeleton} with "
                             f"{len(want)}): not the joints of this calibration",
                             source=joints3d)
    if isinstance(frames, int) and not isinstance(frames, bool) and frames > 0 \
            and len(X) != frames:
        raise InputError(f"{len(X)} frames of joints, the {what} calibration "
                         f"{calibration.name} has {frames}: not the joints of this "
                         "calibration", source=joints3d)
    unit = motion.get("unit")
    if unit is not None and (unit == "m") != metric:
        raise InputError(f"the joints are in {unit!r}, the calibration "
                         f"{'in metres' if metric else 'without a metric scale'}: not the "
                         "joints of this calibration", source=joints3d)
    if in_front:
        valid = motion["valid"]
        with np.errstate(invalid="ignore"):
            behind = valid & ~(X[..., 2] > MIN_DEPTH)
        if behind.any():
            t, j = np.argwhere(behind)[0]
            fid = motion["frame_ids"][t] if motion["frame_ids"] is not None else t
            raise InputError(f"joint {names[j]} at depth {X[t, j, 2]:g}, on, behind or "
                             "against the camera: not the joints of this calibration",
                             source=joints3d,
                             frame=int(fid))


def _read_motion(path) -> dict[str, Any]:
    """A ``--joints3d`` ``.npz`` (:func:`mirrorgraph.io.motion.write_joints3d_npz`)."""
    path = Path(path)
    if path.suffix.lower() != ".npz":
        raise InputError("give the .npz of the 3D joints that a calibration writes (it holds "
                         "the joint names, the unit and the frame)", source=path)
    if path.is_dir():
        raise InputError("is a folder; give the .npz of the 3D joints", source=path)
    try:
        with open(path, "rb") as fh:           # closed whatever np.load makes of it
            z = np.load(fh, allow_pickle=False)
            if not hasattr(z, "files"):
                raise InputError("a single array, not the .npz of 3D joints", source=path)
            with z:
                d = {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise InputError("no such file", source=path) from None
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - numpy's parsers of damaged bytes raise many kinds
        # (BadZipFile, zlib.error, EOFError, ValueError, tokenize's TokenError, ...)
        raise InputError(f"cannot be read as a .npz ({type(exc).__name__}: damaged or "
                         "truncated?)", source=path) from None
    missing = [k for k in ("joints3d", "joint_names") if k not in d]
    if missing:
        raise InputError(f"missing {', '.join(missing)} (not a .npz of 3D joints?)",
                         source=path)
    X = d["joints3d"]
    if X.dtype.kind not in "fiu" or X.ndim != 3 or X.shape[2] != 3:
        raise InputError(f"expected (T, J, 3) numbers, got {X.dtype} {X.shape}", source=path,
                         field="joints3d")
    X = X.astype(float)
    X[~np.isfinite(X)] = np.nan            # an infinity is a joint not estimated, as NaN
    T, J = X.shape[:2]
    names = d["joint_names"]
    if names.ndim != 1 or len(names) != J:
        raise InputError(f"{names.size} names for {J} joints", source=path, field="joint_names")
    valid = d.get("valid")
    if valid is None:
        valid = np.isfinite(X).all(-1)
    elif valid.shape != (T, J) or valid.dtype.kind not in "bui":
        raise InputError(f"expected ({T}, {J}) booleans, got {valid.dtype} {valid.shape}",
                         source=path, field="valid")
    valid = np.asarray(valid, bool) & np.isfinite(X).all(-1)
    ids = d.get("frame_ids")
    if ids is not None and (ids.shape != (T,) or ids.dtype.kind not in "iu"):
        raise InputError(f"expected {T} whole numbers, got {ids.dtype} {ids.shape}",
                         source=path, field="frame_ids")
    huge = valid & (np.abs(np.where(valid[..., None], X, 0.0)) > MAX_COORDINATE).any(-1)
    if huge.any():
        t, j = np.argwhere(huge)[0]
        raise InputError(f"joint {j} at {X[t, j].tolist()}: beyond {MAX_COORDINATE:g} in the "
                         "calibration's unit, not a person's joint", source=path,
                         frame=int(ids[t]) if ids is not None else int(t), field="joints3d")
    try:
        fps = float(d["fps"]) if "fps" in d else float("nan")
    except (TypeError, ValueError):
        fps = float("nan")
    return {"joints3d": X, "valid": valid, "frame_ids": ids,
            "joint_names": [str(n) for n in names],
            "fps": fps if np.isfinite(fps) and fps > 0 else None,
            "unit": str(d["unit"]) if "unit" in d else None}
