"""Rigs: several cameras and several mirrors calibrated together from the people in view.

* :mod:`.config` -- the rig TOML file;
* :mod:`.observations` -- per-camera keypoints, person and reflections sorted, one clock;
* :mod:`.relative` -- two-view initialisation (camera-camera, camera-mirror);
* :mod:`.initial` -- the spanning-tree chaining into one initial rig;
* :mod:`.completion` -- the joints the graph left out, triangulated over real and
  virtual views (:func:`mirrorgraph.geometry.triangulate`);
* :mod:`.solve` -- the factor graph of the whole rig;
* :mod:`.result` -- the calibrated rig and its JSON schema;
* :mod:`.pipeline` -- :func:`calibrate_rig`, the entry point.
"""

from .config import CameraEntry, RigConfig, load_rig_config
from .pipeline import calibrate_rig
from .result import RigCalibration, RigCamera, RigMirror, virtual_extrinsics

__all__ = ["CameraEntry", "RigConfig", "load_rig_config", "calibrate_rig", "RigCalibration",
           "RigCamera", "RigMirror", "virtual_extrinsics"]
