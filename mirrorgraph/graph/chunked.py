"""Videos too long for one graph: a spread subset first, then every frame in chunks.

One graph of 1000 frames x 12 joints peaks at ~100 MB during elimination, so
54,000 frames would need ~5 GB. Above ``options.max_graph_frames`` frames:

1. **Subset.** :func:`mirrorgraph.graph.refine.solve_single` on contiguous blocks of
   ``options.chunk_block_frames`` frames spread evenly over the video,
   ``max_graph_frames`` frames in all (blocks, not single frames, so that the
   smoothness prior still has neighbours). This fixes the scale (the bone-length
   sum), gives the bone lengths and a mirror within a few standard deviations
   of the full-video estimate.
2. **Chunks, shared globals.** The video is cut into consecutive chunks of at most
   ``max_graph_frames`` frames (smoothness factors that would cross a cut are
   dropped: two per joint and cut). Each chunk is triangulated with the current
   mirror, cleaned (:func:`~mirrorgraph.graph.refine.first_outliers`), and its
   points are solved with the mirror and bone lengths *held*
   (:class:`~mirrorgraph.graph.optimizer.LevenbergMarquardt` with
   ``hold_globals=True``), with the second rejection and re-solve as in the
   single graph. Each chunk also returns its Schur complement on the global
   coordinates ``z = (bone lengths, plane)`` and its reduced gradient: the
   information every frame carries about the mirror with that chunk's points
   eliminated. Only one chunk is in memory at a time.
3. **Shared step.** Summing the chunks' reduced systems and the length-only
   factors (symmetry, anthropometry, gauge) gives the Gauss-Newton step of the
   globals over the whole video; it is applied and the chunks are solved again
   with the new mirror, until the step is below ``global_step_tolerance``
   standard deviations (or ``chunk_passes`` passes). The covariance of the mirror
   comes from the summed information of the last pass, so it reflects every frame.
4. **Joints pass.** Chunk by chunk, the 3D joints are solved again with the final
   mirror and bone lengths held and the tighter smoothness of
   ``joints_smoothness_sigma``, as for a short video
   (:func:`mirrorgraph.graph.refine.joints_pass`).

Time is linear in the number of frames (each pass visits each frame once);
memory is bounded by one chunk.
"""

from __future__ import annotations

import time
from typing import Callable

import gtsam
import numpy as np

from ..errors import DegenerateGeometryError
from ..factors import DistancePriorFactor, plane_from_gtsam
from .builder import build_problem, cheirality_guard, extract_points, snap_virtual_poses
from .optimizer import LevenbergMarquardt, dense_system
from .options import RefineOptions
from .reduction import mirror_reduction
from .rig import Rig

__all__ = ["solve_chunked", "spread_blocks", "chunk_ranges"]


