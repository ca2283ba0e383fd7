"""What the solve driver's stages are, per rig: the configuration of :func:`~.solve.solve`.

A :class:`SolveConfig` says what differs between rigs: the full-graph :class:`Stage` s
(each a robust kernel and its scale, the rejection after it), whether outliers are
rejected before the first solve, the warm start, the focal search, the joints pass,
chunking. :func:`single_mirror_config` (a RANSAC-initialised mirror) and
:func:`rig_config` (a rig chained from pairwise estimates) are the two in use; the
driver that runs them is :mod:`.stages`.
"""

from __future__ import annotations

from dataclasses import dataclass

from .options import RefineOptions

__all__ = ["Stage", "SolveConfig", "single_mirror_config", "rig_config",
           "INITIAL_REJECTION_FACTOR"]


@dataclass(frozen=True)
class Stage:
    """One solve of the full graph.

    Attributes:
        name: for the record.
        kernel: robust kernel of the reprojection factors (``"auto"``, a kernel name
            of :func:`mirrorgraph.factors.robust_pixel_noise`, or ``None``: least squares).
        kernel_scale_px: the kernel's scale.
        reject_px: after the stage, observations with a larger residual are dropped
            (``None``: nothing is dropped).
        bone_outliers: after the stage, joints whose bones are all implausible
            (``options.bone_outlier_k``) are dropped too.
        only_if_rejected: run the stage only when the previous one dropped something.
        cap_if_outliers: the stage's most iterations when the first rejection found
            outliers (it only has to expose the rest); ``None``: ``options.max_iterations``.
    """

    name: str
    kernel: str | None
    kernel_scale_px: float
    reject_px: float | None
    bone_outliers: bool = False
    only_if_rejected: bool = False
    cap_if_outliers: int | None = None


@dataclass(frozen=True)
class SolveConfig:
    """What varies between rigs (one driver, :func:`~.solve.solve`).

    Attributes:
        stages: the full-graph solves, in order.
        first_rejection: drop observations beyond the outlier threshold and joints with
            implausible bones after the first triangulation (needs an initial rig good
            to a few pixels: a RANSAC mirror; a chained pairwise rig is not).
        warm_start: reprojection-only iterations on spread frames first (only where
            every camera pose is held: the first mirror's distance is its gauge).
        joints_pass: solve the joints again with the tighter smoothness.
        chunks: long videos of one camera and one mirror in chunks sharing the mirror
            (otherwise: a spread subset of frames).
        focal_search: where the camera's focal length is estimated (one held camera and
            its mirrors), search the focal length that makes the body most rigid
            before the stages (:func:`~.focal_search.focal_search`); the stages then
            estimate it with the rest, and the last stage always runs (the bones it
            keeps are chosen at the new focal length).
    """

    stages: tuple[Stage, ...]
    first_rejection: bool = True
    warm_start: bool = True
    joints_pass: bool = True
    chunks: bool = True
    focal_search: bool = True


def single_mirror_config(opts: RefineOptions) -> SolveConfig:
    """A RANSAC-initialised mirror: the first rejection at once, the kernel chosen by what
    it found, a second solve only if the first exposed more outliers."""
    thr = opts.outlier_threshold
    stages = (Stage("full graph", opts.final_kernel, opts.final_kernel_scale_px, thr,
                    bone_outliers=True, cap_if_outliers=opts.outlier_pass_iterations),
              Stage("final (outliers removed)", opts.final_kernel, opts.final_kernel_scale_px,
                    thr, bone_outliers=True, only_if_rejected=True))
    return SolveConfig(stages=stages)


#: The first solve's robust kernel is this many times wider than the final one, and
#: only observations beyond this many outlier thresholds are dropped after it. The
#: chained pairwise initialisation of a rig can be degrees and decimetres off
#: (residuals of 50-150 px on a 120-frame four-camera rig), which that solve removes;
#: a kernel or a rejection at the final scale would then discard good keypoints.
INITIAL_REJECTION_FACTOR = 5.0


def rig_config(opts: RefineOptions) -> SolveConfig:
    """A rig chained from pairwise estimates: a shrinking kernel, then least squares on
    the inliers; the rejection per observation (a wrong keypoint in one camera does
    not cost the other views)."""
    thr = opts.outlier_threshold
    f = INITIAL_REJECTION_FACTOR
    stages = (Stage("wide kernel", "geman_mcclure", f * opts.final_kernel_scale_px, f * thr,
                    bone_outliers=True),
              Stage("kernel", "geman_mcclure", opts.final_kernel_scale_px, thr),
              Stage("least squares", None, opts.final_kernel_scale_px, None))
    return SolveConfig(stages=stages, first_rejection=False, warm_start=False,
                       joints_pass=False, chunks=False)
