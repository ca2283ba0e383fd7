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

Winter's widths are the body's breadths (biacromial, hip); a keypoint detector gives joint
centres, inside them: on the Pose2Sim demo's subject (1.60 m, four Qualisys cameras,
``bench/RESULTS_focal_real.md``) the hip width is 0.133 H with OpenPose BODY_25B and
0.118 H with BlazePose against 0.191 H, the shoulder width 0.21-0.22 H against 0.259 H,
and BODY_25B's neck (the *upper* neck) lies 0.113 H from each shoulder against the half
shoulder width of 0.1295 H. An estimated focal length uses none of these fractions (the
graph leaves the anthropometric ratios out there, ``FocalOptions.anthropometry``;
swapping them for the detector's own moved it within its noise on that bench).

The same figure gives the heights of landmarks above the floor, standing upright
(:data:`LANDMARK_HEIGHT`): the stature estimate of :mod:`mirrorgraph.stature`
uses the parts of the body below the ankle and above the eyes, which no
keypoint of BODY_25 or COCO spans.
"""

from __future__ import annotations

import math

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

#: How much a segment's length over stature varies among adults: the relative std (the
#: coefficient of variation) of a stature estimated from that one segment at its
#: :data:`HEIGHT_FRACTION` (``length / fraction``), by segment kind (``trunk``: hip to
#: shoulder height, :data:`LANDMARK_HEIGHT` ``shoulder - hip``), anatomical landmarks.
#:
#: The long bones from M. Trotter and G. C. Gleser, "Estimation of stature from long bones
#: of American Whites and Negroes", *Am. J. Phys. Anthropol.* 10, 1952 (white males: stature
#: ``H = b L + a`` +- SEE, cm: femur 2.38, 61.41, 3.27; tibia 2.52, 78.62, 3.37; humerus
#: 3.08, 70.45, 4.05; ulna 3.70, 74.05, 4.32). A proportional estimate ``L / f`` (no
#: intercept, ``f`` the mean ratio) errs by the regression's residual and by its own
#: misfit of the line, ``(H / L - b) (L - mean L)``; with a stature mean of 174 cm and
#: std of 6.7 cm (``std L = sqrt(std H^2 - SEE^2) / b``) that is
#: ``sqrt(SEE^2 + ((H / L - b) std L)^2) / H``: femur 2.6 %, tibia 3.4 %, humerus 3.1 %,
#: ulna 3.3 %. Breadths (shoulders, hips) correlate weakly with stature in adult surveys,
#: so their ratio to it spreads about as much as the breadth itself, 5-6 % (biacromial
#: and hip breadth: C. C. Gordon et al., *2012 Anthropometric Survey of U.S. Army
#: Personnel* (ANSUR II), NATICK/TR-15/007, 2014). The trunk's height (hip joints to
#: shoulders) has no such survey figure at hand: 4 %, between the long bones' and the
#: breadths'. Dimensionless.
HEIGHT_FRACTION_CV: dict[str, float] = {
    "femur": 0.026,
    "tibia": 0.034,
    "humerus": 0.031,
    "ulna": 0.033,
    "shoulder_width": 0.05,
    "hip_width": 0.06,
    "trunk": 0.04,
}

#: Where a keypoint detector places a joint against the anatomical landmark Winter's
#: fractions are measured between, as a fraction of the height: 3 cm for a 1.75 m adult.
#: Video-based 3D joint centres (OpenPose and others, triangulated from many cameras) lie
#: a few centimetres from the marker-based ones, systematically, the hips the most (L.
#: Needham et al., "The accuracy of several pose estimation methods for 3D joint centre
#: localisation", *Sci. Rep.* 11, 20673, 2021). A segment between two such joints is
#: ``sqrt(2)`` times that off its anatomical length (independent ends), a width twice
#: (both sides moved alike by a symmetric convention); the joint inside a limb (knee,
#: elbow) cancels in the limb's length.
KEYPOINT_OFFSET = 0.017

#: How much the parts of the stature that no keypoint spans vary among adults, as a
#: fraction of the stature (dimensionless): ``ankle``, the lateral malleolus above the
#: floor, and ``head``, the vertex above the eyes. Their coefficients of variation over the
#: 6,068 men of ANSUR II (C. C. Gordon et al., *2012 Anthropometric Survey of U.S. Army
#: Personnel*, NATICK/TR-15/007, 2014; its public data: lateral malleolus height
#: 69.6 +- 7.3 mm, tragion to top of head 129.6 +- 6.7 mm, the nearest measured span to
#: eyes-to-vertex), 10.4 % and 5.1 %, at Winter's fractions (:data:`LANDMARK_HEIGHT`:
#: 0.039 and 0.064): 0.41 % and 0.33 %. The whole spread is taken (what correlates with
#: stature is not taken out): an upper bound.
UNMEASURED_STD: dict[str, float] = {
    "ankle": 0.039 * 7.27 / 69.58,
    "head": 0.064 * 6.66 / 129.62,
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


def height_from_bone_lengths(lengths: dict[str, float], skeleton: Skeleton) -> float:
    """The standing height the bones' lengths make, in their unit: their sum over the sum
    of their Winter fractions (:func:`height_fractions`); NaN without a known bone."""
    frac = height_fractions(skeleton)
    known = [(float(v), frac[k]) for k, v in lengths.items() if k in frac and math.isfinite(v)]
    if not known:
        return float("nan")
    return float(sum(v for v, _ in known) / sum(f for _, f in known))


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
