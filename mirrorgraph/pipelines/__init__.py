"""The runs that string the steps together: keypoints or a rig file in, a calibration out.

One mirror is the rig of one camera and one mirror: both front ends take one
:class:`~.options.CalibrateOptions`, scale by the subject's stature the same way
(:mod:`.scale`) and judge their result with the same warnings (:mod:`.judge`).
"""
