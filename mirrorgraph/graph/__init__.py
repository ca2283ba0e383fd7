"""The factor graph of the mirror refinement: rig, builder, optimiser, entry point.

* :mod:`.rig`: cameras (fixed poses), mirrors, views and their observations, and the
  rig's geometry (projections, triangulation, parallax, residuals);
* :mod:`.builder`: variables, initial values and factors of a rig; :mod:`.problem`, the
  built graph and its values read back; :mod:`.priors`, the prior factors;
  :mod:`.bones`, bone lengths from joints and their curvature bias;
* :mod:`.options`: :class:`RefineOptions` (weights, kernels, gauge, solver; tuned defaults);
* :mod:`.optimizer`: Levenberg-Marquardt driven from Python over GTSAM's elimination;
  :mod:`.solve_graph`, set up for one built graph;
* :mod:`.reduction`: the mirror link as an exact constraint (reduced global coordinates);
* :mod:`.lengths`: the held bone lengths set to their optimum between steps;
* :mod:`.outliers`: rejection by reprojection residual and by bone-length consistency,
  the views cleaned before the first solve;
* :mod:`.solve`: :func:`~.solve.solve`, the one solve driver of every rig;
  :mod:`.stages`, its stages, :mod:`.stage_config`, the configuration that says what
  varies, :mod:`.solve_state`, what it returns; :mod:`.focal_search`, the initial
  search of an unknown focal length; :mod:`.noise` and :mod:`.marginals`, the a
  posteriori noise and the covariances it scales;
* :mod:`.chunked`: videos too long for one graph (spread subset, then chunks);
* :mod:`.scores`, :mod:`.sandwich`, :mod:`.uncertainty`, :mod:`.sensitivity`: the
  joints' scores, the cluster-robust sandwich, the headline figures and regions, what
  the calibration rests on;
* :mod:`.result`: :class:`RefinementResult` and the normal-to-rotation uncertainty.

The engine only: what builds a rig from a front end's observations and reads its
solution back is :mod:`mirrorgraph.pipelines.solve` (``refine_mirror``, ``solve_rig``).
"""

from .options import RefineOptions

#: Name -> its module here, imported on first use (``__getattr__``): they import GTSAM,
#: which the options above (and so the command line's parser) do not need.
_LAZY = {"RefinementResult": ".result",
         "rotation_std_from_normal_cov": ".result", "Camera": ".rig", "Mirror": ".rig",
         "Rig": ".rig", "View": ".rig", "single_mirror_rig": ".rig"}

__all__ = ["Camera", "Mirror", "RefineOptions", "RefinementResult", "Rig", "View",
           "rotation_std_from_normal_cov", "single_mirror_rig"]


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from importlib import import_module

    value = getattr(import_module(_LAZY[name], __name__), name)
    globals()[name] = value
    return value
