"""Average human segment lengths as fractions of standing height.

Source: D. A. Winter, *Biomechanics and Motor Control of Human Movement*, 4th ed.,
Wiley 2009, Figure 4.1 ("Body segment lengths expressed as a fraction of body
height H"), after Drillis and Contini (1966). The figures are population averages
for adults; an individual differs by a few percent per segment, which is why the
anthropometric prior of the graph is soft (see ``mirrorgraph.factors.anthropometry``).

Mapping onto the bones of :mod:`mirrorgraph.skeletons`:

==================  =====================================  ==========
bone                Winter's segment                        fraction H
==================  =====================================  ==========
femur               hip (0.530 H) to knee (0.285 H)         0.245
tibia               knee (0.285 H) to ankle (0.039 H)       0.246
humerus             upper arm, shoulder to elbow            0.186
ulna                forearm, elbow to wrist                 0.146
shoulder_width      biacromial width                        0.259
scapular            half the shoulder width (neck to side)  0.1295
hip_width           hip width                               0.191
pelvis              half the hip width (mid-hip to side)    0.0955
==================  =====================================  ==========

The same figure gives the heights of landmarks above the floor, standing upright
(:data:`LANDMARK_HEIGHT`): the stature estimate of :mod:`mirrorgraph.stature`
uses the parts of the body below the ankle and above the eyes, which no
keypoint of BODY_25 or COCO spans.
"""

from __future__ import annotations

from .skeletons import Skeleton, person_of

#: Segment length / standing height, by segment kind (Winter 2009, Fig. 4.1).
HEIGHT_FRACTION: dict[str, float] = {
    "femur": 0.245,
    "tibia": 0.246,
    "humerus": 0.186,
    "ulna": 0.146,
    "shoulder_width": 0.259,
    "scapular": 0.259 / 2,
    "hip_width": 0.191,
    "pelvis": 0.191 / 2,
}

#: Height of a landmark above the floor / standing height, standing upright
#: (Winter 2009, Fig. 4.1).
LANDMARK_HEIGHT: dict[str, float] = {
    "ankle": 0.039,
    "knee": 0.285,
    "hip": 0.530,
    "shoulder": 0.818,
    "chin": 0.870,
    "eye": 0.936,
    "vertex": 1.000,
}


def bone_kind(bone_name: str) -> str:
    """Segment kind of a bone name: ``"left_femur"`` -> ``"femur"`` (a person's tag of
    :func:`~mirrorgraph.skeletons.people_skeleton` left out: ``"left_femur@1"`` too)."""
    bone_name = bone_name[:len(bone_name) - len(person_of(bone_name))]
    for prefix in ("left_", "right_"):
        if bone_name.startswith(prefix):
            return bone_name[len(prefix):]
    return bone_name


def height_fractions(skeleton: Skeleton) -> dict[str, float]:
    """Expected length / height for each bone of ``skeleton`` (dimensionless)."""
    return {b: HEIGHT_FRACTION[bone_kind(b)] for b in skeleton.bones}


def femur_ratios(skeleton: Skeleton) -> dict[str, float]:
    """Expected length / femur length for each bone (the paper's sigma_k)."""
    return {b: f / HEIGHT_FRACTION["femur"] for b, f in height_fractions(skeleton).items()}


def expected_bone_lengths(skeleton: Skeleton, height_m: float) -> dict[str, float]:
    """Expected bone lengths in metres for a subject of standing height ``height_m``."""
    return {b: f * height_m for b, f in height_fractions(skeleton).items()}


#: Standing heights accepted by ``--subject-height``, metres (as the pipeline checks).
HUMAN_HEIGHT_M = (0.5, 2.8)


def height_problem(value: float) -> str | None:
    """Why ``value`` is not a subject height in metres (with the likely unit it was given
    in), or ``None`` when it is one.

    Example:
        >>> height_problem(175)
        '175 m is not a human height (0.5 to 2.8 m): did you mean 1.75 m (centimetres given)?'
    """
    lo, hi = HUMAN_HEIGHT_M
    if lo < value < hi:
        return None
    text = f"{value:g} m is not a human height ({lo:g} to {hi:g} m)"
    for factor, unit in ((100.0, "centimetres"), (1000.0, "millimetres")):
        if lo < value / factor < hi:
            return text + f": did you mean {value / factor:g} m ({unit} given)?"
    return text
