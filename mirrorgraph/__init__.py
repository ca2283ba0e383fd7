"""mirrorgraph: calibrate a planar mirror from the people in the video.

The Python API in a nutshell::

    import mirrorgraph as mg

    run = mg.calibrate("keypoints.json", mg.load_intrinsics("camera.json"),
                       mg.CalibrateOptions(subject_height=1.75))
    print(run.calibration.summary())
    mg.write_calibration("calibration.json", run.calibration)

Modules, one concept each: :mod:`~mirrorgraph.geometry` (mirror math),
:mod:`~mirrorgraph.solvers` (minimal and linear solvers),
:mod:`~mirrorgraph.ransac` (generic robust estimator),
:mod:`~mirrorgraph.estimators` (solvers + RANSAC for the mirror),
:mod:`~mirrorgraph.skeletons`, :mod:`~mirrorgraph.io` (readers and writers),
:mod:`~mirrorgraph.pairing` (person and reflection),
:mod:`~mirrorgraph.graph` and :mod:`~mirrorgraph.factors` (the GTSAM factor graph),
:mod:`~mirrorgraph.pipeline` (the steps strung together),
:mod:`~mirrorgraph.synth` (synthetic scenes with ground truth),
:mod:`~mirrorgraph.cli` (the command line over this API).
"""

from ._version import __version__

from .calibration import Calibration, write_calibration  # noqa: E402
from .errors import DegenerateGeometryError, InputError, MirrorgraphError  # noqa: E402
from .pipeline import CalibrateOptions, CalibrationRun, calibrate  # noqa: E402

__all__ = ["Calibration", "CalibrateOptions", "CalibrationRun", "DegenerateGeometryError",
           "InputError", "MirrorgraphError", "calibrate", "load_intrinsics", "read_keypoints",
           "write_calibration", "__version__"]


def __getattr__(name):
    # light lazy imports so that `import mirrorgraph` stays fast
    if name == "load_intrinsics":
        from .intrinsics import load_intrinsics
        return load_intrinsics
    if name == "read_keypoints":
        from .io import read_keypoints
        return read_keypoints
    raise AttributeError(f"module 'mirrorgraph' has no attribute {name!r}")
