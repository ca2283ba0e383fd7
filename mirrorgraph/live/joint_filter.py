"""Each joint's track filtered over time: the live run's prior of motion, one frame at a time.

A joint's position ``x_t`` follows the second-difference prior of the offline joints pass
(:class:`~mirrorgraph.factors.smoothness.SmoothnessFactor`:
``x_{t+1} - 2 x_t + x_{t-1} ~ N(0, sigma^2 I)``, ``sigma`` per frame^2). With the
velocity ``v_t = x_t - x_{t-1}`` that prior is the linear state-space model

    [x, v]_{t+1} = [[I, I], [0, I]] [x, v]_t + [w, w],    w ~ N(0, sigma^2 I),

so the Kalman filter over it gives, frame by frame, the same newest point and covariance
as the batch maximum a posteriori over every frame so far (Sarkka, *Bayesian Filtering and
Smoothing*, 2013, ch. 4 and 8), at a fixed cost: ``(J, 6, 6)`` matrices, vectorised over
the joints. A step of ``g`` frames applies the model ``g`` times (its noise summed in
closed form); a joint unseen for more than ``max_gap`` frames starts a new track.

Each frame's measurement of a joint (its triangulated point and covariance) is tested
against the prediction before it is taken: its squared Mahalanobis distance on the
innovation's covariance beyond :data:`GATE_CHI2` (3 degrees of freedom) marks it an
outlier (a keypoint displaced along its epipolar line, a left/right label the detector
swapped in both views): the joint keeps its prediction for that frame, and after
``restart_after`` such frames in a row its track restarts from the measurement (the
person moved unlike the prior), keeping the velocity it had and that velocity's
covariance (the motion goes on where the position the frames give jumped). A track is
gated from its ``restart_after``-th measurement on: before, it follows its first few
measurements.
"""

from __future__ import annotations

import numpy as np

__all__ = ["JointFilter", "GATE_CHI2"]

#: Innovations beyond this squared Mahalanobis distance are outliers: chi-square with 3
#: degrees of freedom at 0.9999.
GATE_CHI2 = 21.1


def _noise(g: np.ndarray, sigma: float) -> np.ndarray:
    """``(N, 6, 6)`` the process noise of ``g`` steps of the model (per axis
    ``sigma^2 sum_i [[(1+i)^2, 1+i], [1+i, 1]]``, ``i < g``)."""
    g = np.asarray(g, float)
    s1 = g * (g + 1.0) / 2.0
    s2 = g * (g + 1.0) * (2.0 * g + 1.0) / 6.0
    blocks = np.stack([np.stack([s2, s1], -1), np.stack([s1, g], -1)], -2)      # (N, 2, 2)
    return sigma * sigma * np.einsum("nab,ij->naibj", blocks, np.eye(3)).reshape(-1, 6, 6)


def _transition(g: np.ndarray) -> np.ndarray:
    """``(N, 6, 6)`` the model applied ``g`` times: ``[[I, g I], [0, I]]``."""
    F = np.broadcast_to(np.eye(6), (len(g), 6, 6)).copy()
    F[:, :3, 3:] = np.asarray(g, float)[:, None, None] * np.eye(3)
    return F


