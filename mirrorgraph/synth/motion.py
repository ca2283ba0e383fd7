"""Procedural exercise-like motion with exactly rigid bones, vectorised over frames.

:func:`generate_motion` returns the 3D positions of every joint of
:data:`~mirrorgraph.synth.body.FULL_JOINTS` for ``T`` frames, in units of the
subject's height, in the *body frame* (``x`` left, ``y`` up, ``z`` forward at
yaw 0, floor at ``y = 0``).

How it is built:

* The timeline is cut into blocks of 4-9 s, each with one exercise: standing
  idle, squats, lunges (left, right or alternating), arm raises (forward,
  lateral, alternating, curls), step jacks (jumping-jack arms and feet), torso
  bends (forward, sideways, twists). Inside a block the exercise intensity is a
  ``sin^2`` cycle (period 1-3 s) times a window whose edges are quintic
  smoothsteps, so every block starts and ends at the rest pose with zero
  velocity and acceleration: the sequence is smooth wherever blocks join.
* On top runs small idle motion (sums of slow sinusoids) for the arms, head and
  trunk.
* The person turns in place: the pelvis yaw moves between random targets in
  +-70 degrees with smoothstep transitions.
* The feet step: every 1-2 s one foot (alternately) moves to a new place under
  the hip of the slowly wandering, turning body, lifted on a ``sin^2`` arc.
  Lunges and step jacks add their own foot offsets, lifted in proportion to the
  foot's speed.
* Trunk, head and arms are forward kinematics (rotation matrices per frame);
  the legs are solved by an exact two-bone inverse kinematics from the hip to
  the ankle target, with the knee in the plane of the foot's forward direction.
  An ankle out of reach is pulled in smoothly (heel rise, foot pitched about
  the toes). Every bone length is therefore constant to rounding error.
"""

from __future__ import annotations

import numpy as np

from .body import FULL_INDEX, FULL_JOINTS, BodyModel

IDLE, SQUAT, LUNGE, ARMS, JACKS, BEND = range(6)
_TYPE_P = np.array([0.10, 0.20, 0.15, 0.20, 0.15, 0.20])
_DEG = np.pi / 180.0


