"""The graph's prior factors: body priors, bone sets, the gauge's weights, intrinsics priors.

The builder (:mod:`.builder`) adds them: the bone factors of a set of (frame, bone)
pairs (:class:`BoneSet`), the length-only priors on :data:`~.problem.LENGTH_KEY`
(left/right symmetry, Winter's anthropometric ratios to the femur), the per-frame
priors (hip colinearity, smoothness), the weights of the bone-length-sum gauge
(:func:`gauge_weights`) and the prior of an estimated camera's intrinsics
(:func:`intrinsics_prior`). Each records itself in the problem's ``prior_info``
(:func:`record_prior`: sigma, weight, unit, count).
"""

from __future__ import annotations

from dataclasses import dataclass

import gtsam
import numpy as np

from ..anthropometry import femur_ratios, height_fractions
from ..skeletons import person_of
from ..factors import (AnthropometricRatioFactor, HipColinearityFactor, SmoothnessFactor,
                       SymmetryFactor, TorsoFactors, torso_pairs)
from .bones import median_bone_lengths
from .problem import LENGTH_KEY

__all__ = ["BoneSet", "record_prior", "add_symmetry", "add_anthropometry", "add_focal_prior",
           "add_hip", "add_smoothness", "add_torso", "torso_table", "torso_lengths",
           "other_side_lengths", "gauge_weights", "intrinsics_prior", "intrinsics_prior_sigmas",
           "PRINCIPAL_POINT_PRIOR", "PRINCIPAL_POINT_HOLD"]


def record_prior(info: dict, name: str, sigma: float, unit: str, count: int) -> None:
    """``info[name]``: the prior's sigma, weight ``1 / sigma^2``, unit and ``count`` of
    factors (nothing without factors)."""
    if count:
        info[name] = {"sigma": float(sigma), "weight": 1.0 / float(sigma) ** 2, "unit": unit,
                      "factors": int(count)}


@dataclass
class BoneSet:
    """The bone factors of a graph: which (frame, bone) pairs, their held lengths."""

    names: list[str]
    rows: np.ndarray            # (N, 3): key-order positions of the two joints, bone index
    lengths: np.ndarray | None
    sigma: float

    @classmethod
    def empty(cls, sigma: float) -> "BoneSet":
        return cls([], np.zeros((0, 3), dtype=np.int64), None, float(sigma))

    @classmethod
    def make(cls, keep: np.ndarray, points: np.ndarray, names: list[str], pairs: np.ndarray,
             flat: np.ndarray, J: int, sigma: float, init: dict[str, float] | None
             ) -> "BoneSet":
        """The bones of ``keep`` (``(T, B)``), their lengths from ``init`` or else the
        median over the kept frames; ``flat``: the used points' ``t * J + j`` (key order)."""
        present = np.flatnonzero(keep.any(0))
        if len(present) == 0:
            return cls.empty(sigma)
        names = [names[b] for b in present]
        pairs, keep = pairs[present], keep[:, present]
        medians = median_bone_lengths(points, pairs, keep)
        lengths = np.array([float(init[n]) if init is not None and n in init else medians[b]
                            for b, n in enumerate(names)])
        pos = np.full(keep.shape[0] * J, -1, dtype=np.int64)
        pos[flat] = np.arange(len(flat))
        t, b = np.nonzero(keep)
        rows = np.stack([pos[t * J + pairs[b, 0]], pos[t * J + pairs[b, 1]], b], axis=1)
        return cls(names, rows, lengths, float(sigma))


def gauge_weights(rows: np.ndarray, num_bones: int) -> np.ndarray:
    """``(B,)`` weight of each bone length in the gauge where the lengths are a variable
    of the graph: its frames (rows of ``rows[:, 2]``), scaled to a mean of 1.

    The gauge holds a sum of lengths, and every other length-valued term (a bone's
    constancy, the smoothness) costs less in a smaller scene (:mod:`mirrorgraph.factors.
    gauge`): a plain sum lets a bone that few frames measure carry it, stretched (its
    joints moved along their lines of sight, cheap in a few frames) while the rest of
    the body and the scene shrink. Without the anthropometric ratios, which tie every
    length to the others (:attr:`~.options.FocalOptions.anthropometry` leaves them out
    where a focal length is estimated), nothing else stops it: a hip width measured in
    one frame of 960 can stretch to 12 times the shoulder width, the scene shrink 3.5
    times and the stature measured on the distorted body put the mirror 30 % short.
    Weighted by its frames (the information of its mean length, as in
    :func:`~.lengths.update_lengths`), a bone moves the gauge in proportion to what
    holds it: the shrink a stretch buys is the same per frame whichever bone it is.
    """
    n = np.bincount(np.asarray(rows, dtype=np.int64)[:, 2], minlength=num_bones)
    n = n[:num_bones].astype(float)
    return n * (num_bones / n.sum()) if n.sum() > 0 else np.ones(num_bones)


