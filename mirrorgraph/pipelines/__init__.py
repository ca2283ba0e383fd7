"""The runs that string the steps together: keypoints or a rig file in, a calibration out.

One mirror is the rig of one camera and one mirror, and both runs go the same way:
observations -> initialisation -> solve -> completion -> scale -> result.

* :mod:`.options` -- :class:`~.options.CalibrateOptions`, the one options object of both;
* :mod:`.mirror` -- :func:`~.mirror.calibrate`, one camera and a mirror;
* :mod:`.rig` -- :func:`~.rig.calibrate_rig`, cameras and mirrors;
* :mod:`.solve` -- the graph's front ends: the rig built from the observations, solved by
  the one driver (:mod:`mirrorgraph.graph`), read back with its uncertainty;
* :mod:`.scale` -- the metric scale from the subject's stature
  (:func:`mirrorgraph.stature.stature_rescale`, both runs);
* :mod:`.judge` -- every warning about a result.

``mirrorgraph batch`` runs either over many recordings with the same options
(:mod:`mirrorgraph.batch`).
"""
