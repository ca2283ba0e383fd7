"""A calibration's result: one type for one mirror and for rigs.

:class:`~.rig.RigCalibration` (:mod:`.rig`) holds every camera and mirror with their
uncertainties; a single mirror is the rig of one camera and one mirror
(:meth:`~.rig.RigCalibration.from_mirror`), and :class:`~.mirror.Calibration`
(:mod:`.mirror`, the ``calibration.json`` a single mirror writes) is that rig's view from
its camera (:meth:`~.rig.RigCalibration.mirror_view`: any camera and mirror of a rig).
Each has its JSON reader and writer beside it; the camera files of both are
:mod:`mirrorgraph.export`'s.
"""
