"""The joints' std under noise correlated in time, on a chain whose truth is known.

Each of ``J`` joints over ``T`` frames has a per-frame estimate off by AR(1) noise (std
``s`` per axis, correlation ``rho`` from one frame to the next, truth 0) and is smoothed by
the joints pass's second-difference smoothness (the module's own chain solve,
:func:`mirrorgraph.graph.joints_uncertainty.chain_marginals`). Over ``R`` runs, the
smoothed error's mean squared length against the stated variance (the covariance's trace)
without and with :func:`~mirrorgraph.graph.joints_uncertainty.time_correlation_factor`
(the residual series one coordinate of one run's own noise): ``sqrt(error^2 / stated)``,
1 where the std is right, and the factor's CPU time per 1000 frames of 19 joints.

    python bench/bench_joints_std_time.py [--out bench/RESULTS_joints_std_time_chain.md]
"""

from __future__ import annotations

import argparse
import platform
import time
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from mirrorgraph.factors.smoothness import SmoothnessFactor
from mirrorgraph.graph import joints_uncertainty as ju
from mirrorgraph.synth.detector import correlated_noise

RHOS = (0.0, 0.5, 0.8, 0.9, 0.95)
SIGMAS = (1.0, 0.3, 0.05)          # the smoothness's std per frame^2 over the per-frame std


def ar1(rng, shape: tuple, rho: float) -> np.ndarray:
    """Unit-variance AR(1) noise along the first axis (the synthetic detector's,
    :func:`mirrorgraph.synth.detector.correlated_noise`, whose frames are its axis 1)."""
    return correlated_noise(rng, (1, *shape), rho)[0]


def one(rho: float, sigma: float, T: int = 600, J: int = 2, R: int = 64, s: float = 1.0,
        seed: int = 0) -> dict:
    rng = np.random.default_rng(seed)
    used = np.ones((T, J), bool)
    info = np.broadcast_to(np.eye(3) / s ** 2, (T, J, 3, 3)).copy()
    frame = np.broadcast_to(np.eye(3) * s ** 2, (T, J, 3, 3)).copy()
    band = ju._smoothness_band(used, np.arange(T), SmoothnessFactor(sigma * s, 4))
    smoothed = ju._chain_solve(frame, used, band.copy(), info)
    noise = s * ar1(rng, (T, R, J, 3), rho)
    diag = band[0] + np.moveaxis(info, 0, 1)
    rhs = np.einsum("jtab,trjb->rjta", np.moveaxis(info, 0, 1), noise).reshape(R * J, T, 3)
    est, _ = ju.chain_marginals(np.tile(diag, (R, 1, 1, 1)), np.tile(band[1], (R, 1, 1, 1)),
                                np.tile(band[2], (R, 1, 1, 1)), rhs=rhs)
    inside = slice(100, -100)
    err2 = np.mean(np.sum(est.reshape(R, J, T, 3) ** 2, -1), 0)[:, inside]
    stated = np.trace(smoothed, axis1=-2, axis2=-1)[inside].T
    f = ju.time_correlation_factor(noise[:, 0, :, 0] / s, frame, smoothed)[inside].T
    n = np.trace(frame, axis1=-2, axis2=-1)[inside].T / stated
    return dict(rho=rho, sigma=sigma, n=float(np.median(n)), factor=float(np.median(f)),
                before=float(np.sqrt(np.median(err2 / stated))),
                after=float(np.sqrt(np.median(err2 / (stated * f)))))


def timing(T: int = 1000, J: int = 19, repeat: int = 20) -> float:
    rng = np.random.default_rng(1)
    e = ar1(rng, (T, J), 0.9)
    frame = np.broadcast_to(np.eye(3), (T, J, 3, 3))
    smoothed = np.broadcast_to(np.eye(3) / 10.0, (T, J, 3, 3))
    ju.time_correlation_factor(e, frame, smoothed)                   # the kernels' table
    t = time.process_time()
    for _ in range(repeat):
        ju.time_correlation_factor(e, frame, smoothed)
    return (time.process_time() - t) / repeat


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    rows = [one(rho, sg) for sg in SIGMAS for rho in RHOS]
    lines = ["| smoothness / per-frame std | frames averaged n | rho | factor | "
             "error / stated std, before | after |", "|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['sigma']:g} | {r['n']:.1f} | {r['rho']:g} | {r['factor']:.2f} | "
                     f"{r['before']:.2f} | {r['after']:.2f} |")
    cpu = timing()
    lines.append("")
    lines.append(f"time_correlation_factor: {cpu * 1e3:.1f} ms of CPU per 1000 frames x 19 "
                 "joints (the kernels' table, once a process, aside)")
    print("\n".join(lines))
    if args.out:
        head = ["# The joints' std under AR(1) noise on a known chain "
                "(`bench/bench_joints_std_time.py`)", "",
                f"- date: {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC",
                f"- machine: {platform.platform()}, {platform.processor() or 'cpu'}, "
                f"Python {platform.python_version()}",
                f"- command: `python bench/bench_joints_std_time.py --out {args.out}`",
                "- 2 joints x 600 frames, 64 runs, the middle 400 frames; `before`/`after`: "
                "sqrt(median(error^2 / stated variance)) without and with the factor (1: the "
                "std right; below 1 on a still chain, whose error leaves the smoothness's "
                "share of a moving joint unused)", ""]
        Path(args.out).write_text("\n".join(head + lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
