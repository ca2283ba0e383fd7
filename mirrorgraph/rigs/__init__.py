"""Rigs: several cameras and several mirrors calibrated together from the people in view.

* :mod:`.config` -- the rig TOML file;
* :mod:`.observations` -- per-camera keypoints, person and reflections sorted, one clock;
* :mod:`.relative` -- two-view initialisation (camera-camera, camera-mirror);
* :mod:`.initial` -- the spanning-tree chaining into one initial rig;
* :mod:`.solve` -- the factor graph of the whole rig;
* :mod:`.result` -- the calibrated rig and its JSON schema;
* :mod:`.pipeline` -- :func:`calibrate_rig`, the entry point.
"""

#: Public name -> its module, imported on first use: reading a rig file (``.config``) does
#: not import the solver.
_LAZY = {"CameraEntry": ".config", "RigConfig": ".config", "load_rig_config": ".config",
         "calibrate_rig": ".pipeline", "RigCalibration": ".result", "RigCamera": ".result",
         "RigMirror": ".result", "virtual_extrinsics": ".result"}

__all__ = list(_LAZY)


def __getattr__(name: str):
    from importlib import import_module

    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(_LAZY[name], __name__), name)
    globals()[name] = value
    return value
