"""The live joints' std under a detector whose noise is correlated in time.

The live run's joint filter (:class:`.joint_filter.JointFilter`) and its fixed-lag
smoother average a joint's frames as if each frame's noise were its own; a detector's
error that persists from frame to frame does not average out, and the filtered covariance
understates the error by up to the frames it averages. :class:`NoiseInTime` keeps, frame
by frame, the autocorrelation of each frame's epipolar residual (the component of a
joint's four pixel residuals no point fits: the detector's noise itself,
:func:`~mirrorgraph.graph.joints_uncertainty.epipolar_residuals`), pooled over the joints
and each joint's own mean (its bias) taken out, and widens a filtered covariance by the
cross terms its kernel meets (:func:`~mirrorgraph.graph.joints_uncertainty.
time_correlation_factor`'s formula with the filter's one-sided kernel, :func:`~mirrorgraph.
graph.joints_uncertainty.fixed_lag_kernels`). Under independent noise the factor stays ~1.
Cost: ``O(J L)`` a frame, ``L`` the lags kept.
"""

from __future__ import annotations

import numpy as np

from ..graph.joints_uncertainty import fixed_lag_kernels, null_component
from .frame_prior import view_residuals

__all__ = ["NoiseInTime", "LAGS"]

#: Lags (frames) of the residuals' autocorrelation kept: the filter's kernel at the joints
#: pass's smoothness spans tens of frames.
LAGS = 128


class NoiseInTime:
    """The residuals' autocorrelation over the frames so far and the factor it puts on
    the filtered joints' covariance.

    Args:
        num_joints: ``J``.
        lags: the lags kept (:data:`LAGS`).
    """

    def __init__(self, num_joints: int, lags: int = LAGS) -> None:
        J, L = int(num_joints), int(lags)
        self.lags = L
        self._e = np.full((L + 1, J), np.nan)          # the last frames' residuals, by fid
        self._frame_trace = np.full((L + 1, J), np.nan)  # their per-frame covariances' trace
        self._fid = np.full(L + 1, -1, np.int64)
        self._prod = np.zeros((L + 1, J))               # sum e_t e_{t-k}, k = 0..L
        self._pairs = np.zeros((L + 1, J))
        self._sum = np.zeros(J)
        self._tables: dict = {}              # lag -> its factors' table (and rho), this frame

    def record(self, fid: int, idx: np.ndarray, K: np.ndarray, normal: np.ndarray,
               distance: float, X: np.ndarray, u: np.ndarray, um: np.ndarray,
               keep: np.ndarray, cov: np.ndarray) -> None:
        """Frame ``fid``'s joints ``idx`` ``(k,)``: their points ``X`` ``(k, 3)`` from the
        pixels ``u``, ``um`` ``(k, 2)`` (camera, mirror; ``keep`` ``(k, 2)`` the views each
        keeps) and their per-frame covariances ``cov`` ``(k, 3, 3)`` (before the filter).
        Frames come in increasing order."""
        fid, L = int(fid), self.lags
        self._tables.clear()
        row = fid % (L + 1)
        self._e[row] = np.nan
        self._frame_trace[row] = np.nan
        self._fid[row] = fid
        idx = np.asarray(idx, np.int64)
        if not len(idx):
            return
        self._frame_trace[row, idx] = np.trace(np.asarray(cov, float), axis1=1, axis2=2)
        r, Jac = view_residuals(K, normal, distance, np.asarray(X, float), u, um)
        both = np.asarray(keep, bool).all(1) & np.isfinite(r).all((1, 2))
        if not both.any():
            return
        e = null_component(Jac[both].reshape(-1, 4, 3), r[both].reshape(-1, 4))
        j = idx[both]
        self._e[row, j] = e
        fine = np.isfinite(e)
        j, e = j[fine], e[fine]
        back = fid - np.arange(L + 1)
        rows = back % (L + 1)
        prev = np.where((self._fid[rows] == back)[:, None], self._e[rows][:, j], np.nan)
        prod = prev * e[None, :]                                        # (L + 1, k)
        ok = np.isfinite(prod)
        self._prod[:, j] += np.where(ok, prod, 0.0)
        self._pairs[:, j] += ok
        self._sum[j] += e

    def autocorrelation(self) -> np.ndarray:
        """``(L,)`` the residuals' autocorrelation at lags ``1..L`` frames, each joint's
        own mean out, pooled over the joints (0 where no pair)."""
        n0 = self._pairs[0]
        m = np.where(n0 > 0, self._sum / np.maximum(n0, 1), 0.0)
        cov = (self._prod - self._pairs * m * m).sum(1)
        n = self._pairs.sum(1)
        if not n[0] or cov[0] <= 0:
            return np.zeros(self.lags)
        return np.where(n[1:] > 0, cov[1:] / np.maximum(n[1:], 1) / (cov[0] / n[0]), 0.0)

    def factor(self, fid: int, idx: np.ndarray, cov: np.ndarray, lag: int) -> np.ndarray:
        """``(k,)`` the factor on the covariances ``cov`` ``(k, 3, 3)`` of frame ``fid``'s
        joints ``idx`` filtered with ``lag`` frames after it (0: the filter's newest):
        ``1 + 2 n sum_k a_k(n) rho_k`` clipped to ``[1, n]``, ``n`` the frame's own
        covariance's trace over the filtered one's (the frames the filter averages);
        1 where the frame has left the recorder's window or either trace is not finite."""
        idx = np.asarray(idx, np.int64)
        out = np.ones(len(idx))
        row = int(fid) % (self.lags + 1)
        if not len(idx) or self._fid[row] != int(fid):
            return out
        ts = np.trace(np.asarray(cov, float), axis1=1, axis2=2)
        with np.errstate(divide="ignore", invalid="ignore"):
            n = self._frame_trace[row, idx] / ts
        good = np.isfinite(n) & (ts > 0)
        if not good.any():
            return out
        widths, table = self._table(int(lag))
        n = np.clip(np.where(good, n, 1.0), 1.0, widths[-1])
        f = np.interp(np.log(n), np.log(widths), table)
        return np.where(good, np.clip(f, 1.0, n), 1.0)

    def _table(self, lag: int) -> tuple[np.ndarray, np.ndarray]:
        """The filter's widths ``n`` and the factor ``1 + 2 n sum_k a_k(n) rho_k`` at each
        ``(grid,)``, once a frame and lag."""
        if lag not in self._tables:
            if "rho" not in self._tables:
                self._tables["rho"] = self.autocorrelation()
            widths, acf = fixed_lag_kernels(lag)
            self._tables[lag] = (widths, 1.0 + 2.0 * widths * (acf[:, :self.lags]
                                                               @ self._tables["rho"]))
        return self._tables[lag]
