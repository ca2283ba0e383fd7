"""A 3D body model for synthetic data: segment lengths and rigid joint offsets.

The model is in units of standing height ``H`` (multiply by the subject's height for
metres) in a *body frame*: ``x`` to the person's left, ``y`` up, ``z`` forward (the way
the person faces); right-handed.

Limb and trunk lengths come from :data:`mirrorgraph.anthropometry.HEIGHT_FRACTION`
(Winter 2009, Fig. 4.1): femur, tibia, humerus, ulna, shoulder width and hip width. The
rest (trunk parts, neck, head, face and foot points) are round figures that agree with
Winter's landmark heights (ankle 0.039 H, hip 0.530 H, shoulder 0.818 H, chin 0.870 H,
eye 0.936 H, vertex 1.000 H, foot length 0.152 H, foot width 0.055 H); their table:
``docs/internals.md`` and the constants below.

Individual variation: each segment kind (femur, tibia, humerus, ulna, shoulder width, hip
width, each trunk part, neck, head size, foot size) is scaled by its own factor
``1 + s * z``, ``z`` a standard normal clipped to +-2, ``s = 0.03`` by default, shared by
the left and right segment (the body stays symmetric); then the whole body is scaled so
that the standing height (floor to vertex, legs straight, trunk upright) is exactly ``H``.
With ``variation="population"`` each kind's ``s`` is the adults' spread of its ratio to the
stature where the literature gives one (:data:`POPULATION_VARIATION`).

The OpenPose ``neck`` is the midpoint of the shoulders and ``mid_hip`` that of the hips,
so the scapular and pelvis bones of :mod:`mirrorgraph.skeletons` are half the shoulder
and hip widths. BODY_25B and HALPE_26 get the same ``neck`` and ``mid_hip`` (their
detectors place the neck somewhat higher), and their ``head_top`` is the vertex of the
rigid head (:func:`skeleton_points`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..anthropometry import HEIGHT_FRACTION, HEIGHT_FRACTION_CV, bone_kind
from ..geometry import similarity_align
from ..skeletons import SKELETONS, Skeleton

#: Every joint the model produces (a superset of COCO_17, COCO_18 and BODY_25;
#: BODY_25B and HALPE_26 also need ``head_top``, see :func:`skeleton_points`).
FULL_JOINTS: tuple[str, ...] = (
    "nose", "left_eye", "right_eye", "left_ear", "right_ear", "neck",
    "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
    "left_wrist", "right_wrist", "mid_hip", "left_hip", "right_hip",
    "left_knee", "right_knee", "left_ankle", "right_ankle",
    "left_big_toe", "right_big_toe", "left_small_toe", "right_small_toe",
    "left_heel", "right_heel",
)
FULL_INDEX: dict[str, int] = {n: i for i, n in enumerate(FULL_JOINTS)}

#: Nominal fractions of height not in the anthropometry table (see module doc).
EXTRA_FRACTION: dict[str, float] = {
    "ankle_height": 0.039,
    "lumbar": 0.100,
    "thoracic": 0.100,
    "upper_trunk": 0.088,
    "neck": 0.072,
    "head_top": 0.110,
}

#: Head points relative to the head pivot (left side; right mirrors x), in H.
HEAD_OFFSETS: dict[str, tuple[float, float, float]] = {
    "eye": (0.018, 0.046, 0.048),
    "ear": (0.040, 0.036, 0.000),
    "nose": (0.000, 0.026, 0.062),
}

#: Foot points relative to the ankle for the left foot (x > 0 = lateral), in H.
FOOT_OFFSETS: dict[str, tuple[float, float, float]] = {
    "heel": (0.004, -0.032, -0.028),
    "big_toe": (-0.010, -0.033, 0.118),
    "small_toe": (0.022, -0.033, 0.092),
}

_VARIED = ("femur", "tibia", "humerus", "ulna", "shoulder_width", "hip_width",
           "lumbar", "thoracic", "upper_trunk", "neck", "head", "foot", "ankle_height")

#: The relative std of each varied segment kind among adults (``make_body(variation=
#: "population")``): the long bones' and the breadths' ratio to the stature from
#: :data:`mirrorgraph.anthropometry.HEIGHT_FRACTION_CV` (Trotter and Gleser 1952; ANSUR II),
#: the trunk's parts at its trunk figure; the neck, head, foot and ankle height, which no
#: survey at hand gives as a ratio to the stature, at the default 3 %. Dimensionless.
POPULATION_VARIATION: dict[str, float] = {
    **{k: HEIGHT_FRACTION_CV[k] for k in ("femur", "tibia", "humerus", "ulna",
                                            "shoulder_width", "hip_width")},
    **{k: HEIGHT_FRACTION_CV["trunk"] for k in ("lumbar", "thoracic", "upper_trunk")},
    **{k: 0.03 for k in ("neck", "head", "foot", "ankle_height")},
}


@dataclass(frozen=True)
class BodyModel:
    """Segment lengths and rigid offsets of one individual, in units of height.

    Attributes:
        lengths: segment kind -> length / H (``femur``, ``tibia``, ``humerus``,
            ``ulna``, ``shoulder_width``, ``hip_width``, ``ankle_height``,
            ``lumbar``, ``thoracic``, ``upper_trunk``, ``neck``, ``head_top``).
        head: head point name -> (3,) offset from the head pivot (left side).
        foot: foot point name -> (3,) offset from the ankle (left foot).
        factors: the individual variation factor per segment kind.
    """

    lengths: dict[str, float]
    head: dict[str, np.ndarray]
    foot: dict[str, np.ndarray]
    factors: dict[str, float] = field(default_factory=dict)

    @property
    def stature(self) -> float:
        """Standing height (floor to vertex) / H; 1 up to rounding."""
        L = self.lengths
        return (L["ankle_height"] + L["tibia"] + L["femur"] + L["lumbar"] + L["thoracic"]
                + L["upper_trunk"] + L["neck"] + L["head_top"])

    def bone_lengths(self, skeleton: Skeleton, height: float = 1.0) -> dict[str, float]:
        """Length of every bone of ``skeleton`` for a subject of ``height`` metres."""
        L = self.lengths
        kind = {"femur": L["femur"], "tibia": L["tibia"], "humerus": L["humerus"],
                "ulna": L["ulna"], "shoulder_width": L["shoulder_width"],
                "scapular": L["shoulder_width"] / 2, "hip_width": L["hip_width"],
                "pelvis": L["hip_width"] / 2}
        out = {}
        for b in skeleton.bones:
            out[b] = kind[bone_kind(b)] * height
        return out


def make_body(rng: np.random.Generator | None = None,
              variation: float | str = 0.03) -> BodyModel:
    """An individual body in units of height.

    Args:
        rng: random generator for the individual variation; ``None`` gives the
            nominal (average) body.
        variation: relative standard deviation of each segment kind (default 3 %), or
            ``"population"``: each kind's own (:data:`POPULATION_VARIATION`). The same
            draws from ``rng`` either way.
    """
    if isinstance(variation, str):
        if variation != "population":
            raise ValueError(f"variation must be a number or 'population', got {variation!r}")
        s = [POPULATION_VARIATION[k] for k in _VARIED]
    else:
        s = [float(variation)] * len(_VARIED)
    if rng is None:
        z = np.zeros(len(_VARIED))
    else:
        z = np.clip(rng.standard_normal(len(_VARIED)), -2.0, 2.0)
    f = {k: float(1.0 + sk * zi) for k, sk, zi in zip(_VARIED, s, z)}
    L = {
        "femur": HEIGHT_FRACTION["femur"] * f["femur"],
        "tibia": HEIGHT_FRACTION["tibia"] * f["tibia"],
        "humerus": HEIGHT_FRACTION["humerus"] * f["humerus"],
        "ulna": HEIGHT_FRACTION["ulna"] * f["ulna"],
        "shoulder_width": HEIGHT_FRACTION["shoulder_width"] * f["shoulder_width"],
        "hip_width": HEIGHT_FRACTION["hip_width"] * f["hip_width"],
        "ankle_height": EXTRA_FRACTION["ankle_height"] * f["ankle_height"],
        "lumbar": EXTRA_FRACTION["lumbar"] * f["lumbar"],
        "thoracic": EXTRA_FRACTION["thoracic"] * f["thoracic"],
        "upper_trunk": EXTRA_FRACTION["upper_trunk"] * f["upper_trunk"],
        "neck": EXTRA_FRACTION["neck"] * f["neck"],
        "head_top": EXTRA_FRACTION["head_top"] * f["head"],
    }
    head = {k: np.array(v) * f["head"] for k, v in HEAD_OFFSETS.items()}
    foot = {k: np.array(v) * f["foot"] for k, v in FOOT_OFFSETS.items()}
    # Renormalise so that the standing height is exactly one.
    s = 1.0 / (L["ankle_height"] + L["tibia"] + L["femur"] + L["lumbar"] + L["thoracic"]
               + L["upper_trunk"] + L["neck"] + L["head_top"])
    L = {k: v * s for k, v in L.items()}
    head = {k: v * s for k, v in head.items()}
    foot = {k: v * s for k, v in foot.items()}
    return BodyModel(lengths=L, head=head, foot=foot, factors=f)


def skeleton_columns(skeleton: Skeleton) -> np.ndarray:
    """``(J,)`` indices into :data:`FULL_JOINTS` of the joints of ``skeleton``.

    Raises:
        ValueError: a joint is not a column of the model (``head_top`` of BODY_25B
            and HALPE_26 is derived from the head instead: :func:`skeleton_points`).
    """
    try:
        return np.array([FULL_INDEX[n] for n in skeleton.joints], dtype=int)
    except KeyError as e:
        raise ValueError(f"the synthetic body has no joint {e.args[0]!r}") from None


#: Joints not among :data:`FULL_JOINTS` that :func:`skeleton_points` derives.
DERIVED_JOINTS: tuple[str, ...] = ("head_top",)

#: The layouts of :data:`mirrorgraph.skeletons.SKELETONS` whose every joint the model
#: produces, in that order: every one but BLAZEPOSE (no eye corners, mouth, hands).
#: What ``make_scene(skeleton=...)`` and ``mirrorgraph synth --skeleton`` accept.
SUPPORTED_SKELETONS: tuple[str, ...] = tuple(
    name for name, skel in SKELETONS.items()
    if all(j in FULL_INDEX or j in DERIVED_JOINTS for j in skel.joints))

_HEAD_POINTS = ("left_eye", "right_eye", "left_ear", "right_ear", "nose")


def _head_model() -> np.ndarray:
    """``(5, 3)`` nominal offsets of :data:`_HEAD_POINTS` from the head pivot, in H."""
    rows = []
    for name in _HEAD_POINTS:
        side, _, kind = name.rpartition("_")
        o = np.array(HEAD_OFFSETS[kind], dtype=float)
        rows.append(o * np.array([-1.0, 1.0, 1.0]) if side == "right" else o)
    return np.array(rows)


def head_top(full: np.ndarray) -> np.ndarray:
    """``(..., 3)`` top of the head (vertex) of joints ``(..., 25, 3)`` (:data:`FULL_JOINTS`).

    The eyes, ears and nose are rigid offsets from the head pivot (:data:`HEAD_OFFSETS`,
    the same in :mod:`~mirrorgraph.synth.motion` and :mod:`~mirrorgraph.synth.mocap`,
    scaled by the individual's head size), and the vertex lies ``head_top`` (0.110 H
    nominal, same scale) above the pivot along the head's up axis. A least-squares
    similarity transform (:func:`~mirrorgraph.geometry.similarity_align`) from the nominal
    head points to the five given ones carries the nominal vertex to the answer:
    exact for the model's rigid heads, in the units and frame of ``full``.
    """
    P = np.asarray(full, dtype=float)[..., [FULL_INDEX[n] for n in _HEAD_POINTS], :]
    R, k, t = similarity_align(_head_model(), P)             # nominal -> given
    top = np.array([0.0, EXTRA_FRACTION["head_top"], 0.0])
    return k[..., None] * (R @ top) + t


def check_skeleton(skeleton: Skeleton) -> None:
    """``ValueError`` unless the model produces every joint of ``skeleton``
    (a column of :data:`FULL_JOINTS` or one of :data:`DERIVED_JOINTS`)."""
    for name in skeleton.joints:
        if name not in FULL_INDEX and name not in DERIVED_JOINTS:
            raise ValueError(f"the synthetic body has no joint {name!r}")


def skeleton_points(full: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """``(T, J, 3)`` joints of ``skeleton`` from ``(T, 25, 3)`` ones in :data:`FULL_JOINTS` order.

    Columns of the model are copied; ``head_top`` (BODY_25B, HALPE_26) is
    :func:`head_top`. Same units and frame as ``full``.

    Raises:
        ValueError: ``skeleton`` has a joint the model cannot produce.
    """
    check_skeleton(skeleton)
    full = np.asarray(full, dtype=float)
    out = np.empty(full.shape[:-2] + (skeleton.num_joints, 3))
    for j, name in enumerate(skeleton.joints):
        if name in FULL_INDEX:
            out[..., j, :] = full[..., FULL_INDEX[name], :]
        else:                                           # the one derived joint
            out[..., j, :] = head_top(full)
    return out
