"""Videos too long for one graph: a spread subset first, then every frame in chunks.

One graph of 1000 frames x 12 joints peaks at ~100 MB during elimination (54,000
frames: ~5 GB). Above ``options.max_graph_frames`` frames:

1. **Subset.** The driver's stages (:func:`~.stages.solve_rows`) on contiguous blocks
   of ``options.chunk_block_frames`` frames spread evenly over the video,
   ``max_graph_frames`` frames in all. This fixes the scale (the bone-length sum),
   gives the bone lengths and a mirror within a few of its standard deviations of
   the whole video's.
2. **Chunks, shared globals.** The video is cut into consecutive chunks of at most
   ``max_graph_frames`` frames. Given the mirror and the bone lengths the frames are
   independent (the calibration graph has no smoothness), so each chunk is
   triangulated with the current mirror, cleaned as the driver cleans, and its
   joints are solved with the mirror and bone lengths *held*
   (:class:`~mirrorgraph.graph.optimizer.LevenbergMarquardt` with
   ``hold_globals=True``), with the second rejection and re-solve as in the single
   graph. Each chunk returns its Schur complement on the plane and its reduced
   gradient: the information its frames carry about the mirror with its joints
   eliminated. Only one chunk a worker is in memory at a time.
3. **Shared step.** The sum of the chunks' reduced systems gives the Gauss-Newton
   step of the plane over the whole video from the subset's; one pass by default
   (``options.chunk_passes``; more move the mirror by a fraction of its std). The
   mirror's covariance comes from the summed information of every frame.
4. **Joints pass.** In the same job, on the chunk's calibration graph (built once),
   the joints are solved again with the globals held, the tighter smoothness of
   ``joints_smoothness_sigma`` and every bone (:func:`~.stages.joints_pass`), with
   their sensitivity to the plane's reduced coordinates; the shared step ``z`` moves
   them by ``sensitivity @ z``, the joints pass at the final mirror to first order
   (``bench/RESULTS_long.md``).

An estimated focal length (:attr:`~.rig.Camera.estimate_focal`) is the subset's: the
chunks hold it, and its standard deviation is the subset's (``max_graph_frames``
frames: 2000 carry the focal length to a fraction of a per cent where the data
determine it at all).

The chunks of a pass are independent: they are solved in ``options.workers``
processes (GTSAM holds the interpreter lock, so threads would not help) and
summed in order (the result does not depend on the number of workers); time is
linear in the frames, memory bounded by a chunk per worker.
"""

from __future__ import annotations

import collections
import contextlib
import multiprocessing
import os
import sys
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, replace

import gtsam
import numpy as np

from ..errors import DegenerateGeometryError
from ..factors import DistancePriorFactor, plane_from_gtsam, plane_to_gtsam
from ..keypoints import MIN_PAIRS
from .builder import build_problem
from .marginals import floor_focal
from .noise import reprojection_noise_px
from .optimizer import dense_system, reduced_covariance
from .options import RefineOptions
from .outliers import clean_views, observation_outliers
from .problem import extract_points, snap_virtual_poses
from .rig import Rig, seen_twice, with_views
from .sandwich import held_intrinsics_cov
from .scores import JointScores, joint_scores
from .solve_graph import optimize, undetermined
from .solve_state import SolveState
from .stage_config import SolveConfig
from .stages import joints_pass, solve_rows

__all__ = ["solve_chunked", "spread_blocks", "chunk_ranges", "worker_count"]


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


def worker_count(opts: RefineOptions, jobs: int) -> int:
    """Processes for ``jobs`` independent chunks: ``opts.workers``, or by default the
    machine's cores up to :data:`MAX_AUTO_WORKERS`; never more than the jobs."""
    n = opts.workers if opts.workers is not None else min(os.cpu_count() or 1, MAX_AUTO_WORKERS)
    return max(1, min(int(n), jobs))


#: Most processes chosen by default (each holds one chunk's graph, ~150-250 MB).
MAX_AUTO_WORKERS = 4


