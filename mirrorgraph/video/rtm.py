"""RTMPose through rtmlib, on ONNX model files the user brings (what Pose2Sim users have).

``--pose-model FILE.onnx --det-model FILE.onnx``: a person detector (YOLOX or
RTMDet, exported with or without its NMS) and a top-down RTMPose model (SimCC
outputs), run by ``rtmlib``'s ``YOLOX`` / ``RTMDet`` and ``RTMPose`` classes with
ONNX Runtime on the CPU (its default threads). Local files only: rtmlib downloads a model only when
given a URL, and :func:`check_onnx_files` refuses anything that is not an
existing ``.onnx`` file. The models' input sizes are read from the files.

rtmlib is installed with ``pip install --no-deps rtmlib`` (its declared
``opencv-python`` and ``opencv-contrib-python`` clash with mirrorgraph's
``opencv-python-headless``; it needs only ``cv2`` and ``onnxruntime``). Frames are
given to it in OpenCV's BGR order, as Pose2Sim does.

People are tracked from frame to frame by the overlap of their boxes
(:class:`BoxTracker`). Keypoint scores are SimCC maxima: ``<= 0`` is missing,
above 1 clipped (as :mod:`mirrorgraph.io.mmpose` reads RTMPose's output). The
layout follows the pose model's keypoint count (17: COCO-17, 26: HALPE_26).
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from ..errors import InputError, require_extra
from ..skeletons import skeletons_for_count
from .reader import frames

__all__ = ["check_onnx_files", "rtmlib_frames", "BoxTracker", "RTM_INSTALL_HINT"]

RTM_INSTALL_HINT = "pip install onnxruntime && pip install --no-deps rtmlib==0.0.16"


def check_onnx_files(pose_model, det_model) -> tuple[Path, Path]:
    """Both model paths, checked to be existing ``.onnx`` files (InputError otherwise)."""
    out = []
    for path, flag in ((pose_model, "pose_model"), (det_model, "det_model")):
        if path is None:
            raise InputError("rtmlib needs both a pose model and a person detector",
                             field=flag, fix=(flag,))
        p = Path(path)
        if p.suffix.lower() != ".onnx":
            raise InputError("must be a local .onnx file (nothing is downloaded)", source=p,
                             field=flag)
        if not p.is_file():
            raise InputError("no such ONNX file", source=p, field=flag)
        out.append(p)
    return out[0], out[1]


def _input_hw(session, source: Path, flag: str) -> tuple[int, int]:
    shape = session.get_inputs()[0].shape
    if len(shape) != 4 or not all(isinstance(v, int) and v > 0 for v in shape[2:]):
        raise InputError(f"expected a fixed (1, 3, H, W) input, got {shape}", source=source,
                         field=flag)
    return int(shape[2]), int(shape[3])


def _load(pose_path: Path, det_path: Path):
    # the rtm extra: onnxruntime and rtmlib are optional, imported only to run them
    for module in ("onnxruntime", "rtmlib"):
        require_extra(module, "rtm", "an RTMPose model (pose_model)",
                      what="rtmlib and onnxruntime", hint=RTM_INSTALL_HINT)
    from rtmlib import RTMDet, RTMPose, YOLOX
    quiet = io.StringIO()
    loading = (det_path, "det_model")                # the model a load error is about
    try:
        with contextlib.redirect_stdout(quiet):      # rtmlib prints "load ..." on stdout
            det_cls = RTMDet if "rtmdet" in det_path.name.lower() else YOLOX
            det = det_cls(onnx_model=str(det_path), backend="onnxruntime", device="cpu")
            det.model_input_size = _input_hw(det.session, det_path, "det_model")
            loading = (pose_path, "pose_model")
            pose = RTMPose(onnx_model=str(pose_path), backend="onnxruntime", device="cpu")
            h, w = _input_hw(pose.session, pose_path, "pose_model")
            pose.model_input_size = (w, h)            # RTMPose takes (width, height)
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - onnxruntime's load errors have many types
        raise InputError(f"cannot be loaded by ONNX Runtime ({type(exc).__name__}: "
                         f"{str(exc).splitlines()[0][:200]})", source=loading[0],
                         field=loading[1]) from None
    return det, pose


def _iou_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(len(a), len(b))`` IoU of ``x1, y1, x2, y2`` boxes."""
    lo = np.maximum(a[:, None, :2], b[None, :, :2])
    hi = np.minimum(a[:, None, 2:], b[None, :, 2:])
    inter = np.prod(np.clip(hi - lo, 0, None), axis=2)
    area = lambda x: np.prod(np.clip(x[:, 2:] - x[:, :2], 0, None), axis=1)  # noqa: E731
    union = area(a)[:, None] + area(b)[None, :] - inter
    return np.where(union > 0, inter / np.maximum(union, 1e-12), 0.0)


