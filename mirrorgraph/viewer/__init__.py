"""The Rerun viewer of a calibration: cameras, mirrors, the 3D motion and its reflection.

``mirrorgraph view CALIBRATION`` and ``--view`` on ``calibrate`` / ``calibrate-rig``
(the ``view`` extra, ``rerun-sdk``, imported only when called). One concept a module:

* :mod:`.scene`: what is drawn, :class:`~.scene.ViewScene` (cameras, virtual cameras,
  mirrors, joints and their uncertainty), made from a single mirror's calibration
  (:func:`~.scene.scene_from_calibration`) or a rig's (:func:`~.scene.scene_from_rig`);
* :mod:`.drawing`: the geometry of the drawing (a mirror's drawn extent, reflected
  points, epipolar lines clipped to the image);
* :mod:`.recording`: the Rerun recording of a scene (its entity paths, its layout) and
  the viewer that opens it (:func:`~.recording.record`);
* :mod:`.files`: what the command does with its files (:func:`~.files.view_file`: the
  calibration, the 3D joints, the video).
"""
