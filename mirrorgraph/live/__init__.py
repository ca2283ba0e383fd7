"""Live: calibrate the mirror while the video streams, and 3D joints frame by frame.

* :mod:`.calibrator` -- :class:`LiveCalibrator`, fed one frame of keypoints at a time
  (for apps that run their own detector); :class:`LiveOptions`, :class:`LiveFrame`,
  :class:`LiveMirror`;
* :mod:`.estimator` -- the mirror: windows of frames calibrated by the offline run
  (:func:`mirrorgraph.calibrate`), fused with the older windows' information;
* :mod:`.sources` -- frames from a keypoint file replayed, a video file or a camera
  (BlazePose, :mod:`mirrorgraph.video`);
* :mod:`.stream` -- the run of ``mirrorgraph live``: a source through the calibrator
  into JSON lines (and Rerun's live viewer).

Measured figures and the method's limits: ``docs/guide/live.md``,
``bench/RESULTS_live.md``.
"""

from .calibrator import STATUSES, LiveCalibrator, LiveFrame, LiveMirror, LiveOptions

__all__ = ["LiveCalibrator", "LiveOptions", "LiveFrame", "LiveMirror", "STATUSES"]
