"""Rigs: the inputs of several cameras and mirrors calibrated together.

* :mod:`.config` -- the rig TOML file;
* :mod:`.observations` -- per-camera keypoints, person and reflections sorted, one clock;
* :mod:`.matching` -- the same person in every camera (tracks matched through the
  epipolar geometry, left/right swaps read).

Their initialisation is :mod:`mirrorgraph.initial` (:mod:`~mirrorgraph.initial.relative`,
:mod:`~mirrorgraph.initial.rig`), the run :func:`mirrorgraph.pipelines.rig.calibrate_rig`,
the result :mod:`mirrorgraph.result.rig`.
"""

from .config import CameraEntry, RigConfig, load_rig_config

__all__ = ["CameraEntry", "RigConfig", "load_rig_config"]