def add_symmetry(rig, graph, bone_names, sigma, options, info):
    """Left/right symmetry priors on the length vector :data:`~.problem.LENGTH_KEY`: one
    per pair of symmetric bones both among ``bone_names`` (``sigma``, graph units);
    only with ``options.use_symmetry``."""
    if not options.use_symmetry:
        return
    factor = SymmetryFactor(sigma)
    index = {b: i for i, b in enumerate(bone_names)}
    count = 0
    for left, right in rig.skeleton.symmetric_bones:
        if left in index and right in index:
            graph.push_back(factor.make(LENGTH_KEY, index[left], index[right]))
            count += 1
    record_prior(info, "symmetry", sigma, "length", count)


def add_anthropometry(rig, graph, bone_names, options, info):
    """Every bone's ratio to the femurs (Winter 2009, :func:`~mirrorgraph.anthropometry.
    femur_ratios`) on :data:`~.problem.LENGTH_KEY`, ``options.anthropometry_sigma``;
    only with ``options.use_anthropometry`` and a femur among ``bone_names``."""
    if not options.use_anthropometry:
        return
    index = {b: i for i, b in enumerate(bone_names)}
    ratios = femur_ratios(rig.skeleton)
    factor = AnthropometricRatioFactor(options.anthropometry_sigma)
    count, bodies = 0, 0
    # each person's bones against their own femurs (several people: skeletons.people_skeleton)
    for tag in dict.fromkeys(person_of(b) for b in index):
        femurs = [index[b + tag] for b in ("left_femur", "right_femur") if b + tag in index]
        if not femurs:
            continue
        bodies += 1
        for name, i in index.items():
            if name.endswith("femur" + tag) or person_of(name) != tag:
                continue
            graph.push_back(factor.make(LENGTH_KEY, i, femurs, ratios[name]))
            count += 1
    if not bodies:
        return
    record_prior(info, "anthropometry", options.anthropometry_sigma, "ratio (Winter 2009)",
                 count)


def add_hip(rig, graph, used, keys, h, options, info):
    """Hip colinearity (mid-hip on the line of the two hips, ``options.hip_sigma``, a
    sine) in every frame where the three joints are used; ``keys``: ``(T, J)`` joint keys,
    ``h``: the subject height in graph units."""
    sk = rig.skeleton
    if sk.mid_hip is None:
        return
    joints = set(np.asarray(rig.joints, dtype=int).tolist())
    m, lh, rh = sk.index(sk.mid_hip), sk.index("left_hip"), sk.index("right_hip")
    if not {m, lh, rh} <= joints:
        return
    scale = h * height_fractions(sk).get("left_pelvis", 0.0955)
    factor = HipColinearityFactor(scale, options.hip_sigma)
    frames = np.flatnonzero(used[:, m] & used[:, lh] & used[:, rh])
    for t in frames:
        graph.push_back(factor.make(int(keys[t, m]), int(keys[t, lh]), int(keys[t, rh])))
    record_prior(info, "hip", options.hip_sigma, "sine", len(frames))


def torso_table(rig) -> tuple[list[str], np.ndarray]:
    """The torso's distances that no bone holds (:func:`~mirrorgraph.factors.torso_pairs`)
    between joints the rig estimates: ``"a-b"`` names (the two joints' names) and
    ``(P, 2)`` joint indices."""
    sk = rig.skeleton
    names = list(sk.joints)
    keep = set(np.asarray(rig.joints, dtype=int).tolist())
    pairs = np.array([p for p in torso_pairs(names, np.asarray(sk.bone_index, int)).tolist()
                      if p[0] in keep and p[1] in keep], dtype=int).reshape(-1, 2)
    return [f"{names[a]}-{names[b]}" for a, b in pairs.tolist()], pairs