class JointFilter:
    """Per-joint Kalman filters of positions and their fixed-lag smoother (see the module
    docstring).

    Every frame predicts every joint that has a track (:meth:`step`), the frame's
    measurements update theirs; the last ``lag + 1`` frames' filtered and predicted
    states are kept so that :meth:`smoothed` gives a frame ``lag`` frames back with the
    frames after it (the Rauch-Tung-Striebel recursion, Sarkka 2013, ch. 8), never
    across a track's restart.

    Args:
        joints: the skeleton's joint count ``J``.
        sigma: the acceleration's std, the points' unit per frame^2 of the stream
            (:meth:`mirrorgraph.graph.options.PriorOptions.at_frame_rate`).
        max_gap: a joint unseen for more than this many frames starts a new track.
        gate_chi2: the outlier gate on the innovation (squared Mahalanobis distance).
        restart_after: measurements rejected in a row that restart a joint's track.
        velocity_std: the std of a new track's velocity (a joint without a track within
            ``max_gap``), the points' unit per frame.
        lag: frames kept for :meth:`smoothed`.
    """

    def __init__(self, joints: int, sigma: float, max_gap: int, *,
                 gate_chi2: float = GATE_CHI2, restart_after: int = 3,
                 velocity_std: float = 1.0, lag: int = 0) -> None:
        self.J = int(joints)
        self.sigma = float(sigma)
        self.max_gap = int(max_gap)
        self.gate_chi2 = float(gate_chi2)
        self.restart_after = int(restart_after)
        self.velocity_var = float(velocity_std) ** 2
        self.lag = max(int(lag), 0)
        # (frame, x_f, P_f, gain G, chained, F, x_p and G F P_f of the next frame)
        self.history: list[tuple] = []
        self._models: dict = {}
        self.reset()

    def reset(self) -> None:
        """Forget every track."""
        J = self.J
        self.x = np.full((J, 6), np.nan)
        self.P = np.full((J, 6, 6), np.nan)
        self.seen = np.full(J, -(1 << 62), dtype=np.int64)
        self.rejected = np.zeros(J, dtype=np.int64)
        self.age = np.zeros(J, dtype=np.int64)          # measurements a track has taken
        self.frame: int | None = None
        self.history = []

    def scale(self, factor: float) -> None:
        """Every state's lengths times ``factor`` (a new mirror's distance)."""
        # new arrays: the newest history entry holds the current state itself
        self.x = self.x * factor
        self.P = self.P * (factor * factor)
        self.history = [(h[0], h[1] * factor, h[2] * factor * factor) + h[3:6]
                        + ((h[6] * factor, h[7] * factor * factor) if h[3] is not None
                           else h[6:]) for h in self.history]

    def predict(self, frame_id: int) -> tuple[np.ndarray, np.ndarray]:
        """Every track predicted to ``frame_id`` (after the last step's), the state left
        as it is: ``(J, 3)`` points and ``(J, 3, 3)`` covariances, NaN where a joint has
        no track within its gap or one not yet gated (fewer than ``restart_after``
        measurements: its velocity still that of its first few)."""
        J = self.J
        if self.frame is None:
            return np.full((J, 3), np.nan), np.full((J, 3, 3), np.nan)
        F, Q = self._model(max(int(frame_id) - self.frame, 1))
        alive = (np.isfinite(self.x[:, 0]) & (frame_id - self.seen <= self.max_gap)
                 & (self.age >= self.restart_after))
        xp = np.where(alive[:, None], self.x @ F.T, np.nan)
        Pp = np.where(alive[:, None, None],
                      F @ np.where(alive[:, None, None], self.P, 0.0) @ F.T + Q, np.nan)
        return xp[:, :3], Pp[:, :3, :3]

    def step(self, frame_id: int, idx: np.ndarray, z: np.ndarray, R: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One frame: predict every track to ``frame_id``, take the measurements of joints
        ``idx``.

        Args:
            frame_id: the frame's number (after every earlier step's).
            idx: ``(k,)`` the skeleton's indices of the measured joints.
            z: ``(k, 3)`` their measured points; R: ``(k, 3, 3)`` their covariances.

        Returns:
            ``(X, C, taken)``: the filtered ``(k, 3)`` points and ``(k, 3, 3)``
            covariances of joints ``idx``, and ``(k,)`` bool where the measurement was
            taken (``False``: rejected as an outlier, the prediction given).
        """
        idx = np.asarray(idx, dtype=np.int64)
        z, R = np.asarray(z, float).reshape(-1, 3), np.asarray(R, float).reshape(-1, 3, 3)
        J = self.J
        g = 1 if self.frame is None else max(int(frame_id) - self.frame, 1)
        self.frame = int(frame_id)
        # the measurements over every joint (NaN where none)
        zJ = np.full((J, 3), np.nan)
        RJ = np.broadcast_to(np.eye(3), (J, 3, 3)).copy()
        ok = np.isfinite(z).all(1) & np.isfinite(R).all((1, 2))
        zJ[idx[ok]], RJ[idx[ok]] = z[ok], R[ok]
        meas = np.zeros(J, bool)
        meas[idx[ok]] = True
        # predict: every track still within its gap
        alive = np.isfinite(self.x[:, 0]) & (frame_id - self.seen <= self.max_gap)
        F, Q = self._model(g)
        xp = np.where(alive[:, None], self.x @ F.T, np.nan)
        Pp = np.where(alive[:, None, None],
                      F @ np.where(alive[:, None, None], self.P, 0.0) @ F.T + Q, np.nan)
        chained = alive.copy()
        upd = meas & alive
        S = np.where(upd[:, None, None], Pp[:, :3, :3] + RJ, np.eye(3))
        Sinv = _inverse(S)
        y = np.where(upd[:, None], zJ - xp[:, :3], 0.0)
        m = np.einsum("ni,nij,nj->n", y, Sinv, y)
        out = upd & (m > self.gate_chi2)
        # a track younger than restart_after updates is not gated yet: its velocity is
        # still that of its first measurements (a restart on outliers would lock out
        # the right ones that follow)
        gate = out & (self.rejected + 1 < self.restart_after) & (self.age >= self.restart_after)
        take = upd & ~gate
        Pz = np.where(take[:, None, None], Pp, 0.0)
        Kg = Pz[:, :, :3] @ Sinv                                               # (J, 6, 3)
        xf = np.where(take[:, None], xp + np.einsum("nij,nj->ni", Kg, y), xp)
        Pf = np.where(take[:, None, None], Pp - Kg @ Pz[:, :3, :], Pp)
        Pf = 0.5 * (Pf + Pf.transpose(0, 2, 1))
        self.rejected = np.where(gate, self.rejected + 1, np.where(upd, 0, self.rejected))
        self.age = np.where(take, self.age + 1, self.age)
        fresh = (meas & ~alive) | (out & ~gate)          # a new track from the measurement
        if fresh.any():
            # a track restarted on measurements that left its prediction keeps the
            # velocity it had and its covariance (the body's motion goes on where the
            # position the frames give jumped: a young track's first measurements, an
            # outlier among them, do not set it alone); a new one starts at rest
            again = fresh & alive
            xf[fresh, :3] = zJ[fresh]
            xf[fresh, 3:] = np.where(again[fresh, None], xp[fresh, 3:], 0.0)
            Pv = np.where(again[fresh, None, None], Pp[fresh, 3:, 3:],
                          self.velocity_var * np.eye(3))
            Pf[fresh] = 0.0
            Pf[fresh, :3, :3] = RJ[fresh]
            Pf[fresh, 3:, 3:] = Pv
            self.rejected[fresh] = 0
            self.age[fresh] = 1
            chained[fresh] = False
        taken = ok & ~gate[idx]
        self.x, self.P = xf, Pf
        self.seen[meas] = int(frame_id)
        if self.lag:
            if self.history:
                # the previous frame's smoother gain G = P_f F^T P_p^-1 (RTS)
                prev = self.history[-1]
                c = chained & np.isfinite(prev[1][:, 0])
                G = (np.where(c[:, None, None], prev[2], 0.0) @ F.T
                     @ _inverse(np.where(c[:, None, None], Pp, np.eye(6))))
                self.history[-1] = prev[:3] + (G, c, F, xp, G @ F @ prev[2])
            self.history.append((int(frame_id), xf, Pf, None, None, None, None, None))
            del self.history[:-(self.lag + 1)]
        return xf[idx, :3], Pf[idx, :3, :3], taken

    def _model(self, g: int) -> tuple[np.ndarray, np.ndarray]:
        """``(6, 6)`` the transition and the process noise of ``g`` steps (kept per gap
        and ``sigma``: most frames step by one)."""
        key = (g, self.sigma)
        if key not in self._models:
            if len(self._models) > 64:
                self._models.clear()
            self._models[key] = (_transition(np.array([g]))[0],
                                 _noise(np.array([g]), self.sigma)[0])
        return self._models[key]

    def smoothed(self, frame_id: int) -> tuple[np.ndarray, np.ndarray] | None:
        """Frame ``frame_id`` (one of the last ``lag + 1`` stepped) smoothed with the
        frames stepped after it: ``(J, 3)`` points and ``(J, 3, 3)`` covariances (NaN
        where no track), or ``None`` where the frame is not held."""
        for k in range(len(self.history) - 1, -1, -1):
            if self.history[k][0] == int(frame_id):
                return self._smooth(k)
        return None

    def _smooth(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """The history's frame ``k`` smoothed by the frames after it (RTS, the gains
        kept with each frame)."""
        xs, Ps = self.history[-1][1], self.history[-1][2]
        for i in range(len(self.history) - 2, k - 1, -1):
            _, xf, Pf, G, c, F, xp, GFP = self.history[i]
            c = c & np.isfinite(xs[:, 0])
            # x_s = x_f + G (x_s' - x_p'), P_s = P_f + G (P_s' - P_p') G^T, with
            # x_p' = F x_f and P_f - G P_p' G^T = P_f - G F P_f
            if c.all():                    # every track chained: no rows to pick
                xs = xf + (G @ (xs - xp)[:, :, None])[:, :, 0]
                Ps = Pf - GFP + G @ Ps @ G.transpose(0, 2, 1)
                continue
            x_new, P_new = xf.copy(), Pf.copy()
            if c.any():
                Gc = G[c]
                x_new[c] = xf[c] + (Gc @ (xs[c] - xp[c])[:, :, None])[:, :, 0]
                P_new[c] = Pf[c] - GFP[c] + Gc @ Ps[c] @ Gc.transpose(0, 2, 1)
            xs, Ps = x_new, P_new
        return xs[:, :3], Ps[:, :3, :3]


def _inverse(A: np.ndarray) -> np.ndarray:
    """``(n, m, m)`` inverses of symmetric positive definite matrices (the
    pseudo-inverse where one is singular)."""
    try:
        return np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(A, hermitian=True)
