"""GTSAM factors of the mirror refinement: reprojection, the mirror link, and body priors.

One module per term of MirrorCalib's objective (Liao, Zheng and Mitchell, sec.
"Refining 2D joint locations"):

==================  =====================================  ===========================
module              factor                                  paper term
==================  =====================================  ===========================
``reprojection``    built-in direct / mirror projection    ``L_repro`` (Geman-McClure)
``mirror_link``     virtual pose = reflected camera         (geometry: a constraint)
``bone_length``     per-frame bones vs shared lengths      ``L_var``
``symmetry``        left vs right length variables         ``L_sym``
``anthropometry``   length / femur vs Winter 2009          ``L_anth``
``hip``             left hip, mid-hip, right hip colinear  ``L_hip``
``smoothness``      gap-aware second difference            ``L_smooth``
``torso``           shoulder-hip distances held            (the trunk nearly rigid)
``gauge``           subject height or unit distance        (scale)
==================  =====================================  ===========================

Every class exposes its residual and analytic Jacobians in numpy
(``evaluate``) and builds the GTSAM factor (``make``); the tests compare the
linearised factors with central differences.
"""

from .anthropometry import AnthropometricRatioFactor
from .bone_length import BoneLengthFactor
from .gauge import DistancePriorFactor, HeightPriorFactor
from .hip import HipColinearityFactor
from .mirror_link import MirrorLinkFactor, plane_from_gtsam, plane_to_gtsam, reflected_pose
from .reprojection import (ReprojectionFactors, calibration, direct_residuals, mirror_residuals,
                           mirrored_calibration, robust_pixel_noise)
from .smoothness import SmoothnessFactor
from .symmetry import SymmetryFactor
from .torso import TORSO_CORNERS, TorsoFactors, torso_pairs

__all__ = [
    "AnthropometricRatioFactor", "BoneLengthFactor", "DistancePriorFactor",
    "HeightPriorFactor", "HipColinearityFactor", "MirrorLinkFactor", "ReprojectionFactors",
    "SmoothnessFactor", "SymmetryFactor", "TORSO_CORNERS", "TorsoFactors", "calibration",
    "direct_residuals", "mirror_residuals",
    "mirrored_calibration", "plane_from_gtsam", "plane_to_gtsam", "reflected_pose",
    "robust_pixel_noise", "torso_pairs",
]
