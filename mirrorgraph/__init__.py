"""mirrorgraph: calibrate a planar mirror from the people in the video.

The Python API in a nutshell::

    import mirrorgraph as mg

    run = mg.calibrate("keypoints.json", mg.load_intrinsics("camera.json"),
                       mg.CalibrateOptions(subject_height=1.75))
    print(run.calibration.summary())
    mg.write_calibration("calibration.json", run.calibration)
    mg.export_calibration("calibration.json", "pose2sim", "Calib.toml")

    rig = mg.calibrate_rig("rig.toml", mg.CalibrateOptions(subject_height=1.75))  # a rig
    mg.write_rig_toml(rig, "Calib.toml")

Every name in ``__all__`` is the public API (``docs/api.md``, the *Python API* page); the
rest is reachable through its module. Every name but the errors and the version is
imported on first use (its module pulls NumPy, OpenCV, SciPy, GTSAM or an optional
extra), so that ``import mirrorgraph`` stays fast and imports none of them.

Modules, one concept each: :mod:`~mirrorgraph.geometry` (mirror math),
:mod:`~mirrorgraph.initial.solvers` (minimal and linear solvers),
:mod:`~mirrorgraph.initial.ransac` (generic robust estimator),
:mod:`~mirrorgraph.initial.estimators` (solvers + RANSAC for the mirror),
:mod:`~mirrorgraph.skeletons`, :mod:`~mirrorgraph.io` (readers and writers),
:mod:`~mirrorgraph.initial.pairing` (person and reflection),
:mod:`~mirrorgraph.graph` and :mod:`~mirrorgraph.factors` (the GTSAM factor graph),
:mod:`~mirrorgraph.pipelines.mirror` (the steps strung together),
:mod:`~mirrorgraph.synth` (synthetic scenes with ground truth),
:mod:`~mirrorgraph.cli` (the command line over this API).
"""

from ._version import __version__

from .errors import (DegenerateGeometryError, FailedCameraError, InputError,  # noqa: E402
                     MirrorgraphError, MissingExtraError)

#: Public name -> the module it lives in, imported on first use (``__getattr__``).
_LAZY = {
    "Calibration": "mirrorgraph.result.mirror",
    "read_calibration": "mirrorgraph.result.mirror",
    "write_calibration": "mirrorgraph.result.mirror",
    "CalibrateOptions": "mirrorgraph.pipelines.options",
    "CalibrationRun": "mirrorgraph.pipelines.mirror",
    "calibrate": "mirrorgraph.pipelines.mirror",
    "load_intrinsics": "mirrorgraph.intrinsics",
    "Intrinsics": "mirrorgraph.intrinsics",
    "read_keypoints": "mirrorgraph.io",
    "write_keypoints": "mirrorgraph.io",
    "RefineOptions": "mirrorgraph.graph.options",
    "calibrate_rig": "mirrorgraph.pipelines.rig",
    "load_rig_config": "mirrorgraph.rigs.config",
    "RigConfig": "mirrorgraph.rigs.config",
    "RigCalibration": "mirrorgraph.result.rig",
    "read_rig_calibration": "mirrorgraph.result.rig",
    "write_rig_toml": "mirrorgraph.export",
    "write_rig_json": "mirrorgraph.result.rig",
    "export_calibration": "mirrorgraph.export",
    "export_cameras": "mirrorgraph.export",
    "make_report": "mirrorgraph.report",
    "write_rig_report": "mirrorgraph.report.rig",
}

__all__ = ["DegenerateGeometryError", "FailedCameraError", "InputError", "MirrorgraphError",
           "MissingExtraError", "__version__"] + list(_LAZY)


def __getattr__(name: str):
    from importlib import import_module
    from importlib.util import find_spec

    module = _LAZY.get(name)
    if module is None:
        if not name.startswith("_") and find_spec(f"{__name__}.{name}") is not None:
            return import_module(f"{__name__}.{name}")    # a submodule: mg.geometry
        raise AttributeError(f"module 'mirrorgraph' has no attribute {name!r}")
    value = getattr(import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
