"""Helpers shared by test modules in any folder of tests/ (fixtures live in conftest.py).

Import them as ``from tests.helpers import ...``: pytest puts the repository on
``sys.path`` (``tests/`` and every folder in it are packages).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

#: The repository's root (``bench/``, ``notebooks/`` and the package are there).
REPO_ROOT = Path(__file__).resolve().parents[1]


def random_mirror(rng: np.random.Generator, angle_deg: float | None = None):
    """A unit normal at ``angle_deg`` (random 10-60) to the optical axis and d in [2.5, 4.5]."""
    angle = np.radians(rng.uniform(10, 60) if angle_deg is None else angle_deg)
    az = rng.uniform(0, 2 * np.pi)
    n = np.array([np.sin(angle) * np.cos(az), np.sin(angle) * np.sin(az), np.cos(angle)])
    return n, float(rng.uniform(2.5, 4.5))


def points_in_front(rng, n, d, count):
    """Points between camera and mirror, at 40-80% of the way along the optical axis."""
    X = np.empty((0, 3))
    while len(X) < count:
        z = rng.uniform(0.4, 0.8, count) * d / max(n[2], 0.3)
        P = np.stack([rng.uniform(-0.6, 0.6, count), rng.uniform(-0.8, 0.8, count), z], 1)
        P = P[(P @ n < d - 0.3) & (P[:, 2] > 1.0)]
        X = np.concatenate([X, P])
    return X[:count]


def need_module(module: str, why: str) -> None:
    """Skip the calling test, naming ``module`` and ``why``, where it is not installed."""
    import pytest
    if importlib.util.find_spec(module) is None:
        pytest.skip(f"{module} is not installed: {why}")


def rig_without_intrinsics(rig, folder: Path):
    """Write a synthetic ``rig`` (:func:`mirrorgraph.synth.make_rig`) into ``folder`` and
    return its :class:`~mirrorgraph.rigs.config.RigConfig` with the second camera listed
    without intrinsics (only its image size)."""
    import dataclasses

    from mirrorgraph.rigs.config import load_rig_config
    from mirrorgraph.synth import write_rig

    write_rig(rig, folder)
    cfg = load_rig_config(folder / "rig.toml")
    cams = (cfg.cameras[0], dataclasses.replace(cfg.cameras[1], intrinsics=None,
                                                image_size=tuple(rig.image_size)))
    return dataclasses.replace(cfg, cameras=cams)
