"""Videos too long for one graph: a spread subset first, then every frame in chunks.

One graph of 1000 frames x 12 joints peaks at ~100 MB during elimination, so
54,000 frames would need ~5 GB. Above ``options.max_graph_frames`` frames:

1. **Subset.** The driver (:mod:`.solve`) on contiguous blocks of
   ``options.chunk_block_frames`` frames spread evenly over the video,
   ``max_graph_frames`` frames in all (blocks, not single frames, so that the
   smoothness prior still has neighbours). This fixes the scale (the bone-length
   sum), gives the bone lengths and a mirror within a few standard deviations
   of the full-video estimate.
2. **Chunks, shared globals.** The video is cut into consecutive chunks of at most
   ``max_graph_frames`` frames (smoothness factors that would cross a cut are
   dropped: two per joint and cut). Each chunk is triangulated with the current
   mirror, cleaned as the driver cleans (:mod:`.solve`), and its
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
   (:func:`mirrorgraph.graph.stages.joints_pass`).

Time is linear in the number of frames (each pass visits each frame once);
memory is bounded by one chunk.
"""

from __future__ import annotations

import time
from dataclasses import replace

import gtsam
import numpy as np

from ..errors import DegenerateGeometryError
from ..factors import DistancePriorFactor, plane_from_gtsam
from .builder import build_problem, extract_points, snap_virtual_poses
from .optimizer import dense_system, reduced_covariance
from .options import RefineOptions
from .outliers import observation_outliers
from .rig import Rig
from .stages import (MIN_PAIRS, SolveState, clean_views, joints_pass, optimize,
                     reprojection_noise_px, seen_twice, solve_rows, undetermined, with_views)

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


def solve_chunked(rig: Rig, opts: RefineOptions, config, height: float | None, counter):
    """Subset solve, then chunk passes with a shared global step (see the module docstring).

    Args:
        rig: one fixed camera, one mirror (its initial plane), two views.
        opts, config, height, counter: as :func:`mirrorgraph.graph.solve.solve`.

    Returns:
        :class:`mirrorgraph.graph.stages.SolveState` for the whole video.
    """
    if height is not None:
        opts = replace(opts, subject_height=float(height))
    T = rig.num_frames
    rows = spread_blocks(T, opts.max_graph_frames, opts.chunk_block_frames)
    # the subset's joints are not kept (every chunk is solved again): no joints pass there
    sub = solve_rows(rig.subset(rows), opts, replace(config, joints_pass=False), height, counter)
    timings = dict(sub.timings)
    stages = [dict(s, name="subset: " + s["name"]) for s in sub.stages]
    iterations = sub.iterations
    plane = (np.asarray(sub.planes[0][0], dtype=float), float(sub.planes[0][1]))
    pose = sub.poses
    lengths = dict(sub.bone_lengths)
    length_sum = sub.prior_info.get("length_sum_gauge", {}).get("sum")
    kernel = next((s.get("kernel") for s in reversed(sub.stages) if "kernel" in s), None)

    information = None
    final_error = 0.0
    rejected = 0
    carried: dict[int, tuple] = {}
    out_masks = [np.zeros((T, rig.skeleton.num_joints), bool) for _ in rig.views]
    for npass in range(1, opts.chunk_passes + 1):
        next_carried: dict[int, tuple] = {}
        H = g = None
        out_points = np.full((T, rig.skeleton.num_joints, 3), np.nan)
        out_used = np.zeros((T, rig.skeleton.num_joints), dtype=bool)
        final_error, n_repro, last = 0.0, 0, None
        t_pass = time.perf_counter()
        for ci, (a, b) in enumerate(chunk_ranges(T, opts.max_graph_frames)):
            crig = rig.subset(slice(a, b))
            t = time.perf_counter()
            if ci in carried:
                # later passes start from the previous pass (same pairs)
                cpoints, cmasks = carried.pop(ci)
            else:
                cpoints, cmasks, _, _ = clean_views(crig, [np.asarray(v.mask, bool) for v in crig.views],
                                               pose, [plane], opts, config, opts.min_parallax_deg)
            keep = seen_twice(cmasks) & np.isfinite(cpoints).all(-1)
            timings["solve"] += time.perf_counter() - t
            problem, values, res = None, None, None
            for attempt in range(2):
                if np.count_nonzero(keep) < MIN_PAIRS:
                    break
                t = time.perf_counter()
                if problem is not None:
                    cpoints = extract_points(problem, values)
                problem = build_problem(with_views(crig, cmasks), cpoints, keep, [plane], opts,
                                        body_height=sub.body_height, bone_lengths=lengths,
                                        length_sum=length_sum, final_kernel=kernel)
                snap_virtual_poses(problem, problem.values)
                timings["build"] += time.perf_counter() - t
                t = time.perf_counter()
                res, z_keys = optimize(problem, problem.full(), opts, distance_gauge=None,
                                       hold_globals=True, progress=counter)
                values = res.values
                iterations += res.iterations
                pts = extract_points(problem, values)
                lost = undetermined(problem, res)
                cmasks, dropped = observation_outliers(crig, pts, problem.used & ~lost, cmasks, pose, [plane],
                                         opts.outlier_threshold)
                cmasks = [m & ~lost for m in cmasks]
                keep = problem.used & seen_twice(cmasks)
                timings["solve"] += time.perf_counter() - t
                if not dropped and not lost.any():
                    break
            if problem is None or res.reduced_information is None:
                continue
            out_points[a:b] = extract_points(problem, values)
            out_used[a:b] = problem.used
            for k, v in enumerate(problem.rig.views):
                out_masks[k][a:b] = np.asarray(v.mask, bool) & problem.used
            next_carried[ci] = (out_points[a:b], [np.asarray(v.mask, bool)
                                                  for v in problem.rig.views])
            final_error += res.final_error
            n_repro += int(problem.reprojection.size())
            H = res.reduced_information if H is None else H + res.reduced_information
            g = res.reduced_gradient if g is None else g + res.reduced_gradient
            last = (problem, values, z_keys)
        if last is None:
            raise DegenerateGeometryError("no chunk of the video could be solved")
        # the shared global step: chunks + distance gauge (the bone lengths are held at
        # the subset's)
        problem, values, z_keys = last
        zv = _globals_values(problem, values)
        glob = gtsam.NonlinearFactorGraph()
        if problem.distance_gauge is not None:
            glob.push_back(DistancePriorFactor(problem.distance_gauge).make(problem.plane_keys[0]))
        if glob.size():
            Hg, gg = dense_system(glob.linearize(zv), z_keys)
            H, g = H + Hg, g + gg
            final_error += float(glob.error(zv))
        information = H
        z = np.linalg.solve(H, g)
        zlen = float(np.sqrt(max(z @ H @ z, 0.0)))
        zv = _apply_step(zv, z_keys, z)
        plane_key = problem.plane_keys[0]
        plane = _plane(zv, plane_key)
        rejected = int(sum(np.count_nonzero(np.asarray(v.mask, bool) & ~m)
                           for v, m in zip(rig.views, out_masks)))
        stages.append({"name": "chunk pass %d" % npass, "iterations": None,
                       "initial_error": None, "final_error": final_error, "converged": None,
                       "rejected": rejected, "global_step_sigma": zlen,
                       "seconds": time.perf_counter() - t_pass})
        if zlen <= opts.chunk_step_tolerance:
            break
        carried = next_carried
    del last, problem, values, res      # one chunk's graph in memory at a time
    _joints_pass_chunks(rig, next_carried, plane, lengths, sub.body_height, opts,
                        kernel, out_points, stages, timings)
    t = time.perf_counter()
    noise_px = reprojection_noise_px(rig, out_masks, pose, [plane], 3)
    factor = (noise_px / opts.pixel_sigma) ** 2 if np.isfinite(noise_px) else 1.0
    basis = [np.asarray(zv.atOrientedPlane3(plane_key).normal().basis())]
    plane_cov = [np.full((3, 3), np.nan)]
    if opts.marginals:
        plane_cov = [reduced_covariance(information, z_keys)[int(plane_key)] * factor]
    timings["marginals"] = time.perf_counter() - t
    return SolveState(poses=pose, planes=[plane], points=out_points, used=out_used,
                      bone_lengths={k: float(v) for k, v in lengths.items()}, scale=sub.scale,
                      camera_cov=[np.zeros((6, 6))], plane_cov=plane_cov, plane_basis=basis,
                      noise_px=noise_px, variance_factor=factor, view_masks=out_masks,
                      rejected=rejected, undetermined=sub.undetermined,
                      prior_info=sub.prior_info, reprojection_factors=n_repro,
                      iterations=iterations, final_error=final_error, stages=stages,
                      timings=timings, body_height=sub.body_height, information=information,
                      z_keys=z_keys, z_values=zv, problem=None)


