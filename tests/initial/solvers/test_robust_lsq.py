"""mirrorgraph.initial.solvers.robust_lsq against SciPy's least_squares (#25): the same steps."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg
from scipy.optimize import least_squares

from mirrorgraph.initial.solvers import robust_lsq
from mirrorgraph.initial.solvers.reflective import refine_epipole


def _problems(n: int):
    """Random robust fits: an exponential decay with outliers, and a circle."""
    rng = np.random.default_rng(25)
    for k in range(n):
        t = np.linspace(0, 4, int(rng.integers(20, 200)))
        a, b, c = rng.uniform(0.5, 3), rng.uniform(0.2, 2), rng.uniform(-1, 1)
        y = a * np.exp(-b * t) + c + rng.normal(0, 0.02, t.size)
        bad = rng.random(t.size) < 0.15
        y[bad] += rng.normal(0, 1, bad.sum())
        yield (lambda x, t=t, y=y: x[0] * np.exp(-x[1] * t) + x[2] - y,
               np.array([1.0, 1.0, 0.0]), rng.uniform(0.01, 0.5))
        ang = rng.uniform(0, 2 * np.pi, int(rng.integers(10, 100)))
        cx, cy, r = rng.normal(0, 3, 2).tolist() + [rng.uniform(1, 5)]
        px = cx + r * np.cos(ang) + rng.normal(0, 0.05, ang.size)
        py = cy + r * np.sin(ang) + rng.normal(0, 0.05, ang.size)
        yield (lambda x, px=px, py=py: np.hypot(px - x[0], py - x[1]) - x[2],
               np.array([px.mean() + 0.3 * (k % 3), py.mean(), 1.0]), rng.uniform(0.05, 1))


def _scipy(fun, x0, scale, max_nfev=None):
    return least_squares(fun, x0, loss="cauchy", f_scale=scale, x_scale="jac",
                         max_nfev=max_nfev)


@pytest.mark.parametrize("max_nfev", [None, 3])
def test_with_scipys_svd_the_steps_are_scipys_bit_for_bit(monkeypatch, max_nfev):
    monkeypatch.setattr(robust_lsq, "_svd", scipy.linalg.svd)
    for fun, x0, scale in _problems(20):
        ours = robust_lsq.robust_least_squares(fun, x0, f_scale=scale,
                                               max_nfev=max_nfev or 100 * x0.size)
        theirs = _scipy(fun, x0, scale, max_nfev)
        assert np.array_equal(ours.x, theirs.x)
        assert (ours.nfev, ours.status, ours.cost) == (theirs.nfev, theirs.status, theirs.cost)


def test_with_numpys_svd_the_same_minimum():
    """NumPy's LAPACK rounds the last bits differently, and the steps near the minimum
    are differences of nearly equal numbers (the gradient tends to 0): the same fit to
    what SciPy's own stopping rule leaves (a 1e-8 relative decrease of the cost)."""
    compared = 0
    for fun, x0, scale in _problems(20):
        ours = robust_lsq.robust_least_squares(fun, x0, f_scale=scale, max_nfev=300)
        theirs = _scipy(fun, x0, scale, 300)
        if theirs.status == 0:
            continue
        compared += 1
        np.testing.assert_allclose(ours.x, theirs.x, rtol=1e-7, atol=1e-9)
        assert ours.cost == pytest.approx(theirs.cost, rel=1e-8)
    assert compared >= 30


def test_refine_epipole_is_scipys_on_random_mirror_scenes(monkeypatch):
    """refine_epipole's fit, ours and SciPy's: the same epipole to 1e-9 of its norm."""
    rng = np.random.default_rng(3)
    theirs_fit = []

    def scipy_fit(fun, x0, *, f_scale, max_nfev):
        theirs_fit.append(_scipy(fun, x0, f_scale, max_nfev))
        return theirs_fit[-1]

    for _ in range(30):
        e = np.array([*rng.uniform(-3000, 4000, 2), 1.0])        # the epipole, pixels
        n = int(rng.integers(8, 200))
        u = rng.uniform(0, 1920, (n, 2))
        toward = e[:2] - u
        um = u + toward * rng.uniform(0.05, 0.5, (n, 1)) + rng.normal(0, 1.5, (n, 2))
        e0 = e + np.array([*rng.normal(0, 30, 2), 0])
        ours = refine_epipole(e0, u, um)
        monkeypatch.setattr("mirrorgraph.initial.solvers.reflective.robust_least_squares", scipy_fit)
        theirs = refine_epipole(e0, u, um)
        monkeypatch.undo()
        ours, theirs = ours * np.sign(ours[2]), theirs * np.sign(theirs[2])
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-9)


def test_refine_epipole_imports_no_scipy():
    import subprocess
    import sys
    code = ("import sys, numpy as np\nfrom mirrorgraph.initial.solvers.reflective import refine_epipole\n"
            "u = np.random.default_rng(0).uniform(0, 100, (20, 2))\n"
            "refine_epipole(np.array([500., 50., 1.]), u, u + (np.array([500., 50.]) - u) * 0.2)\n"
            "print(any(m == 'scipy' or m.startswith('scipy.') for m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