# --------------------------------------------------------------------------- chunk jobs
@dataclass
class _Context:
    """What every chunk of a long video shares."""

    opts: RefineOptions
    config: SolveConfig
    pose: list[np.ndarray]
    body_height: float
    lengths: dict[str, float]
    torso: dict[str, float] | None
    length_sum: float | None
    kernel: str | None


@dataclass
class _ChunkResult:
    """One chunk's share of a pass (rows ``a:b`` of the video)."""

    a: int
    b: int
    points: np.ndarray | None = None          # (T_c, J, 3)
    used: np.ndarray | None = None            # (T_c, J)
    masks: list[np.ndarray] | None = None     # per view (T_c, J)
    information: np.ndarray | None = None     # reduced, over the plane
    gradient: np.ndarray | None = None
    z_keys: list | None = None
    plane: tuple[np.ndarray, float] | None = None   # where the reduced system was taken
    distance_gauge: float | None = None
    scores: JointScores | None = None         # frames relative to the chunk
    final_error: float = 0.0
    reprojection_factors: int = 0
    iterations: int = 0
    joints: np.ndarray | None = None          # (T_c, J, 3) the joints pass's
    sensitivity: np.ndarray | None = None     # (T_c, J, 3, nz) its joints per unit z
    joints_masks: list[np.ndarray] | None = None   # per view (T_c, J): the pass's observations
    joints_iterations: int = 0
    joints_seconds: float = 0.0


def _calibrate_chunk(job: tuple) -> _ChunkResult:
    """Solve one chunk's joints with the globals held; return its reduced system, and
    with ``joints_smoothness_sigma`` the joints pass on the same graph with its
    sensitivity to the plane (:func:`_joints_pass`)."""
    crig, a, b, plane, start, ctx = job
    opts, config = ctx.opts, ctx.config
    out = _ChunkResult(a, b)
    if start is None:
        cpoints, cmasks, _, _ = clean_views(crig, [np.asarray(v.mask, bool) for v in crig.views],
                                            ctx.pose, [plane], opts, config, opts.min_parallax_deg)
    else:
        cpoints, cmasks = start
    keep = seen_twice(cmasks) & np.isfinite(cpoints).all(-1)
    problem = values = res = None
    for _ in range(2):
        if np.count_nonzero(keep) < MIN_PAIRS:
            break
        if problem is not None:
            cpoints = extract_points(problem, values)
        problem = build_problem(with_views(crig, cmasks), cpoints, keep, [plane], opts,
                                body_height=ctx.body_height, bone_lengths=ctx.lengths,
                                length_sum=ctx.length_sum, final_kernel=ctx.kernel)
        snap_virtual_poses(problem, problem.values)
        res, z_keys = optimize(problem, problem.full(), opts, distance_gauge=None,
                               hold_globals=True)
        values = res.values
        out.iterations += res.iterations
        pts = extract_points(problem, values)
        lost = undetermined(problem, res)
        cmasks, dropped = observation_outliers(crig, pts, problem.used & ~lost, cmasks, ctx.pose,
                                               [plane], opts.outlier_threshold)
        cmasks = [m & ~lost for m in cmasks]
        keep = problem.used & seen_twice(cmasks)
        if not dropped and not lost.any():
            break
    if problem is None or res.reduced_information is None:
        return out
    out.points, out.used = extract_points(problem, values), problem.used
    out.masks = [np.asarray(v.mask, bool) for v in problem.rig.views]
    out.information, out.gradient, out.z_keys = res.reduced_information, res.reduced_gradient, z_keys
    out.final_error, out.reprojection_factors = res.final_error, int(problem.reprojection.size())
    out.plane = plane_from_gtsam(values.atOrientedPlane3(problem.plane_keys[0]))
    out.distance_gauge = problem.distance_gauge
    if opts.marginals:
        out.scores = joint_scores(problem, values, keep_rows=True)
    _joints_pass(out, problem, values, ctx)
    return out


