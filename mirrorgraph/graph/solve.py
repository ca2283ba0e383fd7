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
disagreement. A chunked video's focal lengths are its spread subset's, judged as a video
of the subset's length (:func:`judge_focal`, the estimator's bias in the std: it does
not shrink with frames) and held in the chunks.
"""

from __future__ import annotations

import numpy as np

from dataclasses import replace

from ..errors import DegenerateGeometryError
from ..keypoints import MIN_PAIRS
from .chunked import solve_chunked
from .marginals import floor_focal, intrinsics_spread
from .options import RefineOptions
from .rig import (Rig, parallax_deg, seen_twice, spread_rows, triangulate_rig, view_projections,
                  with_intrinsics, with_views)
from .solve_graph import Progress
from .solve_state import SolveState
from .stage_config import SolveConfig
from .stages import Counter, solve_rows

__all__ = ["solve", "judge_focal", "undetermined_focal", "focal_bias", "FOCAL_BIAS_FRAMES"]


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
    if _chunked(rig, opts, config):             # judges the subset's focal lengths itself
        state = solve_chunked(rig, opts, config, height, counter, judge=judge_focal)
        state.camera_spread, state.plane_spread = intrinsics_spread(state)
        return state
    state = _solve(rig, opts, config, height, counter)
    judge_focal(state, rig, opts, config, height)
    return state


def judge_focal(state: SolveState, rig: Rig, opts: RefineOptions,
                config: SolveConfig | None = None, height: float | None = None) -> None:
    """The estimated focal lengths' headline stds and verdicts, in place.

    The cameras the data do not determine (:func:`undetermined_focal`, in
    ``state.focal_undetermined``) get their prior's variance where the data's own std is
    that large or the estimate is at an end of the lenses searched (``data_open``), and
    the initial search's disagreement as their std where the data hold the focal
    length but the search, over every bone, puts it further than
    ``opts.focal.fallback_rel_std`` away (:func:`~.marginals.floor_focal`). Every other
    camera's std is the data's own with the estimator's bias added in quadrature
    (:func:`focal_bias`, with ``config``; in ``state.focal_bias``): the search and the
    graph measure the same bones, so a bias they share is in neither their
    disagreement nor the scores, and a disagreement within the search's own sampling
    noise (its ``opts.focal.search_frames`` frames) is no bias. On 40 scenes of 500
    frames (``bench/RESULTS_focal_std.md``) the focal |error| / std of the 31 scenes
    called determined had a median of 0.59 with the disagreement as a floor and no
    bias, 2 scenes beyond 4 std (-9.0 % at 1.6 %, +6.3 % at 1.5 %); with the bias alone
    0.82 and none beyond 2.3. Last, what the headline adds to every camera and plane
    (:func:`~.marginals.intrinsics_spread`).
    """
    floor_focal(state, disagreement=False)
    undetermined = undetermined_focal(state, rig, opts)
    state.focal_undetermined = {rig.cameras[i].name: v for i, v in undetermined.items()}
    open_ = {i for i, v in undetermined.items() if v["data_open"]}
    if any(not v["data_open"] for v in undetermined.values()):
        floor_focal(state, open_)               # the search's disagreement is the std
    elif open_:
        floor_focal(state, open_, disagreement=False)
    if config is not None:
        skip = set(undetermined)
        bias = focal_bias(state, rig, opts, config, height, skip=skip)
        state.focal_bias = {rig.cameras[i].name: v for i, v in bias.items()}
        if bias:
            floor_focal(state, open_, disagreement=False,
                        model_var={i: v["bias_var_px2"] for i, v in bias.items()})
    state.camera_spread, state.plane_spread = intrinsics_spread(state)


def focal_bias(state: SolveState, rig: Rig, opts: RefineOptions, config: SolveConfig,
               height: float | None, skip: set[int] = frozenset(), *,
               replicates: int | None = None, seed: int = 0) -> dict[int, dict]:
    """The bias of the estimated focal lengths under the data's own noise: a parametric
    bootstrap (Efron and Tibshirani 1993, ch. 10).

    Only the bones determine a focal length, measured on joints the graph estimates with
    the mirror: ``T x J`` incidental parameters, whose noise does not average out over
    frames (Neyman and Scott, *Econometrica* 16, 1948). The focal length is then biased
    by the pixel noise itself, at second order, by an amount the scene's geometry sets
    (the rays' angles, the depths, the poses): on a wide scene at 4 px
    (``make_wide_scene(2300, "wide")`` with its principal point shifted, 500 frames) the
    estimate is -9.0 % off, -6.6 % with each of two fresh draws of the noise, +0.8 %
    without noise, at a reported std of 1.6 %. The initial search shares that bias (it
    measures the same bones), so their disagreement does not show it, nor does any
    figure of the scores (first order).

    The replicates measure it: the calibration graph's own joints
    (``state.calibration_points``: the fit whose bones hold the focal length, not the
    joints pass's, whose torso is held nearly rigid) seen through the solved cameras and
    mirrors wherever the data held an observation, solved again by the graph from the
    solution (the last stage's kernel, nothing rejected), once without noise (the
    reference: the solved joints' bones are not exactly rigid, and the noiseless solve
    moves by that alone, +4.7 % on the scene above) and ``opts.focal.bias_replicates``
    times with each coordinate drawn with the a posteriori pixel sigma
    (``state.noise_px``, over the square root of a column's weight). With ``b`` the noisy
    replicates' mean focal length minus the reference's and ``s^2`` the variance of that
    mean (the replicates' marginal variance over their count), the squared bias is
    ``max(b^2, s^2)``: its unbiased estimate ``b^2 - s^2`` (clipped at 0) plus that
    estimate's own sampling variance, so that a replicate whose draw happens to land
    near the reference does not call the bias absent (a bias within ``s`` of zero is
    not resolved). That variance is added to the data's. On the scene above ``b`` is
    -5.4 % (the std becomes 5.7 %: error / std 6.1 -> 1.7). On 20 scenes of
    ``bench/RESULTS_focal_bias.md`` with 6 single-replicate draws each, |error| / std
    beyond 3 in 1 % of the draws (the joints pass's joints and ``b^2 - s^2``: 10 %;
    more replicates of the latter: 8 % with 2, 5 % with 3). The initial search is not
    run again: with it the figures were the same (-73 against -75 px there, +58
    against +62 px on another).

    Args:
        state: the solution (joints, poses, planes, intrinsics, noise).
        rig: the rig it solved (views, masks, cameras).
        opts, config, height: the solve's options, configuration and gauge.
        skip: camera indices not to measure (their focal length left open).
        replicates: noisy replicates (default ``opts.focal.bias_replicates``; 0: none).
        seed: the noise's seed (the figure is reproducible).

    Returns:
        camera index -> ``{"bias_px", "bias_var_px2", "replicate_std_px", "focal_px",
        "noiseless_px", "replicates"}`` (px; ``bias_var_px2`` px^2) for every estimated
        focal length measured (none where no camera is, or a replicate fails: a
        degenerate draw leaves the data's std alone).
    """
    cams = [i for i, c in enumerate(rig.cameras) if c.estimate_focal and i not in skip
            and i < len(state.intrinsics)]
    noise = float(state.noise_px)
    if not cams or not np.isfinite(noise) or noise <= 0 or state.points is None:
        return {}
    R = opts.focal.bias_replicates if replicates is None else int(replicates)
    if R < 1:
        return {}
    rows = spread_rows(rig.num_frames, min(opts.max_graph_frames, FOCAL_BIAS_FRAMES))
    truth = state.points if state.calibration_points is None else state.calibration_points
    points = np.asarray(truth, float)[rows]
    used = np.asarray(state.used, bool)[rows] & np.isfinite(points).all(-1)
    solved = with_intrinsics(rig, [np.asarray(K, float) for K in state.intrinsics])
    solved = with_views(solved, [np.asarray(v.mask, bool) for v in rig.views],
                        state.poses, state.planes).subset(rows)
    masks = [np.asarray(v.mask, bool) & used for v in solved.views]
    if np.count_nonzero(seen_twice(masks)) < MIN_PAIRS:
        return {}
    clean = []
    for P, v in zip(view_projections(solved, state.poses, state.planes), solved.views):
        X = np.concatenate([np.where(used[..., None], points, 0.0),
                            np.ones(points.shape[:2] + (1,))], axis=-1) @ P.T
        clean.append(X[..., :2] / np.where(np.abs(X[..., 2:]) > 1e-12, X[..., 2:], 1e-12))
    last = replace(config.stages[-1], reject_px=None, bone_outliers=False,
                   only_if_rejected=False, cap_if_outliers=None)
    solved = with_views(solved, masks)
    rconfig = replace(config, stages=(last,), first_rejection=False, warm_start=False,
                      joints_pass=False, chunks=False, focal_search=False)
    ropts = replace(opts, marginals=True)
    rng = np.random.default_rng(seed)
    found = {i: [] for i in cams}
    for r in range(R + 1):                       # the first without noise: the reference
        views = []
        for v, px, m in zip(solved.views, clean, masks):
            w = (np.ones(px.shape[1]) if v.weight is None else np.asarray(v.weight, float))
            sd = noise / np.sqrt(np.maximum(w, 1e-12)) if r else np.zeros(px.shape[1])
            drawn = px + rng.normal(size=px.shape) * sd[None, :, None]
            views.append(replace(v, pixels=np.where(m[..., None], drawn, np.nan), mask=m))
        try:
            rep = solve_rows(replace(solved, views=tuple(views)), ropts, rconfig, height,
                             Counter(None))
        except (DegenerateGeometryError, np.linalg.LinAlgError, RuntimeError):
            return {}                       # a degenerate draw: the data's std alone
        for i in cams:
            var = float(rep.intrinsics_cov[i][0, 0]) if i < len(rep.intrinsics_cov) else np.nan
            found[i].append((float(np.asarray(rep.intrinsics[i])[0, 0]), var))
    out = {}
    for i in cams:
        f = float(np.asarray(state.intrinsics[i])[0, 0])
        ref = found[i][0][0]
        fr = np.array([x for x, _ in found[i][1:]])
        var = np.array([v for _, v in found[i][1:]])
        if not (np.isfinite(ref) and np.all(np.isfinite(fr)) and np.all(np.isfinite(var))):
            continue
        b = float(fr.mean() - ref)
        s2 = float(var.mean() / len(fr))
        out[i] = {"bias_px": b, "bias_var_px2": max(b * b, s2),
                  "replicate_std_px": float(np.sqrt(var.mean())), "focal_px": f,
                  "noiseless_px": float(ref), "replicates": [float(x) for x in fr]}
    return out


#: The most frames (spread over the video) of each replicate of :func:`focal_bias`: the
#: bias does not shrink with more frames, the replicate's own noise ``s`` does (and with
#: it the floor ``s^2`` of the squared bias; a long video's replicates cost what a video
#: of this length costs).
FOCAL_BIAS_FRAMES = 1000


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
        not finite, where the initial search's estimate lies more than ``limit`` (of the
        estimate) away, or where the estimate lies at an end of the plausible cameras
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
        search = [st["focal_px"] for st in getattr(state, "stages", ())
                  if st.get("focal_px") is not None]
        apart = (abs(float(search[-1]) - f) / f if search and f > 0 else 0.0)
        if not np.isfinite(rel) or rel > limit or edge or narrow or apart > limit:
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
    rows = spread_rows(T, opts.max_graph_frames)
    sub = rig.subset(rows) if not rows.all() else rig
    state = solve_rows(sub, opts, config, height, counter)
    if not rows.all():                          # every frame: triangulated with the result
        full, ok = triangulate_rig(rig, [v.mask for v in rig.views], state.poses, state.planes)
        idx = np.flatnonzero(rows)
        if state.calibration_points is not None:
            own = full.copy()
            own[idx] = np.where(state.used[..., None], state.calibration_points, full[rows])
            state.calibration_points = own
        full[idx] = np.where(state.used[..., None], state.points, full[rows])
        ok[idx] |= state.used
        state.points, state.used = full, ok
    return state


def _chunked(rig: Rig, opts: RefineOptions, config: SolveConfig) -> bool:
    """Whether :func:`solve` solves ``rig`` in chunks (:mod:`.chunked`)."""
    return (rig.num_frames > opts.max_graph_frames and config.chunks
            and _one_camera_one_mirror(rig))


def _one_camera_one_mirror(rig: Rig) -> bool:
    return (len(rig.cameras) == 1 and len(rig.mirrors) == 1 and len(rig.views) == 2
            and not rig.cameras[0].estimate_pose)