class BoxTracker:
    """Track ids from box overlap: each box takes the id of the best-overlapping box
    (IoU above ``min_iou``) of the last ``keep_frames`` frames, greedily, best first;
    others start new ids."""

    def __init__(self, min_iou: float = 0.3, keep_frames: int = 30) -> None:
        self.min_iou, self.keep_frames = min_iou, keep_frames
        self._boxes = np.zeros((0, 4))
        self._ids = np.zeros(0, np.int64)
        self._last = np.zeros(0, np.int64)
        self._next = 0

    def step(self, boxes: np.ndarray, frame: int) -> np.ndarray:
        """``(P,)`` ids of this frame's ``(P, 4)`` boxes."""
        boxes = np.asarray(boxes, float).reshape(-1, 4)
        ids = np.full(len(boxes), -1, np.int64)
        if len(boxes) and len(self._boxes):
            iou = _iou_matrix(boxes, self._boxes)
            while True:
                i, j = np.unravel_index(np.argmax(iou), iou.shape)
                if iou[i, j] <= self.min_iou:
                    break
                ids[i] = self._ids[j]
                iou[i, :], iou[:, j] = -1, -1
        for i in np.flatnonzero(ids < 0):
            ids[i] = self._next
            self._next += 1
        keep = ~np.isin(self._ids, ids) & (frame - self._last <= self.keep_frames)
        self._boxes = np.concatenate([self._boxes[keep], boxes])
        self._ids = np.concatenate([self._ids[keep], ids])
        self._last = np.concatenate([self._last[keep], np.full(len(ids), frame)])
        return ids


def rtmlib_frames(info, opts, step: Callable[[], None]):
    """Detect every frame of a video with rtmlib (see the module docstring).

    Returns:
        ``(skeleton, frame ids, people, track ids, boxes, model name, stats)`` as
        :func:`mirrorgraph.video.detect.detect_video` assembles them.
    """
    pose_path, det_path = check_onnx_files(opts.pose_model, opts.det_model)
    det, pose = _load(pose_path, det_path)
    tracker = BoxTracker()
    ids, people, tids, boxes_out = [], [], [], []
    skeleton = None
    W, H = info.width, info.height
    runs = {"detector_runs": 0, "pose_runs": 0}
    for t, rgb in frames(info.path, start=opts.start, end=opts.end, every=opts.every):
        bgr = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
        boxes = np.asarray(det(bgr), float).reshape(-1, 4)
        runs["detector_runs"] += 1
        if len(boxes):
            kp, sc = pose(bgr, list(boxes))
            runs["pose_runs"] += len(boxes)
            kp, sc = np.asarray(kp, float).reshape(len(boxes), -1, 2), \
                np.asarray(sc, float).reshape(len(boxes), -1)
        else:
            kp, sc = np.zeros((0, 0, 2)), np.zeros((0, 0))
        if skeleton is None and len(boxes):
            found = skeletons_for_count(kp.shape[1])
            if len(found) != 1:
                raise InputError(f"the pose model gives {kp.shape[1]} keypoints, which fit "
                                 f"{'no' if not found else 'more than one'} layout mirrorgraph "
                                 "knows (17: COCO-17, 26: HALPE_26)", source=pose_path,
                                 field="pose_model")
            skeleton = found[0]
        J = skeleton.num_joints if skeleton is not None else 0
        out = np.zeros((len(boxes), J, 3))
        if len(boxes):
            out[..., :2], out[..., 2] = kp, np.clip(sc, 0.0, 1.0)
            bad = (sc <= 0) | (kp[..., 0] < 0) | (kp[..., 0] > W - 1) | \
                  (kp[..., 1] < 0) | (kp[..., 1] > H - 1)
            out[bad] = [np.nan, np.nan, 0.0]
        ids.append(t)
        people.append(out)
        tids.append(tracker.step(boxes, t))
        boxes_out.append(boxes)
        step()
    if skeleton is None:
        raise InputError("the detector found nobody in any frame", source=info.path,
                         field="det_model")
    people = [p if p.shape[1] == skeleton.num_joints else np.zeros((0, skeleton.num_joints, 3))
              for p in people]
    return skeleton, ids, people, tids, boxes_out, f"rtmlib:{pose_path.name}", runs
