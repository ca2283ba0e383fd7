"""One solve driver for every rig: the single mirror is the rig with one camera and one mirror.

:func:`solve` takes a :class:`~.rig.Rig` (cameras with their initial poses, which of
them are estimated, mirrors with their initial planes, views with their keypoints)
and a :class:`~.stage_config.SolveConfig` that says what varies between a well-initialised
single mirror (:func:`~.stage_config.single_mirror_config`) and a rig chained from pairwise
estimates (:func:`~.stage_config.rig_config`), as COLMAP's bundle adjuster takes one
configuration for every problem. The stages themselves (triangulation and
cleaning, warm start, gauge, the full-graph solves with rejection between them,
the joints pass, marginals and noise) are in :mod:`.stages`.

Videos longer than ``options.max_graph_frames`` frames: a rig of one fixed camera
and one mirror is solved in chunks sharing the mirror (:mod:`.chunked`); any other
rig on that many frames spread over the video, the other frames triangulated with
the result.

Estimated intrinsics (:attr:`~.rig.Camera.estimate_focal`): the estimate is kept
whatever the data say about it, with its standard deviation (the posterior under the
priors of the guess, :class:`~.options.FocalOptions`), never replaced by the guess
held exact. A camera whose focal length the data do not determine (its standard
deviation above ``options.focal.fallback_rel_std`` of it, or an estimate at an end of
the lenses searched) is named in :attr:`~.solve_state.SolveState.focal_undetermined` with
the figures found (and the rays' median angle), for the warnings, and carries its
prior's variance (:func:`~.marginals.floor_focal`) where the data's own std is that
large; where only the initial search and the graph disagree that much, their
disagreement.
"""

from __future__ import annotations

import numpy as np

from .chunked import solve_chunked
from .marginals import floor_focal, intrinsics_spread
from .options import RefineOptions
from .rig import Rig, parallax_deg, spread_rows, triangulate_rig
from .solve_graph import Progress
from .solve_state import SolveState
from .stage_config import SolveConfig
from .stages import Counter, solve_rows

__all__ = ["solve", "judge_focal", "undetermined_focal"]


def solve(rig: Rig, opts: RefineOptions, config: SolveConfig, *,
          height: float | None = None, progress: Progress | None = None,
          counter: Counter | None = None) -> SolveState:
    """Solve a rig (see the module docstring).

    Args:
        rig: cameras (initial poses; ``estimate_pose`` says which vary), mirrors (initial
            planes), views (pixels, observation masks), the joints to estimate.
        opts: weights, kernels, thresholds and solver settings.
        config: what varies (:func:`~.stage_config.single_mirror_config`,
            :func:`~.stage_config.rig_config`).
        height: the subject's height in the output unit: the gauge (``None``: the sum
            of the bone lengths keeps its initial value, lengths in the unit of the
            initial rig).
        progress: ``progress(iteration, error)`` per accepted step.

    Raises:
        DegenerateGeometryError: too few joints seen twice, or a camera or mirror left
            without keypoints.
    """
    counter = counter or Counter(progress)
    state = _solve(rig, opts, config, height, counter)
    judge_focal(state, rig, opts)
    return state


def judge_focal(state: SolveState, rig: Rig, opts: RefineOptions) -> None:
    """The estimated focal lengths' headline stds and verdicts, in place: the floor of the
    initial search's disagreement (:func:`~.marginals.floor_focal`), the cameras the data
    do not determine (:func:`undetermined_focal`, in ``state.focal_undetermined``), the
    prior's variance for those whose data's own std is that large (a focal length the
    data hold, on which only the search and the graph disagree, keeps their
    disagreement as its std), and what the headline adds to every camera and plane
    (:func:`~.marginals.intrinsics_spread`)."""
    floor_focal(state)
    undetermined = undetermined_focal(state, rig, opts)
    state.focal_undetermined = {rig.cameras[i].name: v for i, v in undetermined.items()}
    open_ = {i for i, v in undetermined.items() if v["data_open"]}
    if open_:
        floor_focal(state, open_)
    state.camera_spread, state.plane_spread = intrinsics_spread(state)


