"""Standing height from 3D joints: the anatomical (segment-sum) method.

Reflections and views carry no absolute scale; it comes from the subject's standing
height ``H``, which needs the same height measured in the reconstruction's units.
Stature is the sum of the heights of the segments stacked from the floor to the vertex
(G. Fully, "Une nouvelle methode de determination de la taille", *Ann. Med. Leg.* 36,
1956; Raxter, Auerbach and Ruff, "Revision of the Fully technique for estimating
statures", *Am. J. Phys. Anthropol.* 130, 2006), measured per frame, median over frames:

==========  =========================================================  ============
segment     measured as                                                Winter, H
==========  =========================================================  ============
shank       ``|knee - ankle|``, both sides                             0.246
thigh       ``|hip - knee|``, both sides                               0.245
trunk       ``|mid-shoulder - mid-hip|``                               0.288
head        ``(top - mid-shoulder) . u``, ``u`` the unit trunk axis    0.118 / 0.182
==========  =========================================================  ============

``top`` is ``head_top`` where the skeleton has one (BODY_25B, HALPE_26), else the
midpoint of the eyes; mid-points come from the left and right joints. What no keypoint
spans comes from Winter's landmark heights
(:data:`mirrorgraph.anthropometry.LANDMARK_HEIGHT`): the ankle above the floor (0.039 H)
and, with the eyes as top, the vertex above the eyes (0.064 H):

    H = (shank + thigh + trunk + head) / (1 - unmeasured fraction).

On synthetic subjects with 3 % individual variation per segment this gives ~0.2 % RMS
scale error against ~1.1 % from limb proportions (``bench/RESULTS_rig.md``). The medians
assume the subject is upright for most frames; a video spent sitting or bent over
shortens the estimate. A real skeleton's posture moves it too: the CMU take 01_01's true
joints measure 0.9 % short at the skeleton's own rest pose (its trunk axis leans 11 deg
back from its head) and 1.4 % over the take (jumps, never upright;
``bench/RESULTS_scale_cmu.md``). The measurement's own spread: :func:`measurement_rel_std`,
:func:`bones_rel_spread`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .anthropometry import (HEIGHT_FRACTION, HEIGHT_FRACTION_CV, KEYPOINT_OFFSET,
                            LANDMARK_HEIGHT, UNMEASURED_STD, bone_kind)
from .skeletons import Skeleton

__all__ = ["StatureEstimate", "estimate_stature", "stature_joints", "stature_rescale",
           "with_height_sigma", "measurement_rel_std", "bones_rel_spread", "keypoint_rel_std",
           "unmeasured_rel_std",
           "limbs_rel_std", "keypoint_offset_fraction", "segment_rel_std", "MIN_FRAMES",
           "SAMPLING_BLOCKS", "BONES_ALPHA", "WILD_RATIO", "SEGMENT_REL_STD",
           "LIMB_PROPORTIONS", "LIMB_CHOSEN"]

#: A segment needs at least this many frames with both its end points.
MIN_FRAMES = 10

#: Most blocks of consecutive frames the stature's sampling std is measured over (batch
#: means: each block's own stature, their spread; :attr:`StatureEstimate.sampling_rel_std`).
SAMPLING_BLOCKS = 8

#: The segments' disagreement about the height is the measurement's own where it exceeds
#: what adults and keypoints give with this probability (one-sided: a body measured right
#: is taken as distorted in 5 % of cases; :func:`bones_rel_spread`).
BONES_ALPHA = 0.05

#: A segment kind outside the chain (arms, widths) whose height is this factor or more off
#: the chain's (half as long again, or two thirds) is taken as a limb the reconstruction
#: failed, which the chain does not use, and left out of :func:`bones_rel_spread`: an arm
#: that far is over 5 std of adults and keypoints (:data:`SEGMENT_REL_STD`), a width over 2
#: (the hips' keypoints may lie far inside Winter's hip width).
WILD_RATIO = 1.5
#: The segment kinds the stature chain is made of (never left out).
_CHAIN_KINDS = ("leg", "trunk")
#: The limbs measured whole (the inner joint's placement cancels): kind -> the bones'
#: kinds in :data:`~mirrorgraph.anthropometry.HEIGHT_FRACTION` and their joints.
_WHOLE_LIMBS = {"leg": (("femur", "hip", "knee"), ("tibia", "knee", "ankle")),
                "arm": (("humerus", "shoulder", "elbow"), ("ulna", "elbow", "wrist"))}
#: Width bones (a half width from a neck or a mid-hip joint, or the whole) -> their kind.
_WIDTH_KIND = {"scapular": "shoulder_width", "pelvis": "hip_width",
               "shoulder_width": "shoulder_width", "hip_width": "hip_width"}


def segment_rel_std(keypoint_offset: float = KEYPOINT_OFFSET) -> dict[str, float]:
    """Segment kind -> the relative std of the height it gives over adults and detectors:
    the anatomical spread (:data:`~mirrorgraph.anthropometry.HEIGHT_FRACTION_CV`; a limb's
    the length-weighted mean of its bones', an upper bound for a sum) and the keypoints'
    placement (``o``: ``sqrt(2) o / f`` for a limb or the trunk, ``2 o / f`` for a width,
    ``f`` its fraction), in quadrature.

    Args:
        keypoint_offset: ``o``, where the keypoints lie off their anatomical landmarks, a
            fraction of the height (:data:`~mirrorgraph.anthropometry.KEYPOINT_OFFSET` by
            default; :func:`keypoint_offset_fraction` from metres).

    Returns:
        Kind -> relative std (dimensionless).
    """
    o = float(keypoint_offset)
    out = {}
    for kind, parts in _WHOLE_LIMBS.items():
        f = sum(HEIGHT_FRACTION[b] for b, _, _ in parts)
        cv = sum(HEIGHT_FRACTION[b] * HEIGHT_FRACTION_CV[b] for b, _, _ in parts) / f
        out[kind] = math.hypot(cv, math.sqrt(2.0) * o / f)
    f = LANDMARK_HEIGHT["shoulder"] - LANDMARK_HEIGHT["hip"]
    out["trunk"] = math.hypot(HEIGHT_FRACTION_CV["trunk"], math.sqrt(2.0) * o / f)
    for kind in ("shoulder_width", "hip_width"):
        out[kind] = math.hypot(HEIGHT_FRACTION_CV[kind], 2.0 * o / HEIGHT_FRACTION[kind])
    return out


#: Segment kind (``leg``, ``arm``, ``trunk``, ``shoulder_width``, ``hip_width``) -> the
#: relative std of the height it gives (its length over Winter's fraction) among adults
#: measured by keypoints at the literature's placement
#: (:data:`~mirrorgraph.anthropometry.KEYPOINT_OFFSET`): leg 5.7 %, arm 7.9 %, trunk 9.3 %,
#: shoulder width 14 %, hip width 19 % (dimensionless; :func:`segment_rel_std` for another).
SEGMENT_REL_STD: dict[str, float] = segment_rel_std()


def keypoint_offset_fraction(offset_m: float | None, height: float | None) -> float:
    """The keypoints' placement against their anatomical landmarks as a fraction of the
    height, the unit of :func:`keypoint_rel_std`, :func:`limbs_rel_std` and
    :func:`segment_rel_std`.

    Args:
        offset_m: the placement a user states, metres (``RefineOptions.keypoint_offset``),
            or ``None``: the literature's,
            :data:`~mirrorgraph.anthropometry.KEYPOINT_OFFSET` of the height (3.0 cm at
            1.75 m; Needham et al. 2021).
        height: the subject's standing height, metres; ``None`` (no metric scale): the
            literature's fraction, whatever ``offset_m``.

    Returns:
        ``offset_m / height``, or :data:`~mirrorgraph.anthropometry.KEYPOINT_OFFSET`.
    """
    if offset_m is None or height is None:
        return KEYPOINT_OFFSET
    return float(offset_m) / float(height)


#: ``Phi^-1(0.75)``: the median of ``|z|`` for a standard normal ``z``.
_MAD_NORMAL = 0.6744897501960817

_LEGS = ("knee", "ankle", "hip")
_TRUNK = ("shoulder", "hip")


@dataclass(frozen=True)
class StatureEstimate:
    """The subject's standing height measured on 3D joints.

    Attributes:
        height: standing height in the joints' unit (metres if they are).
        segments: ``shank``, ``thigh``, ``trunk``, ``head`` -> median length, the
            joints' unit.
        top: ``"head_top"`` or ``"eyes"``: the highest keypoint used.
        unmeasured_fraction: the part of ``height`` taken from Winter's landmark
            heights (below the ankle, above ``top``).
        frames: frames with every segment measured.
        side_rel_diff: the two legs' measured lengths (shank + thigh, each side's
            medians) apart, ``|L - R| / (L + R)``: the measurement's own spread where a
            detector places one side's joints with a bias (a body's legs differ by
            under 1 %), ``0`` where a side is not measured in enough frames
            (:func:`measurement_rel_std`).
        bone_ratios: segment kind (``leg``: hip to ankle, ``arm``: shoulder to wrist,
            ``trunk``, ``shoulder_width``, ``hip_width``) -> the height its median length
            gives at Winter's fraction, over :attr:`height` (dimensionless; kinds measured
            in fewer than ``min_frames`` frames absent).
        bones_rel_spread: the segments' disagreement about the height beyond the spread
            of adults and keypoints (:func:`bones_rel_spread` of :attr:`bone_ratios`),
            relative; ``0`` where it is within it.
        sampling_rel_std: the height's relative std from the frames measured (batch
            means: the frames cut into up to :data:`SAMPLING_BLOCKS` blocks of consecutive
            frames, each block's stature from its own medians, their standard error; the
            frames' correlation in time stays inside the blocks); it shrinks with the
            frames, unlike :func:`measurement_rel_std`'s spreads, which a longer video
            does not average out; NaN with fewer than three blocks of ``min_frames``.
        scale_from: what made the run's metric scale: ``"stature"`` (this chain, set to
            the given height) or ``"limbs"`` (the gauge's limb proportions, this estimate
            measured on the result only); :func:`measurement_rel_std` follows it.
        keypoint_offset: where the keypoints are taken to lie off their anatomical
            landmarks, a fraction of the height (the literature's
            :data:`~mirrorgraph.anthropometry.KEYPOINT_OFFSET`, or a user's statement,
            ``RefineOptions.keypoint_offset``): the placement term of
            :func:`measurement_rel_std` and the segments' spread of
            :attr:`bones_rel_spread`.
    """

    height: float
    segments: dict[str, float]
    top: str
    unmeasured_fraction: float
    frames: int
    side_rel_diff: float = 0.0
    bone_ratios: dict[str, float] = field(default_factory=dict)
    bones_rel_spread: float = 0.0
    sampling_rel_std: float = float("nan")
    scale_from: str = "stature"
    keypoint_offset: float = KEYPOINT_OFFSET

    def describe(self) -> str:
        """One line for reports: what was measured and what was assumed (the keypoints'
        placement its std holds in the estimate's unit, metres once scaled)."""
        top = "head top" if self.top == "head_top" else "eyes"
        o = self.keypoint_offset
        source = "Needham et al. 2021" if o == KEYPOINT_OFFSET else "as stated"
        return (f"stature measured from ankle to {top} (shank, thigh, trunk, head); "
                f"{100 * self.unmeasured_fraction:.1f} % of it from Winter's landmark heights; "
                f"its std holds keypoints placed {100 * o * self.height:.1f} cm "
                f"({100 * o:.2f} % of the height) off the landmarks ({source})")

    def scaled(self, factor: float) -> "StatureEstimate":
        """The same estimate on joints ``factor`` times larger (height and segments)."""
        f = float(factor)
        return StatureEstimate(height=self.height * f,
                               segments={k: v * f for k, v in self.segments.items()},
                               top=self.top, unmeasured_fraction=self.unmeasured_fraction,
                               frames=self.frames, side_rel_diff=self.side_rel_diff,
                               bone_ratios=dict(self.bone_ratios),
                               bones_rel_spread=self.bones_rel_spread,
                               sampling_rel_std=self.sampling_rel_std,
                               scale_from=self.scale_from,
                               keypoint_offset=self.keypoint_offset)

    def to_dict(self) -> dict:
        """Plain-Python form for JSON."""
        return {"height": float(self.height), "segments": {k: float(v) for k, v in self.segments.items()},
                "top": self.top, "unmeasured_fraction": float(self.unmeasured_fraction),
                "frames": int(self.frames), "side_rel_diff": float(self.side_rel_diff),
                "bone_ratios": {k: float(v) for k, v in self.bone_ratios.items()},
                "bones_rel_spread": float(self.bones_rel_spread),
                "sampling_rel_std": (float(self.sampling_rel_std)
                                     if math.isfinite(self.sampling_rel_std) else None),
                "scale_from": self.scale_from,
                "keypoint_offset": float(self.keypoint_offset),
                "rel_std": measurement_rel_std(self), "method": self.describe()}


def _required(skeleton: Skeleton) -> dict[str, int] | None:
    """Indices of the joints the chain needs, or ``None`` if the skeleton lacks one."""
    names = [f"{s}_{j}" for s in ("left", "right") for j in _LEGS + _TRUNK[:1]]
    if "head_top" in skeleton.joints:
        names.append("head_top")
    else:
        names += ["left_eye", "right_eye"]
    if any(n not in skeleton.joints for n in names):
        return None
    return {n: skeleton.index(n) for n in names}


def stature_joints(skeleton: Skeleton) -> np.ndarray | None:
    """``(k,)`` indices of the joints the stature chain uses, or ``None`` if the skeleton
    lacks one of them."""
    idx = _required(skeleton)
    return None if idx is None else np.array(sorted(idx.values()), dtype=int)


def _median(values: np.ndarray) -> tuple[float, int]:
    """Median of the finite ``values`` and their count."""
    v = values[np.isfinite(values)]
    return (float(np.median(v)) if len(v) else float("nan")), int(len(v))


def estimate_stature(points: np.ndarray, valid: np.ndarray, skeleton: Skeleton, *,
                     min_frames: int = MIN_FRAMES,
                     keypoint_offset: float = KEYPOINT_OFFSET) -> StatureEstimate | None:
    """Standing height from 3D joints by summing the segments of the vertical chain.

    Args:
        points: ``(T, J, 3)`` joints, any frame, any length unit.
        valid: ``(T, J)`` bool, the joints to trust.
        skeleton: their layout (needs left/right ankle, knee, hip, shoulder and
            either ``head_top`` or both eyes).
        min_frames: frames each segment needs.
        keypoint_offset: the keypoints' placement off their landmarks, a fraction of the
            height (:attr:`StatureEstimate.keypoint_offset`; :func:`keypoint_offset_fraction`
            from metres).

    Returns:
        The estimate, or ``None`` when the skeleton lacks a joint of the chain or
        a segment is measured in fewer than ``min_frames`` frames (the caller
        falls back to limb proportions and says so).
    """
    idx = _required(skeleton)
    if idx is None:
        return None
    P = np.where(np.asarray(valid, bool)[..., None], np.asarray(points, float), np.nan)

    def joint(name: str) -> np.ndarray:
        return P[:, idx[name]]

    sides = ("left", "right")
    bone = {(s, a, b): np.linalg.norm(joint(f"{s}_{a}") - joint(f"{s}_{b}"), axis=-1)
            for s in sides for a, b in (("knee", "ankle"), ("hip", "knee"))}

    def both(a: str, b: str) -> np.ndarray:               # (2T,) lengths, both sides
        return np.concatenate([bone[(s, a, b)] for s in sides])

    mid_hip = 0.5 * (joint("left_hip") + joint("right_hip"))
    mid_shoulder = 0.5 * (joint("left_shoulder") + joint("right_shoulder"))
    if "head_top" in idx:
        top, top_name, above = joint("head_top"), "head_top", 1.0 - LANDMARK_HEIGHT["vertex"]
    else:
        top, top_name = 0.5 * (joint("left_eye") + joint("right_eye")), "eyes"
        above = LANDMARK_HEIGHT["vertex"] - LANDMARK_HEIGHT["eye"]
    axis = mid_shoulder - mid_hip
    trunk = np.linalg.norm(axis, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        head = np.einsum("ti,ti->t", top - mid_shoulder, axis) / trunk

    measured = {"shank": _median(both("knee", "ankle")), "thigh": _median(both("hip", "knee")),
                "trunk": _median(trunk), "head": _median(head)}
    if min(n for _, n in measured.values()) < min_frames:
        return None
    segments = {k: v for k, (v, _) in measured.items()}
    if not all(v > 0 for v in segments.values()):
        return None
    unmeasured = LANDMARK_HEIGHT["ankle"] + above
    frames = int(np.sum(np.isfinite(trunk) & np.isfinite(head)))
    legs = []
    for s in sides:
        parts = [_median(bone[(s, a, b)]) for a, b in (("knee", "ankle"), ("hip", "knee"))]
        legs.append(sum(v for v, _ in parts) if min(n for _, n in parts) >= min_frames
                    else float("nan"))
    side = abs(legs[0] - legs[1]) / (legs[0] + legs[1])
    height = sum(segments.values()) / (1.0 - unmeasured)
    ratios = {k: v / height for k, v in _segment_statures(P, skeleton, trunk, min_frames).items()}
    per_frame = {"shank": np.stack([bone[(s, "knee", "ankle")] for s in sides], 1),
                 "thigh": np.stack([bone[(s, "hip", "knee")] for s in sides], 1),
                 "trunk": trunk[:, None], "head": head[:, None]}
    sampling = _sampling_rel_std(per_frame, height, 1.0 - unmeasured, min_frames)
    return StatureEstimate(height=height, segments=segments, top=top_name,
                           unmeasured_fraction=unmeasured, frames=frames,
                           side_rel_diff=float(side) if np.isfinite(side) else 0.0,
                           bone_ratios=ratios,
                           bones_rel_spread=bones_rel_spread(ratios,
                                                             keypoint_offset=keypoint_offset),
                           sampling_rel_std=sampling, keypoint_offset=float(keypoint_offset))


def _sampling_rel_std(per_frame: dict[str, np.ndarray], height: float, measured: float,
                      min_frames: int) -> float:
    """The stature's relative standard error from its frames, by batch means.

    ``per_frame``: segment -> ``(T, k)`` its lengths a frame (both sides for the legs; NaN
    where not measured); ``height`` the stature of every frame, ``measured`` the part of
    it the segments make (``1 -`` the unmeasured fraction). The ``T`` frames are cut into
    ``B`` blocks of consecutive frames (at most :data:`SAMPLING_BLOCKS`, each of at least
    ``min_frames``); each block's stature is its segments' medians summed over
    ``measured``, and the standard error of the whole is their standard deviation over
    ``sqrt(B)`` (the batch-means estimator of a correlated series' mean: G. S. Fishman,
    *Monte Carlo*, Springer 1996, sec. 6.6). Returns NaN with fewer than three blocks."""
    T = len(next(iter(per_frame.values())))
    blocks = min(SAMPLING_BLOCKS, T // max(min_frames, 1))
    if blocks < 3:
        return float("nan")
    edges = np.linspace(0, T, blocks + 1).astype(int)
    heights = []
    for a, b in zip(edges[:-1], edges[1:]):
        parts = [_median(v[a:b].ravel()) for v in per_frame.values()]
        if min(n for _, n in parts) >= 3:
            heights.append(sum(m for m, _ in parts) / measured)
    if len(heights) < 3:
        return float("nan")
    return float(np.std(heights, ddof=1) / np.sqrt(len(heights)) / height)


def _segment_statures(P: np.ndarray, skeleton: Skeleton, trunk: np.ndarray, min_frames: int
                      ) -> dict[str, float]:
    """Segment kind -> the height it gives: the median over frames (and sides) of its
    length over Winter's fraction (``P`` ``(T, J, 3)`` with NaN where not valid, ``trunk``
    ``(T,)`` mid-hip to mid-shoulder), the joints' unit. The limbs (``leg``: hip, knee,
    ankle; ``arm``: shoulder, elbow, wrist) are measured whole, the widths from the
    skeleton's width bones; kinds with fewer than ``min_frames`` lengths left out."""
    def joint(name: str) -> np.ndarray:
        return P[:, skeleton.index(name)]

    per_kind: dict[str, list[np.ndarray]] = {}
    for kind, parts in _WHOLE_LIMBS.items():
        f = sum(HEIGHT_FRACTION[b] for b, _, _ in parts)
        for side in ("left", "right"):
            if all(f"{side}_{j}" in skeleton.joints for _, a, b in parts for j in (a, b)):
                length = sum(np.linalg.norm(joint(f"{side}_{a}") - joint(f"{side}_{b}"), axis=-1)
                             for _, a, b in parts)
                per_kind.setdefault(kind, []).append(length / f)
    for name, (a, b) in skeleton.bones.items():
        kind = bone_kind(name)
        if kind in _WIDTH_KIND:
            length = np.linalg.norm(joint(a) - joint(b), axis=-1)
            per_kind.setdefault(_WIDTH_KIND[kind], []).append(length / HEIGHT_FRACTION[kind])
    per_kind["trunk"] = [trunk / (LANDMARK_HEIGHT["shoulder"] - LANDMARK_HEIGHT["hip"])]
    out = {}
    for kind, parts in per_kind.items():
        value, n = _median(np.concatenate(parts))
        if n >= min_frames and value > 0:
            out[kind] = value
    return out


def _median_abs_quantile(n: int, alpha: float) -> float:
    """The ``1 - alpha`` point of ``median |z| / Phi^-1(0.75)`` over ``n`` independent
    standard normal ``z`` (``~1`` on average; the median the ``k = n // 2 + 1``-th smallest,
    the upper of the two middle ones for even ``n``).

    ``|z| <= x`` with probability ``p = 2 Phi(x) - 1``; the ``k``-th smallest of ``n``
    uniforms is ``Beta(k, n - k + 1)`` (David and Nagaraja, *Order Statistics*, 2003,
    sec. 2.1), so the point is ``Phi^-1((1 + B^-1(1 - alpha)) / 2)`` with ``B^-1`` that
    Beta's quantile (:func:`scipy.special.betaincinv`)."""
    from scipy.special import betaincinv, ndtri     # at first use: not on every start-up

    k = n // 2 + 1
    p = float(betaincinv(k, n - k + 1, 1.0 - alpha))
    return float(ndtri(0.5 * (1.0 + p))) / _MAD_NORMAL


def bones_rel_spread(bone_ratios: dict[str, float], alpha: float = BONES_ALPHA, *,
                     keypoint_offset: float = KEYPOINT_OFFSET) -> float:
    """The body's segments' disagreement about the height beyond what adults and keypoints
    give: the stature measurement's spread where the reconstruction distorts the body.

    Each segment kind gives a height, its length over Winter's fraction
    (:attr:`StatureEstimate.bone_ratios` ``r_k``, over the chain's); the log ratio
    ``ln r_k`` has std ``c_k`` over adults measured by keypoints (:data:`SEGMENT_REL_STD`:
    the population's proportions and the keypoints' placement against the anatomical
    landmarks, 6-19 %). An arm or a width ``WILD_RATIO`` or more off (a limb the
    reconstruction failed, which the chain does not use) is left out; the chain's own
    kinds (leg, trunk) always count. Normalised, ``z_k = ln r_k / c_k``, their robust
    scale ``s = median |z_k| / Phi^-1(0.75)`` (the upper of the two middle values for an
    even count) is ``~1`` for a body measured right. Where ``s`` exceeds its ``1 - alpha``
    point for that many kinds (a one-sided test: the binomial tail of the median's order
    statistic), the reconstruction stretches segments against each other beyond any
    adult body, and the same reconstruction holds the chain and the mirror's geometry:
    the distortion's own relative spread ``e``, the one that brings the robust scale of
    ``ln r_k / sqrt(c_k^2 + e^2)`` back to 1 (each kind distorted by ``e`` on top of its
    population spread), is the measurement's relative std. A bias that lengthens both
    legs alike (invisible to :attr:`StatureEstimate.side_rel_diff`) shows here against
    the arms, the widths and the trunk.

    Args:
        bone_ratios: segment kind -> height it gives over the chain's (dimensionless).
        alpha: the test's false-alarm probability on a body measured right.
        keypoint_offset: the keypoints' placement off their landmarks in ``c_k``, a
            fraction of the height (:func:`segment_rel_std`).

    Returns:
        The relative std (dimensionless), ``0`` within the spread of adults and keypoints
        or with fewer than three kinds left.
    """
    wild = math.log(WILD_RATIO)
    spread = (SEGMENT_REL_STD if keypoint_offset == KEYPOINT_OFFSET
              else segment_rel_std(keypoint_offset))
    kinds = [k for k, r in bone_ratios.items() if k in spread and r > 0
             and (k in _CHAIN_KINDS or abs(math.log(r)) < wild)]
    if len(kinds) < 3:
        return 0.0
    cv = np.array([spread[k] for k in kinds])
    r = np.abs(np.log([bone_ratios[k] for k in kinds]))

    def scale(extra: float) -> float:                    # the (high) median of |z|, normalised
        return float(np.sort(r / np.hypot(cv, extra))[len(r) // 2]) / _MAD_NORMAL

    if scale(0.0) <= _median_abs_quantile(len(kinds), alpha):
        return 0.0
    # the root of scale(extra) = 1 in [0, 10] (scale decreases): its end where none is inside
    if scale(0.0) <= 1.0 or scale(10.0) > 1.0:
        return 0.0 if scale(0.0) <= 1.0 else 10.0
    from scipy.optimize import brentq

    return float(brentq(lambda e: scale(e) - 1.0, 0.0, 10.0, xtol=1e-14))


def keypoint_rel_std(top: str = "eyes", keypoint_offset: float = KEYPOINT_OFFSET) -> float:
    """The stature's relative std from where a detector places the chain's two end
    keypoints against Winter's landmarks.

    The chain's segments are stacked (shank, thigh, trunk, head along the trunk), so a
    keypoint inside it (knee, hip, shoulder) moved along the body lengthens one segment by
    what it shortens the next: to first order only the ankle and the top (eyes or head top)
    move the sum. Each lies :data:`~mirrorgraph.anthropometry.KEYPOINT_OFFSET` ``o`` (a
    fraction of the height) off its landmark, independently (L. Needham et al., *Sci.
    Rep.* 11, 20673, 2021: video-based joint centres a few centimetres off the
    marker-based ones, systematically, per detector), and the sum is ``1 - u`` of the
    height (``u`` the unmeasured fraction): ``sqrt(2) o / (1 - u)``, 2.7 % with the eyes
    as top, 2.5 % with the head top. A detector's bias, so a longer video does not average
    it out. On the Pose2Sim demo trial (4 Qualisys cameras) OpenPose's and BlazePose's
    keypoints give statures 4.5 % apart, a detector's std of 3.2 % from that one pair
    (``|a - b| / sqrt(2)``; ``bench/RESULTS_stature_real.md``).

    Keypoints placed on the landmarks themselves (2D projections of motion-capture
    markers, synthetic keypoints: ``keypoint_offset`` 0) make it 0.

    Args:
        top: ``"eyes"`` or ``"head_top"`` (:attr:`StatureEstimate.top`).
        keypoint_offset: ``o``, a fraction of the height (the literature's
            :data:`~mirrorgraph.anthropometry.KEYPOINT_OFFSET` by default;
            :func:`keypoint_offset_fraction` from a user's metres).

    Returns:
        The relative std (dimensionless).
    """
    above = (1.0 - LANDMARK_HEIGHT["vertex"] if top == "head_top"
             else LANDMARK_HEIGHT["vertex"] - LANDMARK_HEIGHT["eye"])
    return math.sqrt(2.0) * float(keypoint_offset) / (1.0 - LANDMARK_HEIGHT["ankle"] - above)


def unmeasured_rel_std(top: str = "eyes") -> float:
    """The stature's relative std from the subject's own proportions of the parts no
    keypoint spans: the ankle above the floor and, with the eyes as top, the vertex above
    them, taken at Winter's landmark heights (:data:`~mirrorgraph.anthropometry.
    LANDMARK_HEIGHT`). With ``u`` the unmeasured fraction, ``H = S / (1 - u)`` errs by
    ``du / (1 - u)``, ``du`` the subject's departure from it: each part's spread among
    adults (:data:`~mirrorgraph.anthropometry.UNMEASURED_STD`, ANSUR II), independent,
    over ``1 - u``: 0.58 % with the eyes, 0.42 % with the head top (dimensionless). A
    prior, like :func:`keypoint_rel_std`: no video shows it."""
    parts = [UNMEASURED_STD["ankle"]] + ([] if top == "head_top" else [UNMEASURED_STD["head"]])
    above = (1.0 - LANDMARK_HEIGHT["vertex"] if top == "head_top"
             else LANDMARK_HEIGHT["vertex"] - LANDMARK_HEIGHT["eye"])
    return math.hypot(*parts) / (1.0 - LANDMARK_HEIGHT["ankle"] - above)


def _limbs_parts(keypoint_offset: float = KEYPOINT_OFFSET) -> tuple[float, float]:
    """``(proportions, keypoints)``: the relative stds of the limb-proportion scale
    (:func:`limbs_rel_std`)."""
    groups = {}                                            # kind -> (fraction, anatomical cv)
    for kind, parts in _WHOLE_LIMBS.items():               # both sides: twice the limb
        f = sum(HEIGHT_FRACTION[b] for b, _, _ in parts)
        cv = sum(HEIGHT_FRACTION[b] * HEIGHT_FRACTION_CV[b] for b, _, _ in parts) / f
        groups[kind] = (2.0 * f, cv)
    for kind in ("shoulder_width", "hip_width"):
        groups[kind] = (HEIGHT_FRACTION[kind], HEIGHT_FRACTION_CV[kind])
    total = sum(f for f, _ in groups.values())
    proportions = math.sqrt(sum((f * cv) ** 2 for f, cv in groups.values())) / total
    # each limb's two ends, both sides moved alike (2 o each); each width's two sides (2 o)
    ends = 2 * len(_WHOLE_LIMBS) + 2
    keypoints = 2.0 * float(keypoint_offset) * math.sqrt(ends) / total
    return proportions, keypoints


def limbs_rel_std(keypoint_offset: float = KEYPOINT_OFFSET) -> float:
    """The relative std of the limb-proportion scale (``RefineOptions.scale_from =
    "limbs"``: the gauge's limb bones and widths at Winter's fractions of the height)
    beyond the height's prior: the subject's proportions and the detector's keypoints,
    in quadrature, the terms :func:`keypoint_rel_std` and :data:`SEGMENT_REL_STD` take
    for the stature's chain and its segments.

    - Proportions: the legs, arms, shoulder width and hip width, each at its fraction of
      the height (both sides: twice a limb's) with its anatomical spread among adults
      (:data:`~mirrorgraph.anthropometry.HEIGHT_FRACTION_CV`, a limb's the
      length-weighted mean of its bones', as in :data:`SEGMENT_REL_STD`), the four
      independent: 1.9 %.
    - Keypoints: every limb end (hips, ankles, shoulders, wrists) and every width's side
      placed :data:`~mirrorgraph.anthropometry.KEYPOINT_OFFSET` ``o`` off its landmark,
      the left and right ends moved alike (a detector's convention is symmetric) so that
      each moves the sum by ``2 o``, the knees and elbows inside a limb cancelling: six
      independent offsets, ``2 sqrt(6) o`` over the fractions' sum (2.10), 4.0 %.

    Together 4.4 % (dimensionless), against the chain's 2.7 % (:func:`keypoint_rel_std`,
    the proportions of the 10 % of the height outside it under the height's prior): the
    limbs are the scale for a subject who is not upright, not the more precise one.
    ``keypoint_offset`` (a fraction of the height) replaces ``o``: 0 leaves the
    proportions' 1.9 %.
    """
    return math.hypot(*_limbs_parts(keypoint_offset))


def measurement_rel_std(stature: StatureEstimate | dict | None,
                        scale_from: str | None = None,
                        keypoint_offset: float | None = None) -> float:
    """The metric scale's measured relative std: its share beyond the height's prior
    (``RefineOptions.height_sigma``), for a single mirror, a rig and the live scale alike,
    whichever made the scale (``scale_from``: the stature's chain, or the limbs).

    The detector's placement of the scale's keypoints and the proportions they stand for
    (a prior: no video shows them; the chain's end keypoints, :func:`keypoint_rel_std`,
    with the subject's proportions of the unmeasured parts, :func:`unmeasured_rel_std`,
    or the limbs', :func:`limbs_rel_std`) and two views of a distorted reconstruction,
    measured on the result's stature, added in quadrature:

    - the two legs apart (:attr:`StatureEstimate.side_rel_diff`): each leg measured with
      a relative error of std ``s``, ``(L - R) / (L + R)`` has std ``s / sqrt(2)``, as has
      the legs' mean, so one draw of the first stands for the second;
    - the body's segments' (limbs, trunk, widths) disagreement about the height beyond
      what adults and keypoints give (:attr:`StatureEstimate.bones_rel_spread`,
      :func:`bones_rel_spread`): seen where a bias lengthens both legs alike, against the
      arms, the widths and the trunk.

    A detector's per-joint bias makes the 3D joints (depth along the rays) and the stature
    measured on them wrong: on the realistic synthetic detector (per-label bias 2-4 px,
    epipolar outliers) one 1800-frame scene's legs come out 18 % long, its arms 14 % and
    trunk 20 % short, the distance 23.5 % off: the height's 2 % and the legs' 1.7 % apart
    give 2.6 %, the segments' term 21.1 % (``bench/RESULTS_scale_spread.md`` measures the
    distance's error/std with and without this term over realistic, iid and Pose2Sim
    scenes). A distortion within the spread of adults and
    keypoints (up to ~10 % of the stature) is not seen by the last two: a 3600-frame
    scene's distance is 6.1 % off, at 2.0 % without the end keypoints' term and 3.4 %
    with it.

    Args:
        stature: the estimate, or its :meth:`StatureEstimate.to_dict` record (as a
            calibration's ``refinement["stature"]`` holds it), or ``None`` (not measured).
        scale_from: ``"stature"`` or ``"limbs"`` (``RefineOptions.scale_from``); ``None``:
            the estimate's own (:attr:`StatureEstimate.scale_from`), else ``"stature"``.
        keypoint_offset: the keypoints' placement, a fraction of the height
            (:func:`keypoint_offset_fraction`); ``None``: the estimate's own
            (:attr:`StatureEstimate.keypoint_offset`; a record without one, or no
            estimate: :data:`~mirrorgraph.anthropometry.KEYPOINT_OFFSET`).

    Returns:
        The relative std (dimensionless); for ``None`` ``0`` with the stature (no scale
        measured), :func:`limbs_rel_std` with the limbs.
    """
    if isinstance(stature, dict):
        side = stature.get("side_rel_diff") or 0.0
        bones = stature.get("bones_rel_spread") or 0.0
        top = stature.get("top") or "eyes"
        own = stature.get("scale_from")
        offset = stature.get("keypoint_offset")
    elif stature is not None:
        side, bones, top = stature.side_rel_diff, stature.bones_rel_spread, stature.top
        own, offset = stature.scale_from, stature.keypoint_offset
    else:
        side = bones = 0.0
        top, own, offset = "eyes", None, None
    o = next((v for v in (keypoint_offset, offset) if v is not None), KEYPOINT_OFFSET)
    scale_from = scale_from or own or "stature"
    if scale_from == "limbs":
        prior = limbs_rel_std(o)
    elif stature is None:
        return 0.0
    else:
        prior = math.hypot(keypoint_rel_std(top, o), unmeasured_rel_std(top))
    return float(np.sqrt(float(side) ** 2 + float(bones) ** 2 + prior ** 2))


_LIMBS = "limb proportions (sum of the limb bones at Winter's fractions of the height)"
#: The scale's description when the stature cannot be measured.
LIMB_PROPORTIONS = _LIMBS + ": the joints do not span ankle to eyes in enough frames"
#: ... and when the user chose the limbs (``RefineOptions.scale_from = "limbs"``).
LIMB_CHOSEN = _LIMBS + ", as asked (scale_from = limbs)"


def stature_rescale(points: np.ndarray, valid: np.ndarray, skeleton: Skeleton, height: float,
                    keypoint_offset: float = KEYPOINT_OFFSET
                    ) -> tuple[float | None, str, StatureEstimate | None]:
    """The factor that makes the stature measured on a solution's joints ``height``: the
    metric scale of every front end (one mirror, :mod:`mirrorgraph.pipelines.scale`;
    a rig, :func:`mirrorgraph.pipelines.rig.calibrate_rig`).

    The graph's gauge holds the limb bones' sum at Winter's fractions of the height, which
    carries the subject's limb proportions into the scale; the stature measured on the
    solved joints (:func:`estimate_stature`) depends on population proportions only for
    the few percent of the height below the ankles and above the eyes.

    Args:
        points: ``(T, J, 3)`` the solution's joints (any length unit).
        valid: ``(T, J)`` bool, where ``points`` hold a joint.
        skeleton: their layout.
        height: the subject's height in the unit wanted (metres).
        keypoint_offset: the keypoints' placement off their landmarks, a fraction of the
            height (:func:`keypoint_offset_fraction`), which the estimate's std holds.

    Returns:
        ``(factor, source, stature)``: the factor to multiply every length by, a description
        of the scale's source, and the stature estimate after scaling; ``(None,
        LIMB_PROPORTIONS, None)`` where the joints do not span ankle to eyes (the gauge's
        limb-proportion scale stays).
    """
    est = estimate_stature(points, valid, skeleton, keypoint_offset=keypoint_offset)
    if est is None:
        return None, LIMB_PROPORTIONS, None
    factor = float(height) / est.height
    scaled = est.scaled(factor)
    return factor, scaled.describe(), scaled


def with_height_sigma(std: float, length: float, rel_sigma: float) -> float:
    """A length's std with the metric scale's own uncertainty added: the subject's height
    and proportions, a pure scale error of ``rel_sigma`` (relative,
    ``RefineOptions.height_sigma``) on ``length``, independent of the data's ``std``:
    ``sqrt(std^2 + (rel_sigma * |length|)^2)``, in the unit of ``length``."""
    return float(np.hypot(std, rel_sigma * abs(float(length))))