def _joints_pass(out: _ChunkResult, problem, values: gtsam.Values, ctx: _Context) -> None:
    """The joints pass of a chunk on its calibration graph ``problem`` at its solution
    ``values`` (the mirror it was given held), into ``out``: the joints and their
    ``(T_c, J, 3, nz)`` change per unit of the plane's reduced coordinates (zero where
    a joint is not estimated); nothing without ``joints_smoothness_sigma``."""
    t = time.perf_counter()
    jp = joints_pass(problem, values, ctx.lengths, ctx.opts, sensitivity=True, torso=ctx.torso)
    if jp is None:
        return
    jproblem, res = jp
    T, J = jproblem.used.shape
    out.joints, out.joints_iterations = extract_points(jproblem, res.values), res.iterations
    out.joints_masks = [np.asarray(v.mask, bool) for v in jproblem.rig.views]
    if res.sensitivity is not None:
        sens = np.zeros((T * J, 3, res.sensitivity.shape[-1]))
        sens[jproblem.flat_index] = res.sensitivity
        out.sensitivity = sens.reshape(T, J, 3, -1)
    out.joints_seconds = time.perf_counter() - t


class _Runner:
    """Runs chunk jobs in this process and in ``workers - 1`` more processes at once.

    This process takes jobs from the end of the list while the others take them from
    the front, so that it never idles waiting on them; a thread of this process hands
    the next job to a worker as soon as it is free (a worker does not wait for this
    process's job to end). The results are returned in the jobs' order (the sums do not
    depend on the workers). The workers are started when the runner is made, before the
    subset's solve, so that their start-up (an interpreter, GTSAM's import: about a
    second each) overlaps it.

    The workers are spawned (a fresh interpreter: a forked one would inherit the
    locks of any thread the caller runs, JAX's or PyTorch's say, and may deadlock),
    and while they start the caller's main module is hidden from them: a spawned
    process imports it again otherwise, which would run a user's script that has no
    ``if __name__ == "__main__"`` guard once more. The jobs need nothing from it.
    """

    def __init__(self, workers: int) -> None:
        self.pool = None
        self.size = max(int(workers) - 1, 0)
        # a daemonic process (a Dask or multiprocessing worker) may not have children
        if self.size and not multiprocessing.current_process().daemon:
            self.pool = ProcessPoolExecutor(max_workers=self.size,
                                            mp_context=multiprocessing.get_context("spawn"))
            with _main_hidden():               # spawned now, their imports run meanwhile
                for _ in range(self.size):
                    self.pool.submit(_ready, 0)

    def map(self, fn, jobs: list, counter) -> list[_ChunkResult]:
        out: list = [None] * len(jobs)
        pending = collections.deque(range(len(jobs)))
        lock = threading.Lock()
        failed: list[BaseException] = []

        def take(front: bool) -> int | None:
            with lock:
                if not pending:
                    return None
                return pending.popleft() if front else pending.pop()

        def feed() -> None:                    # the workers' jobs, from the front
            running: dict = {}
            try:
                while True:
                    while len(running) < self.size:
                        i = take(front=True)
                        if i is None:
                            break
                        running[self.pool.submit(fn, jobs[i])] = i
                    if not running:
                        return
                    for f in wait(running, return_when=FIRST_COMPLETED).done:
                        out[running.pop(f)] = f.result()
            except BaseException as exc:      # raised in the caller's thread
                failed.append(exc)
                with lock:
                    pending.clear()
                wait(running)

        reported = 0

        def report() -> None:                  # in order, as the first results complete
            nonlocal reported
            while reported < len(out) and out[reported] is not None:
                reported += 1
                if counter is not None:
                    counter(reported, float(out[reported - 1].final_error))

        feeder = None
        if self.pool is not None:
            feeder = threading.Thread(target=feed, name="mirrorgraph-chunks", daemon=True)
            feeder.start()
        try:
            while (i := take(front=self.pool is None)) is not None:   # this process's jobs
                out[i] = fn(jobs[i])
                report()
        except BaseException:
            with lock:
                pending.clear()
            raise
        finally:
            if feeder is not None:
                feeder.join()
        if failed:
            raise failed[0]
        report()
        return out

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown()