def torso_lengths(rig, points: np.ndarray, used: np.ndarray,
                  frames: np.ndarray | None = None) -> dict[str, float]:
    """The torso's distances that no bone holds (:func:`torso_table`), each its median
    over the frames of ``points`` (``(T, J, 3)``) where both its joints are ``used``
    (``(T, J)``) and, with ``frames`` (``(T, P)`` bool, :func:`torso_table`'s order),
    the distance's own frames. The points must hold their depth: joints the bones and
    the smoothness hold (the joints pass's), or the frames where the rays meet at an
    angle that fixes it (:func:`~.bones.bone_curvature_bias` under the bone rule); raw
    triangulations of rays that meet at a few degrees would not do (their depth noise
    is decimetres, and first-order corrections of it fail: a diagonal 25-55 % short on
    a 300-frame clip).

    Returns:
        ``"a-b"`` -> length in graph units; a distance seen in no frame is left out.
    """
    names, pairs = torso_table(rig)
    if not len(pairs):
        return {}
    both = used[:, pairs[:, 0]] & used[:, pairs[:, 1]]
    if frames is not None:
        both = both & np.asarray(frames, bool)
    med = median_bone_lengths(points, pairs, both)
    return {n: float(v) for n, v in zip(names, med) if np.isfinite(v) and v > 0}


def other_side_lengths(skeleton, lengths: dict[str, float]) -> tuple[dict[str, float],
                                                                     list[str]]:
    """``lengths`` with each bone it lacks given its left/right partner's length
    (``skeleton.symmetric_bones``: a healthy adult's limbs differ by millimetres,
    the paper's ``L_sym``), and the names so given. A limb left without any length
    has no body term in the joints pass, and where its joints' rays meet at a small
    angle nothing holds their depth."""
    out = dict(lengths)
    given = []
    for left, right in skeleton.symmetric_bones:
        for a, b in ((left, right), (right, left)):
            if a not in out and b in lengths:
                out[a] = float(lengths[b])
                given.append(a)
    return out, given


def add_torso(rig, graph, used, keys, lengths: dict[str, float], sigma, info):
    """The torso nearly rigid (:mod:`mirrorgraph.factors.torso`): each distance of
    ``lengths`` (``"a-b"`` joint names -> length, :func:`torso_lengths`) at its length,
    standard deviation ``sigma`` (graph units), in every frame where both joints are
    used; ``keys``: ``(T, J)`` joint keys."""
    if not lengths:
        return
    sk = rig.skeleton
    factor = TorsoFactors(sigma)
    count = 0
    for pair, length in lengths.items():
        a, b = (sk.index(n) for n in pair.split("-"))
        t = np.flatnonzero(used[:, a] & used[:, b])
        factor.add(graph, keys[t, a], keys[t, b], np.full(len(t), float(length)))
        count += len(t)
    record_prior(info, "torso", sigma, "length", count)
    if count:
        info["torso"]["lengths"] = {k: float(v) for k, v in lengths.items()}


def add_smoothness(rig, graph, values, used, keys, points, sigma, max_gap, info):
    """Smoothness of every estimated joint's track: second differences over its frames
    (``rig.frame_ids``, gaps up to ``max_gap``), ``sigma`` in graph units / frame^2;
    ``points``: ``(T, J, 3)`` the initial joints."""
    factor = SmoothnessFactor(sigma, max_gap)
    fid = np.asarray(rig.frame_ids, dtype=np.int64)
    triples = []
    for j in np.asarray(rig.joints, dtype=int):
        rows = np.flatnonzero(used[:, j])
        tri = rows[factor.triples(fid[rows])]
        if len(tri):
            triples.append(np.stack([tri, np.full_like(tri, j)], axis=-1))      # (M, 3, 2)
    count = 0
    if triples:
        tri = np.concatenate(triples)
        k = keys[tri[..., 0], tri[..., 1]]                                      # (M, 3)
        X = np.asarray(points, dtype=float)[tri[..., 0], tri[..., 1]]           # (M, 3, 3)
        factor.add_many(graph, k, fid[tri[..., 0]], X, values)
        count = len(tri)
    record_prior(info, "smoothness", sigma, "length / frame^2", count)


#: Standard deviation of the principal point's prior where it is estimated without a
#: :attr:`~.rig.Camera.principal_point_prior`, fraction of the image width (``2 cx`` of
#: the initial ``K``): the loose prior of ``--principal-point free``.
PRINCIPAL_POINT_PRIOR = 0.05