def undetermined_focal(state: SolveState, rig: Rig, opts: RefineOptions,
                       limit: float | None = None) -> dict[int, dict]:
    """Cameras whose estimated focal length the data do not determine.

    Args:
        limit: the relative std above which a focal length counts as undetermined
            (default ``opts.focal.fallback_rel_std``).

    Returns:
        camera index -> ``{"focal_px", "std_px", "rel_std", "fov_deg"}`` (the estimate,
        its standard deviation: the larger of the marginal and the time-robust figure,
        and its horizontal field of view) where the relative std exceeds ``limit`` or is
        not finite, or where the estimate lies at an end of the plausible cameras
        (within :data:`FOV_EDGE` of ``opts.focal.search_fov_deg``, or beyond): there the
        bones ask for a lens no camera of that range has, which is no minimum of the
        data's but their lack of one (seen on scenes with little depth change: a
        "determined" 20 deg lens, 5x the true focal length, its std 16 %). The record
        says too whether the joints' two rays meet at a median angle under
        :data:`FOCAL_MIN_PARALLAX_DEG` (``low_parallax``: a cause the warning names, not
        a criterion by itself: it would throw good estimates away), the data's own
        relative std (``data_rel_std``: without the floor of two estimates' disagreement,
        :func:`~.marginals.floor_focal`), the initial search's estimate (``search_px``)
        and whether the data leave the focal length open (``data_open``: their own std
        beyond ``limit``, or the estimate at an end of the range), where the solve gives
        it its prior's variance; else only the two estimates disagree beyond ``limit``,
        and their disagreement is its std.
    """
    limit = opts.focal.fallback_rel_std if limit is None else float(limit)
    lo, hi = opts.focal.search_fov_deg
    angles = None                                       # (T, J) ray angles, once
    out = {}
    for i, cam in enumerate(rig.cameras):
        if not cam.intrinsics_dim or i >= len(state.intrinsics_cov):
            continue
        K = np.asarray(state.intrinsics[i], dtype=float)
        f = float(K[0, 0])
        std = float(np.sqrt(max(state.intrinsics_cov[i][0, 0], 0.0)))
        if state.intrinsics_std and i < len(state.intrinsics_std):
            std = max(std, float(state.intrinsics_std[i][0]))
        rel = std / f if f > 0 else float("inf")
        own = float(np.sqrt(max(state.intrinsics_cov[i][0, 0], 0.0)))
        data_std = getattr(state, "intrinsics_data_std", None) or state.intrinsics_std
        if data_std and i < len(data_std) and len(data_std[i]):
            own = max(own, float(data_std[i][0]))
        own_rel = own / f if f > 0 else float("inf")
        fov = float(np.degrees(2.0 * np.arctan(float(K[0, 2]) / f))) if f > 0 else float("nan")
        edge = not (lo * (1.0 + FOV_EDGE) < fov < hi / (1.0 + FOV_EDGE))
        if angles is None and state.points is not None and len(state.view_masks):
            angles = parallax_deg(rig, state.points, state.view_masks, state.poses, state.planes)
        rays = _median_parallax(state, rig, i, angles)
        narrow = bool(rays < FOCAL_MIN_PARALLAX_DEG)
        if not np.isfinite(rel) or rel > limit or edge or narrow:
            search = [st["focal_px"] for st in getattr(state, "stages", ())
                      if st.get("focal_px") is not None]
            out[i] = {"focal_px": f, "std_px": std, "rel_std": rel, "fov_deg": fov,
                      "at_range_end": bool(edge), "parallax_deg": rays,
                      "low_parallax": narrow, "data_rel_std": own_rel,
                      "search_px": float(search[-1]) if search else None,
                      "data_open": bool(not np.isfinite(own_rel) or own_rel > limit or edge
                                        or narrow)}
    return out


def _median_parallax(state: SolveState, rig: Rig, camera: int, ang: np.ndarray | None
                     ) -> float:
    """Median angle between the two rays of the joints camera ``camera`` sees, degrees,
    of the ``(T, J)`` angles ``ang`` (:func:`~.rig.parallax_deg`; ``None``: nan)."""
    if ang is None:
        return float("nan")
    mine = np.zeros_like(state.used)
    name = rig.cameras[camera].name
    for v, m in zip(rig.views, state.view_masks):
        if v.camera == name:
            mine |= np.asarray(m, bool)
    sel = ang[state.used & mine]
    sel = sel[sel > 0]
    return float(np.median(sel)) if sel.size else float("nan")


#: Below this median angle between a joint's two rays the focal length is not taken as
#: determined: there the bones' lengths, which alone determine it, carry a curvature
#: bias that its standard deviation does not contain. Measured on 40 scenes of the four
#: slices (600 frames, no intrinsics): under 20 deg the estimate is 20-46 % off in 5 of
#: 8 scenes with a reported std of 2-8 %; above it, within 4 % on every iid scene. The
#: estimate is kept there too (the guess is worse); this names the cause.
FOCAL_MIN_PARALLAX_DEG = 20.0


#: An estimated focal length whose horizontal field of view is within this fraction of
#: an end of ``FocalOptions.search_fov_deg`` (or beyond it) is not taken as determined.
FOV_EDGE = 0.05


def _solve(rig: Rig, opts: RefineOptions, config: SolveConfig, height: float | None,
           counter: Counter) -> SolveState:
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