def _ready(_: int) -> int:
    return os.getpid()


@contextlib.contextmanager
def _main_hidden():
    """Hide the ``__main__`` module's name and path from process start-up (see
    :class:`_Runner`)."""
    main = sys.modules.get("__main__")
    saved = {k: getattr(main, k) for k in ("__spec__", "__file__") if hasattr(main, k)}
    try:
        for k in saved:
            setattr(main, k, None)
        yield
    finally:
        for k, v in saved.items():
            setattr(main, k, v)


# --------------------------------------------------------------------------- driver
def solve_chunked(rig: Rig, opts: RefineOptions, config, height: float | None, counter,
                  judge=None):
    """Subset solve, then chunk passes with a shared global step (see the module docstring).

    Args:
        rig: one fixed camera, one mirror (its initial plane), two views.
        opts, config, height, counter: as :func:`mirrorgraph.graph.solve.solve`.
        judge: ``judge(state, rig, opts, config, height)``, the estimated focal lengths'
            headline stds and verdicts (:func:`mirrorgraph.graph.solve.judge_focal`),
            applied to the subset whose focal lengths the chunks hold: its stds (the
            estimator's bias in them), verdicts and bias are the video's, and its
            uncertainty is added to the plane's. ``None``: the disagreement floor alone
            (:func:`~.marginals.floor_focal`).

    Returns:
        :class:`mirrorgraph.graph.solve_state.SolveState` for the whole video.
    """
    if height is not None:
        opts = replace(opts, subject_height=float(height))
    T = rig.num_frames
    rows = spread_blocks(T, opts.max_graph_frames, opts.chunk_block_frames)
    ranges = chunk_ranges(T, opts.max_graph_frames)
    runner = _Runner(worker_count(opts, len(ranges)))
    try:
        return _solve_chunked(rig, opts, config, height, counter, rows, ranges, runner, judge)
    finally:
        runner.close()


