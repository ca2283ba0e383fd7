"""One solve driver for every rig: the single mirror is the rig with one camera and one mirror.

:func:`solve` takes a :class:`~.rig.Rig` (cameras with their initial poses, which of
them are estimated, mirrors with their initial planes, views with their keypoints)
and a :class:`~.stages.SolveConfig` that says what varies between a well-initialised
single mirror (:func:`~.stages.single_mirror_config`) and a rig chained from pairwise
estimates (:func:`~.stages.rig_config`), as COLMAP's bundle adjuster takes one
configuration for every problem. The stages themselves (triangulation and
cleaning, warm start, gauge, the full-graph solves with rejection between them,
the joints pass, marginals and noise) are in :mod:`.stages`.

Videos longer than ``options.max_graph_frames`` frames: a rig of one fixed camera
and one mirror is solved in chunks sharing the mirror (:mod:`.chunked`); any other
rig on that many frames spread over the video, the other frames triangulated with
the result.
"""

from __future__ import annotations

import numpy as np

from .chunked import solve_chunked
from .options import RefineOptions
from .rig import Rig
from .stages import Counter, Progress, SolveConfig, SolveState, solve_rows, spread_rows, triangulate_rig

__all__ = ["solve"]


def solve(rig: Rig, opts: RefineOptions, config: SolveConfig, *,
          height: float | None = None, progress: Progress | None = None,
          counter: Counter | None = None) -> SolveState:
    """Solve a rig (see the module docstring).

    Args:
        rig: cameras (initial poses; ``estimate_pose`` says which vary), mirrors (initial
            planes), views (pixels, observation masks), the joints to estimate.
        opts: weights, kernels, thresholds and solver settings.
        config: what varies (:func:`single_mirror_config`, :func:`rig_config`).
        height: the subject's height in the output unit: the gauge (``None``: the sum
            of the bone lengths keeps its initial value, lengths in the unit of the
            initial rig).
        progress: ``progress(iteration, error)`` per accepted step.

    Raises:
        DegenerateGeometryError: too few joints seen twice, or a camera or mirror left
            without keypoints.
    """
    counter = counter or Counter(progress)
    T = rig.num_frames
    if T > opts.max_graph_frames and config.chunks and _one_camera_one_mirror(rig):
        return solve_chunked(rig, opts, config, height, counter)
    rows = spread_rows(T, opts.max_graph_frames)
    sub = rig.subset(rows) if not rows.all() else rig
    state = solve_rows(sub, opts, config, height, counter)
    if not rows.all():                          # every frame: triangulated with the result
        full, ok = triangulate_rig(rig, [v.mask for v in rig.views], state.poses, state.planes)
        full[np.flatnonzero(rows)] = np.where(state.used[..., None], state.points, full[rows])
        ok[np.flatnonzero(rows)] |= state.used
        state.points, state.used = full, ok
    return state


def _one_camera_one_mirror(rig: Rig) -> bool:
    return (len(rig.cameras) == 1 and len(rig.mirrors) == 1 and len(rig.views) == 2
            and not rig.cameras[0].estimate_pose)


