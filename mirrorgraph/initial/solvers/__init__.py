"""Minimal and linear solvers for the mirror's epipole (no robustness here).

* :mod:`.reflective` — ours: the skew-symmetric reflective fundamental matrix
  ``F = [e]_x`` from joint/reflection lines: 2-point minimal solver, weighted
  linear least squares, and a nonlinear refinement of the epipolar distance.
* :mod:`.eightpoint` — the reference estimators of MirrorCalib: the plain
  normalised eight-point algorithm (OpenCV, the paper's Baseline1) and the
  paper's 6-unknown reflective eight-point algorithm.

Robust estimation (RANSAC) lives apart, in :mod:`mirrorgraph.initial.ransac`, and takes
any of these solvers.
"""

from .normalization import SimilarityNormalizer
from .reflective import (epipole_from_two_pairs, epipole_least_squares, pair_lines,
                         refine_epipole)

__all__ = ["SimilarityNormalizer", "epipole_from_two_pairs", "epipole_least_squares",
           "pair_lines", "refine_epipole"]