def _solve_chunked(rig: Rig, opts: RefineOptions, config, height: float | None, counter,
                   rows: np.ndarray, ranges: list[tuple[int, int]], runner: _Runner, judge):
    """:func:`solve_chunked` with the subset's ``rows``, the chunks' row ``ranges``, the
    ``runner`` of their jobs and the focal lengths' ``judge``."""
    T, J = rig.num_frames, rig.skeleton.num_joints
    # the subset's joints are not kept (every chunk is solved again): no joints pass
    # there; its own uncertainty (the marginals, the joints' scores) serves an estimated
    # intrinsic's only (held in the chunks): the video's comes from the chunks
    estimated = any(c.intrinsics_dim for c in rig.cameras)
    sub_rig, sub_config = rig.subset(rows), replace(config, joints_pass=False)
    sub = solve_rows(sub_rig, opts if estimated else replace(opts, marginals=False),
                     sub_config, height, counter)
    # the subset's estimated intrinsics are held in the chunks: what their uncertainty
    # (the estimator's bias in it) brings to the plane is added to every figure of the
    # whole video's
    held_cov = None
    if sub.scores is not None and estimated:
        if judge is not None:
            judge(sub, sub_rig, opts, sub_config, height)
        else:
            floor_focal(sub)
        held_cov = held_intrinsics_cov(sub.scores)
    # an estimated focal length is the subset's, held in the chunks
    rig = replace(rig, cameras=tuple(replace(c, K=np.asarray(K, float), estimate_focal=False,
                                             estimate_principal_point=False)
                                     for c, K in zip(rig.cameras, sub.intrinsics)))
    timings = dict(sub.timings)
    stages = [dict(s, name="subset: " + s["name"]) for s in sub.stages]
    iterations = sub.iterations
    plane = (np.asarray(sub.planes[0][0], dtype=float), float(sub.planes[0][1]))
    ctx = _Context(opts=opts, config=config, pose=sub.poses, body_height=sub.body_height,
                   lengths=dict(sub.bone_lengths), torso=sub.torso_lengths,
                   length_sum=sub.prior_info.get("length_sum_gauge", {}).get("sum"),
                   kernel=next((s.get("kernel") for s in reversed(sub.stages) if "kernel" in s),
                               None))
    chunks = [rig.subset(slice(a, b)) for a, b in ranges]
    starts: list = [None] * len(ranges)
    for npass in range(1, opts.chunk_passes + 1):
        t_pass = time.perf_counter()
        done = runner.map(_calibrate_chunk, [(c, a, b, plane, s, ctx) for c, (a, b), s
                                             in zip(chunks, ranges, starts)], counter)
        good = [r for r in done if r.information is not None]
        if not good:
            raise DegenerateGeometryError("no chunk of the video could be solved")
        iterations += sum(r.iterations for r in done)
        H, final_error, z_keys, zv, z, zlen = _global_step(good)
        plane = plane_from_gtsam(zv.atOrientedPlane3(z_keys[0][0]))
        seconds = time.perf_counter() - t_pass
        timings["solve"] += seconds
        stages.append({"name": "chunk pass %d (%d chunks)" % (npass, len(ranges)),
                       "iterations": None, "initial_error": None, "final_error": final_error,
                       "converged": None, "rejected": None, "global_step_sigma": zlen,
                       "seconds": seconds})
        starts = [None if r.points is None else (r.points, r.masks) for r in done]
        if zlen <= opts.chunk_step_tolerance:
            break
    information = H
    out_points = np.full((T, J, 3), np.nan)
    out_used = np.zeros((T, J), dtype=bool)
    out_masks = [np.zeros((T, J), bool) for _ in rig.views]
    for r in good:
        out_points[r.a:r.b], out_used[r.a:r.b] = r.points, r.used
        for k, m in enumerate(r.masks):
            out_masks[k][r.a:r.b] = m & r.used
    rejected = int(sum(np.count_nonzero(np.asarray(v.mask, bool) & ~m)
                       for v, m in zip(rig.views, out_masks)))
    stages[-1]["rejected"] = rejected
    n_repro = sum(r.reprojection_factors for r in good)
    solved = [r for r in good if r.joints is not None]
    joints_masks: list[np.ndarray] = []
    own_points = None                 # the chunks' calibration joints (focal_bias's truth)
    if opts.joints_smoothness_sigma is not None and solved:
        own_points = out_points.copy()
        # each chunk's joints pass at the mirror of the last pass, moved by its step,
        # on the observations it kept
        joints_masks = [m.copy() for m in out_masks]
        for r in solved:
            out_points[r.a:r.b] = r.joints
            for k, m in enumerate(r.joints_masks):
                joints_masks[k][r.a:r.b] = m & r.used
            if r.sensitivity is not None:
                out_points[r.a:r.b] += np.einsum("tjkn,n->tjk", r.sensitivity, z)
        joints_iterations = sum(r.joints_iterations for r in solved)
        iterations += joints_iterations
        stages.append({"name": "joints pass (mirror held, smoothness %g h), %d chunks"
                       % (opts.joints_smoothness_sigma, len(solved)),
                       "iterations": joints_iterations, "initial_error": None,
                       "final_error": None, "converged": None, "rejected": 0,
                       "seconds": sum(r.joints_seconds for r in solved)})
    t = time.perf_counter()
    scores = _joined_scores([r for r in good if r.scores is not None], T, z)
    noise_px = reprojection_noise_px(rig, out_masks, ctx.pose, [plane], 3)
    factor = (noise_px / opts.pixel_sigma) ** 2 if np.isfinite(noise_px) else 1.0
    plane_key = z_keys[0][0]
    basis = [np.asarray(zv.atOrientedPlane3(plane_key).normal().basis())]
    plane_cov = [np.full((3, 3), np.nan)]
    if opts.marginals:
        plane_cov = [reduced_covariance(information, z_keys)[int(plane_key)] * factor]
    if held_cov is not None:
        plane_cov = [plane_cov[0] + held_cov]
        if scores is not None and scores.scores.shape[1] == 3:
            scores.added_cov = held_cov
    timings["marginals"] = time.perf_counter() - t
    return SolveState(poses=ctx.pose, planes=[plane], points=out_points, used=out_used,
                      bone_lengths={k: float(v) for k, v in ctx.lengths.items()},
                      torso_lengths=ctx.torso, scale=sub.scale,
                      camera_cov=[np.zeros((6, 6))], plane_cov=plane_cov, plane_basis=basis,
                      noise_px=noise_px, variance_factor=factor, view_masks=out_masks,
                      rejected=rejected, undetermined=sub.undetermined,
                      prior_info=sub.prior_info, reprojection_factors=n_repro,
                      iterations=iterations, final_error=final_error, stages=stages,
                      timings=timings, body_height=sub.body_height, information=information,
                      z_keys=z_keys, z_values=zv, problem=None, scores=scores,
                      intrinsics=sub.intrinsics, intrinsics_cov=sub.intrinsics_cov,
                      intrinsics_std=sub.intrinsics_std, joints_masks=joints_masks,
                      calibration_points=own_points,
                      intrinsics_data_std=sub.intrinsics_data_std,
                      focal_undetermined=sub.focal_undetermined, focal_bias=sub.focal_bias)


