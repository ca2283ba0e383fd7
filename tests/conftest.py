"""Shared fixtures: small random mirror scenes made with the geometry module (helper
functions that test modules import are in helpers.py)."""

from __future__ import annotations

import numpy as np
import pytest

from mirrorgraph import geometry as geo

from tests.helpers import points_in_front, random_mirror


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