#: Where a principal point has a prior of the population of cameras
#: (:attr:`~.rig.Camera.principal_point_prior`), the graph's factor holds it at this
#: fraction of that prior's sigma: the estimate keeps the centre, and the uncertainty
#: takes the population's spread (:func:`intrinsics_prior_sigmas`,
#: :func:`~.scores.intrinsics_prior_spread`: a "consider" parameter). The people
#: pull it, but wrongly: on the independent generator's scenes estimating it from them
#: turns the mirror by 6.8 and 1.2 deg (0.008 and 0.016 with the true intrinsics), on a
#: 20 px offset the data move it 42 px the other way (tests/graph/
#: test_focal_principal_point.py).
PRINCIPAL_POINT_HOLD = 1e-3


def intrinsics_prior(camera, population: bool = False) -> tuple[gtsam.Cal3_S2, np.ndarray] | None:
    """The prior of an estimated camera's intrinsics: its mean and ``(5,)`` sigmas on the
    :class:`gtsam.Cal3_S2` coordinates ``(fx, fy, s, cx, cy)`` (px), or ``None`` without
    one. ``fx`` and ``fy`` move together (one unknown ``f``): each at ``sigma sqrt(2)`` is
    ``sigma`` on ``f`` (:func:`intrinsics_prior_sigmas`). A principal point with a
    population prior is held in the graph (:data:`PRINCIPAL_POINT_HOLD`); ``population``:
    that prior's own sigma (the uncertainty's)."""
    if camera.focal_prior is None and not camera.estimate_principal_point:
        return None
    K = np.asarray(camera.K, dtype=float)
    f0, sigma = camera.focal_prior if camera.focal_prior is not None else (K[0, 0], 1e9)
    cx, cy = float(K[0, 2]), float(K[1, 2])
    sp = 1e9
    if camera.estimate_principal_point:
        if camera.principal_point_prior is not None:
            cx, cy, sp = (float(v) for v in camera.principal_point_prior)
            sp = sp if population else sp * PRINCIPAL_POINT_HOLD
        else:
            sp = PRINCIPAL_POINT_PRIOR * 2.0 * cx
    sigmas = np.array([sigma * np.sqrt(2.0), sigma * np.sqrt(2.0), 1e9, sp, sp])
    return gtsam.Cal3_S2(f0, f0, 0.0, cx, cy), sigmas


def intrinsics_prior_sigmas(camera) -> np.ndarray:
    """``(d,)`` the prior's standard deviations on the camera's reduced intrinsics
    (:mod:`.reduction`: ``f`` or ``f, cx, cy``, px; ``inf`` where it has none)."""
    d = camera.intrinsics_dim
    prior = intrinsics_prior(camera, population=True)
    if prior is None:
        return np.full(d, np.inf)
    s = prior[1]
    return np.array([s[0] / np.sqrt(2.0), s[3], s[4]])[:d]


def add_focal_prior(camera, key, graph, info):
    """The prior of :func:`intrinsics_prior` on ``K(c)``: the weak one of
    :attr:`~.rig.Camera.focal_prior` on the focal length, and where the principal point
    is estimated its :attr:`~.rig.Camera.principal_point_prior`.

    Where the scene's straight lines witness the focal length
    (:attr:`~.options.FocalOptions.lines`), ``focal_prior`` is the product of the
    guess's Gaussian and the lines' (:func:`mirrorgraph.pipelines.lines.fuse_gaussians`):
    two Gaussian priors on one variable are this one factor, so its record in ``info``
    (``focal_prior_<camera>``: sigma, weight) is the two together."""
    prior = intrinsics_prior(camera)
    if prior is None:
        return
    mean, sigmas = prior
    population = intrinsics_prior(camera, population=True)[1]
    graph.push_back(gtsam.PriorFactorCal3_S2(key, mean,
                                             gtsam.noiseModel.Diagonal.Sigmas(sigmas)))
    sigma = float(sigmas[0] / np.sqrt(2.0))
    info[f"focal_prior_{camera.name}"] = {"sigma": sigma, "weight": 1.0 / sigma ** 2,
                                          "unit": "px", "factors": 1,
                                          "focal_px": float(mean.fx())}
    if camera.estimate_principal_point:
        info[f"principal_point_prior_{camera.name}"] = {
            "sigma": float(population[3]), "weight": 1.0 / float(population[3]) ** 2,
            "unit": "px", "factors": 1, "principal_point_px": [float(mean.px()), float(mean.py())],
            "held": bool(sigmas[3] < population[3])}