# --------------------------------------------------------------------------- helpers
def _global_step(good: list[_ChunkResult]):
    """One Gauss-Newton step of the shared plane from the chunks' reduced systems: their
    sum, with the distance gauge's prior where the bone lengths do not hold the scale.

    Returns:
        The ``(n, n)`` information, the summed error, the reduced keys, the plane's
        value after the step, the ``(n,)`` step and its length in its own standard
        deviations (``sqrt(z^T H z)``).
    """
    H = sum(r.information for r in good)
    g = sum(r.gradient for r in good)
    final_error = sum(r.final_error for r in good)
    z_keys = good[-1].z_keys
    zv = gtsam.Values()
    zv.insert(z_keys[0][0], plane_to_gtsam(*good[-1].plane))
    glob = gtsam.NonlinearFactorGraph()          # the bone lengths are held
    gauge = good[-1].distance_gauge
    if gauge is not None:
        glob.push_back(DistancePriorFactor(gauge).make(z_keys[0][0]))
        Hg, gg = dense_system(glob.linearize(zv), z_keys)
        H, g = H + Hg, g + gg
        final_error += float(glob.error(zv))
    z = np.linalg.solve(H, g)
    zlen = float(np.sqrt(max(z @ H @ z, 0.0)))
    zv = _apply_step(zv, z_keys, z)
    return H, final_error, z_keys, zv, z, zlen


def _joined_scores(parts: list[_ChunkResult], T: int, z: np.ndarray) -> JointScores | None:
    """The chunks' joint scores as one record over the video's ``T`` frame rows.

    Every chunk scored its joints at the globals it was given; the last global step ``z``
    moves them to the final globals (else each score would carry the step's gradient and
    the per-joint clusters would read it as noise)."""
    if not parts:
        return None
    first = parts[0].scores
    n = first.scores.shape[1]
    frame_info = np.zeros((T, n, n))
    for r in parts:
        frame_info[r.a:r.b] = r.scores.frame_info
    return JointScores(frames=np.concatenate([r.scores.frames + r.a for r in parts]),
                       joints=np.concatenate([r.scores.joints for r in parts]),
                       clusters=np.concatenate([r.scores.clusters for r in parts]),
                       scores=np.concatenate([r.scores.moved(z) for r in parts]),
                       frame_info=frame_info,
                       joint_info=sum(r.scores.joint_info for r in parts),
                       z_keys=first.z_keys, gauge=first.gauge)


def _apply_step(zv: gtsam.Values, z_keys: list[tuple[int, int]], z: np.ndarray) -> gtsam.Values:
    delta = gtsam.VectorValues()
    off = 0
    for k, d in z_keys:
        delta.insert(int(k), z[off:off + d])
        off += d
    return zv.retract(delta)