def spread_blocks(T: int, frames: int, block: int) -> np.ndarray:
    """``(T,)`` bool: about ``frames`` rows in contiguous blocks of ``block``, spread evenly."""
    mask = np.zeros(T, dtype=bool)
    if T <= frames:
        mask[:] = True
        return mask
    block = max(1, min(block, frames))
    count = max(1, frames // block)
    starts = np.linspace(0, T - block, count).round().astype(int)
    for s in starts:
        mask[s:s + block] = True
    return mask


def chunk_ranges(T: int, size: int) -> list[tuple[int, int]]:
    """Consecutive ``(start, stop)`` row ranges of at most ``size`` rows, of equal length."""
    count = max(1, int(np.ceil(T / max(size, 1))))
    edges = np.linspace(0, T, count + 1).round().astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def solve_chunked(rig: Rig, used: np.ndarray, d0: float, opts: RefineOptions,
                  progress: Callable[[int, float], None] | None = None):
    """Subset solve, then chunk passes with a shared global step (see the module docstring).

    Returns:
        :class:`mirrorgraph.graph.refine.SolveState` for the whole video.
    """
    from .refine import (MIN_PAIRS, SolveState, _Counter, _build_full, first_outliers,
                         in_front, lm_params, reject_outliers, solve_single, triangulate_rig,
                         undetermined)

    T = rig.num_frames
    counter = _Counter(progress)
    rows = spread_blocks(T, opts.max_graph_frames, opts.chunk_block_frames)
    sub = solve_single(rig.subset(rows), used[rows], d0, opts, counter)
    timings = dict(sub.timings)
    stages = [dict(s, name="subset: " + s["name"]) for s in sub.stages]
    iterations = sub.iterations
    plane = (np.asarray(sub.normal, dtype=float), float(sub.distance))
    lengths = dict(sub.bone_lengths)
    length_sum = sub.prior_info.get("length_sum_gauge", {}).get("sum")

    information = None
    final_error = 0.0
    carried: dict[int, tuple] = {}
    for npass in range(1, opts.chunk_passes + 1):
        next_carried: dict[int, tuple] = {}
        H = g = None
        out_points = np.full(used.shape + (3,), np.nan)
        out_used = np.zeros(used.shape, dtype=bool)
        final_error, n_repro, last = 0.0, 0, None
        t_pass = time.perf_counter()
        for ci, (a, b) in enumerate(chunk_ranges(T, opts.max_graph_frames)):
            crig = rig.subset(slice(a, b))
            t = time.perf_counter()
            if ci in carried:
                # later passes start from the previous pass (same pairs, same kernel)
                cpoints, keep, kernel = carried.pop(ci)
            else:
                cused = used[a:b]
                cpoints = triangulate_rig(crig, cused, [plane])
                cused = cused & in_front(cpoints, *plane)
                keep = cused & ~first_outliers(crig, cpoints, cused, [plane], opts)
                kernel = opts.final_kernel
                if kernel == "auto":
                    found = np.count_nonzero(cused & ~keep)
                    kernel = ("geman_mcclure"
                              if found > opts.auto_kernel_fraction * cused.sum() else None)
            timings["solve"] += time.perf_counter() - t
            problem, values = None, None
            for attempt in range(2):
                if np.count_nonzero(keep) < MIN_PAIRS:
                    break
                t = time.perf_counter()
                if problem is None:
                    problem = build_problem(_masked(crig, keep), cpoints, keep, [plane], opts,
                                            body_height=sub.body_height,
                                            bone_lengths=lengths, length_sum=length_sum,
                                            final_kernel=kernel)
                else:
                    problem = _build_full(crig, problem, values, cpoints, keep, [plane], opts,
                                          kernel)
                snap_virtual_poses(problem, problem.values)
                timings["build"] += time.perf_counter() - t
                t = time.perf_counter()
                red = mirror_reduction(problem, with_lengths=True, distance_gauge=None)
                lm = LevenbergMarquardt(problem.frame_factors(), red, lm_params(opts, problem),
                                        ordering=problem.point_ordering(), hold_globals=True,
                                        guard=cheirality_guard(problem))
                res = lm.optimize(problem.values, counter)
                values = res.values
                iterations += res.iterations
                keep = reject_outliers(problem, values, opts) & ~undetermined(problem, res)
                timings["solve"] += time.perf_counter() - t
                if not (problem.used & ~keep).any():
                    break
            if problem is None or res.reduced_information is None:
                continue
            out_points[a:b] = extract_points(problem, values)
            out_used[a:b] = problem.used
            next_carried[ci] = (out_points[a:b], problem.used.copy(), kernel)
            final_error += res.final_error
            n_repro += int(problem.reprojection.size())
            H = res.reduced_information if H is None else H + res.reduced_information
            g = res.reduced_gradient if g is None else g + res.reduced_gradient
            last = (problem, values, red)
        if last is None:
            raise DegenerateGeometryError("no chunk of the video could be solved")
        # the shared global step: chunks + length-only factors + distance gauge
        problem, values, red = last
        zv = _globals_values(problem, values)
        glob = problem.global_factors()
        if problem.distance_gauge is not None:
            glob.push_back(DistancePriorFactor(problem.distance_gauge).make(problem.plane_keys[0]))
        if glob.size():
            Hg, gg = dense_system(glob.linearize(zv), red.z_keys)
            H, g = H + Hg, g + gg
            final_error += float(glob.error(zv))
        information = H
        z = np.linalg.solve(H, g)
        zlen = float(np.sqrt(max(z @ H @ z, 0.0)))
        zv = _apply_step(zv, red.z_keys, z)
        plane_key = problem.plane_keys[0]
        plane = _plane(zv, plane_key)
        if problem.length_key is not None:
            lengths = dict(zip(problem.bone_names, zv.atVector(problem.length_key)))
        stages.append({"name": "chunk pass %d" % npass, "iterations": None,
                       "initial_error": None, "final_error": final_error, "converged": None,
                       "rejected": int(np.count_nonzero(used & ~out_used)),
                       "global_step_sigma": zlen, "seconds": time.perf_counter() - t_pass})
        if zlen <= opts.chunk_step_tolerance:
            break
        carried = next_carried
    z_keys = red.z_keys
    del last, problem, values, red, lm, res      # one chunk's graph in memory at a time
    _joints_pass_chunks(rig, next_carried, plane, lengths, length_sum, sub.body_height, opts,
                        out_points, stages, timings)
    return SolveState(normal=plane[0], distance=plane[1], points=out_points, used=out_used,
                      bone_lengths={k: float(v) for k, v in lengths.items()}, scale=sub.scale,
                      information=information, z_keys=z_keys, z_values=zv,
                      plane_key=plane_key, prior_info=sub.prior_info,
                      reprojection_factors=n_repro, iterations=iterations,
                      final_error=final_error, stages=stages, timings=timings,
                      body_height=sub.body_height)


def _joints_pass_chunks(rig: Rig, chunks: dict[int, tuple], plane: tuple[np.ndarray, float],
                        lengths: dict, length_sum, body_height: float, opts: RefineOptions,
                        out_points: np.ndarray, stages: list[dict], timings: dict) -> None:
    """The joints pass (:func:`mirrorgraph.graph.refine.joints_pass`) chunk by chunk with
    the final mirror and bone lengths held, writing the smoothed joints into
    ``out_points`` ``(T, J, 3)`` (in place). The mirror held, chunks are independent."""
    from .refine import joints_pass

    if opts.joints_smoothness_sigma is None or not chunks:
        return
    t = time.perf_counter()
    iterations, done = 0, 0
    for ci, (a, b) in enumerate(chunk_ranges(rig.num_frames, opts.max_graph_frames)):
        if ci not in chunks:
            continue
        cpoints, keep, kernel = chunks[ci]
        if np.count_nonzero(keep) == 0:
            continue
        problem = build_problem(_masked(rig.subset(slice(a, b)), keep), cpoints, keep, [plane],
                                opts, body_height=body_height, bone_lengths=lengths,
                                length_sum=length_sum, final_kernel=kernel)
        snap_virtual_poses(problem, problem.values)
        res = joints_pass(problem, problem.values, opts)
        if res is None:
            return
        out_points[a:b] = extract_points(problem, res.values)
        iterations += res.iterations
        done += 1
    timings["solve"] += time.perf_counter() - t
    stages.append({"name": "joints pass (mirror held, smoothness %g h), %d chunks"
                   % (opts.joints_smoothness_sigma, done), "iterations": iterations,
                   "initial_error": None, "final_error": None, "converged": None, "rejected": 0,
                   "seconds": time.perf_counter() - t})


# --------------------------------------------------------------------------- helpers
def _masked(rig: Rig, mask: np.ndarray) -> Rig:
    from dataclasses import replace
    return replace(rig, views=tuple(replace(v, mask=np.asarray(v.mask, dtype=bool) & mask)
                                    for v in rig.views))


def _globals_values(problem, values: gtsam.Values) -> gtsam.Values:
    zv = gtsam.Values()
    for k in problem.plane_keys:
        zv.insert(k, values.atOrientedPlane3(k))
    if problem.length_key is not None:
        zv.insert(problem.length_key, values.atVector(problem.length_key))
    return zv


def _apply_step(zv: gtsam.Values, z_keys: list[tuple[int, int]], z: np.ndarray) -> gtsam.Values:
    delta = gtsam.VectorValues()
    off = 0
    for k, d in z_keys:
        delta.insert(int(k), z[off:off + d])
        off += d
    return zv.retract(delta)


def _plane(zv: gtsam.Values, key: int) -> tuple[np.ndarray, float]:
    return plane_from_gtsam(zv.atOrientedPlane3(key))