# --------------------------------------------------------------------------- helpers
def _rx(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(np.shape(a) + (3, 3))
    R[..., 0, 0] = 1.0
    R[..., 1, 1], R[..., 1, 2], R[..., 2, 1], R[..., 2, 2] = c, -s, s, c
    return R


def _ry(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(np.shape(a) + (3, 3))
    R[..., 1, 1] = 1.0
    R[..., 0, 0], R[..., 0, 2], R[..., 2, 0], R[..., 2, 2] = c, s, -s, c
    return R


def _rz(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(np.shape(a) + (3, 3))
    R[..., 2, 2] = 1.0
    R[..., 0, 0], R[..., 0, 1], R[..., 1, 0], R[..., 1, 1] = c, -s, s, c
    return R


def _mv(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate: ``(T,3,3) x (3,) or (T,3) -> (T,3)``."""
    if v.ndim == 1:
        return R @ v
    return np.einsum("tij,tj->ti", R, v)


def _smoothstep(x: np.ndarray) -> np.ndarray:
    """Quintic smoothstep on [0, 1] (zero first and second derivative at the ends)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (x * (6.0 * x - 15.0) + 10.0)


def _wiggle(rng: np.random.Generator, t: np.ndarray, amp: float, fmin: float = 0.05,
            fmax: float = 0.4, n: int = 3) -> np.ndarray:
    """Sum of ``n`` random sinusoids with ``|sum| <= amp``."""
    w = rng.uniform(0.3, 1.0, n)
    w *= amp / w.sum()
    f = rng.uniform(fmin, fmax, n)
    ph = rng.uniform(0.0, 2 * np.pi, n)
    return (w[:, None] * np.sin(2 * np.pi * f[:, None] * t[None, :] + ph[:, None])).sum(0)


def _knot_interp(t: np.ndarray, knots: np.ndarray, values: np.ndarray,
                 dur: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Hold ``values[k-1]`` until ``knots[k]``, then smoothstep to ``values[k]`` in ``dur``.

    Returns ``(value (T, ...), linear progress u (T,), knot index (T,))``.
    ``knots[0]`` must be ``<= t[0]``; ``values[0]`` is the initial value.
    """
    k = np.searchsorted(knots, t, side="right") - 1
    d = dur if np.isscalar(dur) else dur[k]
    u = np.clip((t - knots[k]) / d, 0.0, 1.0)
    s = _smoothstep(u)
    prev = values[np.maximum(k - 1, 0)]
    cur = values[k]
    shape = (-1,) + (1,) * (values.ndim - 1)
    return prev + (cur - prev) * s.reshape(shape), u, k


# --------------------------------------------------------------------------- schedule
def _schedule(rng: np.random.Generator, t: np.ndarray) -> dict[str, np.ndarray]:
    """Exercise activations per frame (all in [0, 1] except signed ones)."""
    total = float(t[-1]) + 1.0 if len(t) else 1.0
    nb = int(np.ceil(total / 4.0)) + 2
    dur = rng.uniform(4.0, 9.0, nb)
    start = np.concatenate([[0.0], np.cumsum(dur)[:-1]])
    kind = rng.choice(6, size=nb, p=_TYPE_P)
    kind[0] = rng.choice([IDLE, ARMS, SQUAT])
    amp = rng.uniform(0.6, 1.0, nb)
    period = rng.uniform(1.6, 3.0, nb)
    period[kind == JACKS] = rng.uniform(1.0, 1.6, int((kind == JACKS).sum()))
    variant = rng.integers(0, 4, nb)

    b = np.searchsorted(start, t, side="right") - 1
    tau = t - start[b]
    D = dur[b]
    ramp = np.minimum(0.8, D / 3.0)
    win = _smoothstep(tau / ramp) * _smoothstep((D - tau) / ramp)
    ph = 2 * np.pi * tau / period[b]
    cyc = np.sin(ph / 2) ** 2                      # 0 -> 1 -> 0 once per period
    sgn = np.sin(ph)                               # signed, for side bends/twists
    odd = (np.floor(tau / period[b]) % 2).astype(bool)
    e = amp[b] * win
    K, V = kind[b], variant[b]

    z = np.zeros_like(t)
    out = {k: z.copy() for k in (
        "squat", "squat_arms", "squat_hips", "lunge_l", "lunge_r", "raise_l", "raise_r",
        "lateral", "curl", "jack", "bend", "side", "twist")}
    m = K == SQUAT
    out["squat"] = np.where(m, e * cyc, 0.0)
    out["squat_arms"] = np.where(m & ((V == 0) | (V == 3)), out["squat"], 0.0)
    out["squat_hips"] = np.where(m & (V == 2), out["squat"], 0.0)
    m = K == LUNGE
    left = np.where(V >= 2, ~odd, V == 0)
    out["lunge_l"] = np.where(m & left, e * cyc, 0.0)
    out["lunge_r"] = np.where(m & ~left, e * cyc, 0.0)
    m = K == ARMS
    out["raise_l"] = np.where(m & ((V == 0) | ((V == 2) & ~odd)), e * cyc, 0.0)
    out["raise_r"] = np.where(m & ((V == 0) | ((V == 2) & odd)), e * cyc, 0.0)
    out["lateral"] = np.where(m & (V == 1), e * cyc, 0.0)
    out["curl"] = np.where(m & (V == 3), e * cyc, 0.0)
    out["jack"] = np.where(K == JACKS, e * cyc, 0.0)
    m = K == BEND
    out["bend"] = np.where(m & ((V == 0) | (V == 3)), e * cyc * np.where(V == 3, 0.6, 1.0), 0.0)
    out["side"] = np.where(m & (V == 1), e * sgn, 0.0)
    out["twist"] = np.where(m & (V == 2), e * sgn, 0.0)
    return out


def _yaw_curve(rng: np.random.Generator, t: np.ndarray, max_yaw_deg: float) -> np.ndarray:
    """Turning in place: smoothstep moves between random targets in +-max_yaw."""
    total = float(t[-1]) + 1.0 if len(t) else 1.0
    n = int(np.ceil(total / 3.0)) + 2
    gaps = rng.uniform(3.0, 10.0, n)
    knots = np.concatenate([[t[0] if len(t) else 0.0], t[0] + np.cumsum(gaps)[:-1]])
    target = rng.uniform(-max_yaw_deg, max_yaw_deg, n)
    target[rng.random(n) < 0.35] = 0.0
    target[0] = rng.uniform(-20.0, 20.0)
    trans = rng.uniform(1.0, 2.5, n)
    yaw, _, _ = _knot_interp(t, knots, target * _DEG, trans)
    return yaw


# --------------------------------------------------------------------------- motion
def generate_motion(body: BodyModel, frames: int, fps: float = 30.0,
                    rng: np.random.Generator | None = None,
                    max_yaw_deg: float = 70.0) -> np.ndarray:
    """Joint positions ``(T, 25, 3)`` in units of height, body frame, order of FULL_JOINTS.

    Args:
        body: the individual (see :func:`mirrorgraph.synth.body.make_body`).
        frames: number of frames ``T``.
        fps: frame rate; the motion is defined in seconds.
        rng: random generator (a fresh default one if ``None``).
        max_yaw_deg: largest turn away from the initial facing, in degrees.
    """
    rng = np.random.default_rng() if rng is None else rng
    T = int(frames)
    t = np.arange(T, dtype=float) / float(fps)
    L = body.lengths
    act = _schedule(rng, t)
    yaw = _yaw_curve(rng, t, max_yaw_deg)
    P = np.zeros((T, len(FULL_JOINTS), 3))
    feet_xz, feet_yaw, feet_lift = _foot_steps(rng, t, fps, L, yaw)
    ankles, fwd, lat = _ankles(t, fps, L, act, yaw, feet_xz, feet_lift)
    pelvis, R_pel, hips = _pelvis(P, rng, t, L, act, yaw, ankles, fwd, lat)
    _legs(P, body, hips, ankles, R_pel, feet_yaw)
    neck, R_ch, shoulders = _trunk(P, rng, t, L, act, pelvis, R_pel)
    _head(P, rng, t, body, act, neck, R_ch)
    _arms(P, rng, t, L, act, R_ch, shoulders)
    return P


# --------------------------------------------------------------------------- its parts
# Each part draws from ``rng`` in the order generate_motion calls them: the same seed, the
# same motion.
def _foot_steps(rng: np.random.Generator, t: np.ndarray, fps: float, L: dict, yaw: np.ndarray):
    """The feet's steps on the floor: ``(feet_xz, feet_yaw, feet_lift)``, one ``(T, 3)``
    position, ``(T,)`` yaw and ``(T,)`` lift a foot (left, right)."""
    T = len(t)
    hw = L["hip_width"] / 2
    stance = hw + 0.012
    wander = np.stack([_wiggle(rng, t, 0.12, 1 / 60, 1 / 8), np.zeros(T),
                       _wiggle(rng, t, 0.12, 1 / 60, 1 / 8)], -1)
    total = float(t[-1]) + 1.0 if T else 1.0
    ns = int(np.ceil(total / 1.0)) + 4
    step_t = np.cumsum(rng.uniform(1.0, 2.0, ns)) - 1.5 + (t[0] if T else 0.0)
    step_dur = 0.5
    feet_xz, feet_yaw, feet_lift = [], [], []
    toe_out = 8.0 * _DEG
    for side, sx in ((0, 1.0), (1, -1.0)):
        kn = step_t[side::2]
        kn = np.concatenate([[min(kn[0], t[0] if T else 0.0) - 10.0], kn])
        look = np.clip(kn + step_dur, 0.0, None)
        idx = np.clip(np.rint(look * fps).astype(int), 0, max(T - 1, 0))
        y_k = yaw[idx] if T else np.zeros(len(kn))
        off = np.stack([sx * stance * np.cos(y_k), np.zeros_like(y_k),
                        -sx * stance * np.sin(y_k)], -1)
        tgt = (wander[idx] if T else np.zeros((len(kn), 3))) + off
        pos, u, k = _knot_interp(t, kn, tgt, step_dur)
        fy, _, _ = _knot_interp(t, kn, y_k + sx * toe_out, step_dur)
        step_len = np.linalg.norm(tgt[k] - tgt[np.maximum(k - 1, 0)], axis=-1)
        lift = 0.04 * np.sin(np.pi * u) ** 2 * np.clip(step_len / 0.03, 0.0, 1.0)
        feet_xz.append(pos)
        feet_yaw.append(fy)
        feet_lift.append(lift)
    return feet_xz, feet_yaw, feet_lift


def _ankles(t: np.ndarray, fps: float, L: dict, act: dict, yaw: np.ndarray, feet_xz: list,
            feet_lift: list):
    """The ankles ``(T, 3)`` (left, right) with the exercises' offsets of the feet, in the
    current facing (yaw) frame, and that frame's forward and lateral axes ``(T, 3)``."""
    T = len(t)
    jack, lun_l, lun_r = act["jack"], act["lunge_l"], act["lunge_r"]
    fwd = np.stack([np.sin(yaw), np.zeros(T), np.cos(yaw)], -1)
    lat = np.stack([np.cos(yaw), np.zeros(T), -np.sin(yaw)], -1)   # body +x (left)
    dt = 1.0 / float(fps)
    ankles = []
    for side, sx in ((0, 1.0), (1, -1.0)):
        lun_me, lun_other = (lun_l, lun_r) if side == 0 else (lun_r, lun_l)
        o_lat = sx * 0.11 * jack
        o_fwd = 0.30 * lun_me - 0.05 * lun_other
        off = lat * o_lat[:, None] + fwd * o_fwd[:, None]
        if T > 1:
            v = np.gradient(np.stack([o_lat, o_fwd], -1), dt, axis=0)
            speed = np.sqrt((v ** 2).sum(-1) + 1e-4) - 1e-2
        else:
            speed = np.zeros(T)
        ex_lift = 0.035 * np.tanh(0.12 * speed / 0.035)
        a = feet_xz[side] + off
        a[:, 1] = L["ankle_height"] + feet_lift[side] + ex_lift
        ankles.append(a)
    return ankles, fwd, lat


def _pelvis(P: np.ndarray, rng: np.random.Generator, t: np.ndarray, L: dict, act: dict,
            yaw: np.ndarray, ankles: list, fwd: np.ndarray, lat: np.ndarray):
    """The pelvis over the ankles (``mid_hip`` set in ``P``): ``(pelvis, R_pel, hips)``."""
    I = FULL_INDEX
    hw = L["hip_width"] / 2
    leg = L["femur"] + L["tibia"]
    jack, lun_l, lun_r = act["jack"], act["lunge_l"], act["lunge_r"]
    squat, bend = act["squat"], act["bend"]
    lunge = lun_l + lun_r
    mid = (ankles[0] + ankles[1]) / 2
    pelvis = mid.copy()
    back = 0.10 * squat + 0.06 * bend
    pelvis -= fwd * back[:, None]
    pelvis += lat * _wiggle(rng, t, 0.008)[:, None]
    pelvis[:, 1] = (L["ankle_height"] + 0.985 * leg - 0.26 * squat - 0.16 * lunge
                    - 0.02 * jack - 0.01 * bend + _wiggle(rng, t, 0.004))
    p_pitch = (20 * squat + 25 * bend + 5 * lunge) * _DEG + _wiggle(rng, t, 2 * _DEG)
    p_roll = 5 * act["side"] * _DEG + _wiggle(rng, t, 1.5 * _DEG)
    R_pel = _ry(yaw + _wiggle(rng, t, 3 * _DEG)) @ _rx(p_pitch) @ _rz(p_roll)
    P[:, I["mid_hip"]] = pelvis
    hips = [pelvis + _mv(R_pel, np.array([sx * hw, 0.0, 0.0])) for sx in (1.0, -1.0)]
    return pelvis, R_pel, hips


def _legs(P: np.ndarray, body: BodyModel, hips: list, ankles: list, R_pel: np.ndarray,
          feet_yaw: list) -> None:
    """Knees by two-bone IK between hips and ankles, and the feet's points, set in ``P``."""
    T, I, L = len(P), FULL_INDEX, body.lengths
    L1, L2 = L["femur"], L["tibia"]
    reach = 0.998 * (L1 + L2)
    kk = 0.004
    for side, name in ((0, "left"), (1, "right")):
        Hp, A = hips[side], ankles[side]
        v = A - Hp
        dist = np.linalg.norm(v, axis=-1)
        vh = v / dist[:, None]
        # smooth minimum of dist and reach (pulls an out-of-reach ankle in)
        m = np.minimum(dist, reach)
        dc = m - kk * np.log(np.exp(-(dist - m) / kk) + np.exp(-(reach - m) / kk))
        A2 = Hp + vh * dc[:, None]
        a = (L1 * L1 - L2 * L2 + dc * dc) / (2 * dc)
        r = np.sqrt(np.maximum(L1 * L1 - a * a, 0.0))
        fy = feet_yaw[side]
        ffwd = np.stack([np.sin(fy), np.zeros(T), np.cos(fy)], -1)
        pole = ffwd + _mv(R_pel, np.array([0.0, 0.0, 1.0]))
        pole -= (pole * vh).sum(-1, keepdims=True) * vh
        pole /= np.linalg.norm(pole, axis=-1, keepdims=True)
        knee = Hp + vh * a[:, None] + pole * r[:, None]
        P[:, I[f"{name}_hip"]] = Hp
        P[:, I[f"{name}_knee"]] = knee
        P[:, I[f"{name}_ankle"]] = A2
        rise = A2[:, 1] - A[:, 1]
        toe = body.foot["big_toe"][2]
        pitch = np.arcsin(np.clip(rise / toe, 0.0, 0.8))
        R_foot = _ry(fy) @ _rx(pitch)
        sx = 1.0 if side == 0 else -1.0
        for pt in ("heel", "big_toe", "small_toe"):
            o = body.foot[pt] * np.array([sx, 1.0, 1.0])
            P[:, I[f"{name}_{pt}"]] = A2 + _mv(R_foot, o)


def _trunk(P: np.ndarray, rng: np.random.Generator, t: np.ndarray, L: dict, act: dict,
           pelvis: np.ndarray, R_pel: np.ndarray):
    """The spine up to the neck and shoulders (set in ``P``): ``(neck, R_ch, shoulders)``."""
    I = FULL_INDEX
    squat, bend = act["squat"], act["bend"]
    side, twist = act["side"], act["twist"]
    R_lum = R_pel @ _ry(15 * twist * _DEG + _wiggle(rng, t, 3 * _DEG)) @ _rx(
        (10 * squat + 20 * bend) * _DEG + _wiggle(rng, t, 2 * _DEG)) @ _rz(10 * side * _DEG)
    spine1 = pelvis + _mv(R_pel, np.array([0.0, L["lumbar"], 0.0]))
    R_ch = R_lum @ _ry(20 * twist * _DEG) @ _rx(15 * bend * _DEG + _wiggle(rng, t, 2 * _DEG)) \
        @ _rz(10 * side * _DEG + _wiggle(rng, t, 1.5 * _DEG))
    spine2 = spine1 + _mv(R_lum, np.array([0.0, L["thoracic"], 0.0]))
    neck = spine2 + _mv(R_ch, np.array([0.0, L["upper_trunk"], 0.0]))
    P[:, I["neck"]] = neck
    sw = L["shoulder_width"] / 2
    shoulders = [neck + _mv(R_ch, np.array([sx * sw, 0.0, 0.0])) for sx in (1.0, -1.0)]
    P[:, I["left_shoulder"]], P[:, I["right_shoulder"]] = shoulders
    return neck, R_ch, shoulders


def _head(P: np.ndarray, rng: np.random.Generator, t: np.ndarray, body: BodyModel, act: dict,
          neck: np.ndarray, R_ch: np.ndarray) -> None:
    """The head's points (eyes, ears, nose), set in ``P``."""
    I, L = FULL_INDEX, body.lengths
    bend = act["bend"]
    R_head = R_ch @ _ry(_wiggle(rng, t, 20 * _DEG, 0.03, 0.2)) @ _rx(
        _wiggle(rng, t, 10 * _DEG, 0.03, 0.3) - 12 * bend * _DEG) @ _rz(_wiggle(rng, t, 5 * _DEG))
    pivot = neck + _mv(R_head, np.array([0.0, L["neck"], 0.0]))
    for pt in ("eye", "ear"):
        for sx, name in ((1.0, "left"), (-1.0, "right")):
            P[:, I[f"{name}_{pt}"]] = pivot + _mv(R_head, body.head[pt] * np.array([sx, 1, 1]))
    P[:, I["nose"]] = pivot + _mv(R_head, body.head["nose"])


def _arms(P: np.ndarray, rng: np.random.Generator, t: np.ndarray, L: dict, act: dict,
          R_ch: np.ndarray, shoulders: list) -> None:
    """Elbows and wrists, set in ``P``."""
    I = FULL_INDEX
    bend, jack = act["bend"], act["jack"]
    hang = 60 * bend + 85 * act["squat_arms"]
    for side_i, (sx, name) in enumerate(((1.0, "left"), (-1.0, "right"))):
        raise_ = act["raise_l"] if side_i == 0 else act["raise_r"]
        flex = (_wiggle(rng, t, 8 * _DEG) + (hang + 170 * raise_ + 10 * act["curl"]) * _DEG)
        abd = (10 + _wiggle(rng, t, 4.0) + 165 * act["lateral"] + 155 * jack
               + 35 * act["squat_hips"]) * _DEG
        rot = _wiggle(rng, t, 15 * _DEG) + 20 * act["squat_hips"] * _DEG
        elbow = (15 + _wiggle(rng, t, 8.0) + 120 * act["curl"] + 95 * act["squat_hips"]) * _DEG
        R_sh = R_ch @ _rz(sx * abd) @ _rx(-flex) @ _ry(sx * rot)
        elb = shoulders[side_i] + _mv(R_sh, np.array([0.0, -L["humerus"], 0.0]))
        R_el = R_sh @ _rx(-elbow)
        wri = elb + _mv(R_el, np.array([0.0, -L["ulna"], 0.0]))
        P[:, I[f"{name}_elbow"]] = elb
        P[:, I[f"{name}_wrist"]] = wri
