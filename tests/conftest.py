"""Shared fixtures: small random mirror scenes made with the geometry module."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph import geometry as geo


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


@pytest.fixture
def K():
    return np.array([[1400.0, 0.0, 955.0], [0.0, 1400.0, 545.0], [0.0, 0.0, 1.0]])


@pytest.fixture
def scene_points(K):
    """A noiseless scene: (K, n, d, X (200, 3), u (200, 2), u_mirror (200, 2))."""
    rng = np.random.default_rng(3)
    n, d = random_mirror(rng, 35.0)
    X = points_in_front(rng, n, d, 200)
    return K, n, d, X, geo.project(K, X), geo.project(K, geo.reflect_points(X, n, d))


@pytest.fixture
def without_matplotlib(monkeypatch):
    """Every ``import matplotlib...`` raises :class:`ImportError` (a machine without the
    plot extra)."""
    import builtins

    real_import = builtins.__import__

    def fake_import(name, *args, **kwargs):
        if name == "matplotlib" or name.startswith("matplotlib."):
            raise ImportError("no matplotlib")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", fake_import)