def _joints_pass_chunks(rig: Rig, chunks: dict[int, tuple], plane: tuple[np.ndarray, float],
                        lengths: dict, body_height: float, opts: RefineOptions,
                        kernel, out_points: np.ndarray, stages: list[dict], timings: dict) -> None:
    """The joints pass (:func:`mirrorgraph.graph.stages.joints_pass`) chunk by chunk with
    the final mirror and bone lengths held, writing the smoothed joints into
    ``out_points`` ``(T, J, 3)`` (in place). The mirror held, chunks are independent."""
    if opts.joints_smoothness_sigma is None or not chunks:
        return
    t = time.perf_counter()
    iterations, done = 0, 0
    for ci, (a, b) in enumerate(chunk_ranges(rig.num_frames, opts.max_graph_frames)):
        if ci not in chunks:
            continue
        cpoints, cmasks = chunks[ci]
        keep = seen_twice(cmasks) & np.isfinite(cpoints).all(-1)
        if np.count_nonzero(keep) == 0:
            continue
        base = build_problem(with_views(rig.subset(slice(a, b)), cmasks), cpoints, keep, [plane],
                             replace(opts, use_bone_length=False, subject_height=None),
                             body_height=body_height, final_kernel=kernel)
        snap_virtual_poses(base, base.values)
        jp = joints_pass(base, base.values, lengths, opts)
        if jp is None:
            return
        problem, res = jp
        out_points[a:b] = extract_points(problem, res.values)
        iterations += res.iterations
        done += 1
    timings["solve"] += time.perf_counter() - t
    stages.append({"name": "joints pass (mirror held, smoothness %g h), %d chunks"
                   % (opts.joints_smoothness_sigma, done), "iterations": iterations,
                   "initial_error": None, "final_error": None, "converged": None, "rejected": 0,
                   "seconds": time.perf_counter() - t})


# --------------------------------------------------------------------------- helpers
def _globals_values(problem, values: gtsam.Values) -> gtsam.Values:
    zv = gtsam.Values()
    for k in problem.plane_keys:
        zv.insert(k, values.atOrientedPlane3(k))
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
