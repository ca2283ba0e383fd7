"""Is the "reflection" a reflection? The check for a second person mistaken for it.

Before the refinement, every frame holding two detections or more is scored by how
well its best candidate pair fits the initial mirror's epipolar geometry
(:func:`mirrorgraph.initial.pair_scores.frame_scores`). A true reflection pairs in nearly every
frame; a second person standing still pairs by chance in some and lies in a *grey
zone* (fitting neither as a reflection nor as an unrelated pair) in many. The verdict
(:func:`check_reflection`): ``ok``, ``doubtful`` (a warning) or ``second_person``
(refused), from the fractions of frames that pair and that lie in the grey zone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ReflectionCheck", "check_reflection"]

#: Frames a verdict on the reflection needs (frames holding a candidate pair).
CHECK_MIN_FRAMES = 30
#: Warn when fewer of the frames holding two detections or more pair up (their best
#: candidate's median epipolar distance under the threshold) ...
DOUBT_PAIRED_FRACTION = 0.80
#: ... or when more of them fall in the grey zone: fitting neither as a reflection nor
#: as an unrelated pair. The grey zone is read on a lower quantile of each frame's
#: epipolar distances, :data:`GREY_QUANTILE` (the median lets a detector's gross errors
#: on a few joints in: real reflections with 20 % outliers a view fall in it in 39 of
#: 40 scenes with the median, 0 of 40 with the 0.3 quantile); its bounds are
#: :data:`GREY_LOW` times that score's median over the frames that pair, and
#: :data:`GREY_HIGH` times the threshold.
DOUBT_GREY_FRACTION = 0.08
GREY_QUANTILE = 0.3
GREY_LOW = 2.5
GREY_HIGH = 3.0
#: Refuse when both hold: the "reflection" pairs in fewer than this fraction of the
#: frames ...
REFUSE_PAIRED_FRACTION = 0.25
#: ... and more than this fraction lie in the grey zone.
REFUSE_GREY_FRACTION = 0.15


@dataclass(frozen=True)
class ReflectionCheck:
    """Is the detection paired with the person their reflection? (:func:`check_reflection`)

    Attributes:
        frames: frames holding a candidate pair (two detections or more).
        paired_fraction: of those, the fraction whose best pair fits the mirror (median
            epipolar distance under the threshold).
        grey_fraction: the fraction in the grey zone (see :func:`check_reflection`).
        median_px: median score of the frames that pair, pixels (NaN if none).
        verdict: ``"ok"``, ``"doubtful"`` (a warning), ``"second_person"`` (refused) or
            ``"too_few_frames"`` (no verdict).
    """

    frames: int
    paired_fraction: float
    grey_fraction: float
    median_px: float
    verdict: str

    def describe(self) -> str:
        """One line for the warnings or the error."""
        what = (f"the detection paired as the reflection fits one mirror in "
                f"{100 * self.paired_fraction:.0f}% of the {self.frames} frames holding two "
                f"people and fits badly in {100 * self.grey_fraction:.0f}% (a reflection "
                "fits in nearly all, at the detector's noise)")
        if self.verdict == "second_person":
            return what + ": it is a second person, not the reflection"
        return (what + ": the 'reflection' may be a second person, or the detector poor "
                "(gross errors on many joints, noise beyond --threshold), or the reflection "
                "often missing while somebody else is seen")

    @classmethod
    def from_dict(cls, record: dict) -> "ReflectionCheck":
        """The check of its :meth:`to_dict` record (``None`` figures read as NaN)."""
        num = {k: float("nan") if record.get(k) is None else float(record[k])
               for k in ("paired_fraction", "grey_fraction", "median_px")}
        return cls(frames=int(record.get("frames") or 0), verdict=record["verdict"], **num)

    def to_dict(self) -> dict:
        """The record in ``calibration.json`` (``input.reflection_check``)."""
        def num(v: float) -> float | None:
            return float(v) if np.isfinite(v) else None
        return {"frames": self.frames, "paired_fraction": num(self.paired_fraction),
                "grey_fraction": num(self.grey_fraction), "median_px": num(self.median_px),
                "verdict": self.verdict}


def check_reflection(scores: np.ndarray, threshold_px: float,
                     grey_scores: np.ndarray | None = None) -> ReflectionCheck:
    """Tell a reflection from a second person by how the frames fit the mirror.

    ``scores`` is, per frame, the best candidate pair's median epipolar distance to the
    estimated mirror (:func:`mirrorgraph.initial.pair_scores.frame_scores`); ``grey_scores`` the
    same with the :data:`GREY_QUANTILE` quantile over joints instead of the median. A
    true reflection fits in nearly every frame holding it, at the detector's noise: the
    scores gather around one value (about 3 px for 4 px noise), and the frames that do
    not pair are frames without the reflection (the person and a bystander), scored by
    two unrelated poses, mostly far off. A second person taken for the reflection fits
    only by chance: in the frames where both stand in alike poses; elsewhere their
    poses differ by a little or a lot, and the scores spread from the noise to tens of
    pixels. Two fractions of the frames holding a candidate pair tell them apart:

    * ``paired``: ``scores`` under ``threshold_px``;
    * ``grey``: ``grey_scores`` above :data:`GREY_LOW` times their median over the
      paired frames and under :data:`GREY_HIGH` times ``threshold_px``: too far for
      noise, too close for most unrelated pairs.

    Verdicts: refused (``second_person``) when ``paired < REFUSE_PAIRED_FRACTION`` and
    ``grey > REFUSE_GREY_FRACTION``; doubtful (a warning) when
    ``paired < DOUBT_PAIRED_FRACTION`` or ``grey > DOUBT_GREY_FRACTION``; no verdict on
    fewer than :data:`CHECK_MIN_FRAMES` frames. Both fractions are ratios, free of the
    detector's noise level as long as the noise stays under the threshold.

    Measured over 40 synthetic scenes a case (``tests/initial/test_reflection_check.py``
    builds them; the tables in ``docs/internals.md``): no false alarm on real
    reflections up to 20 % outliers a view, and 30-40 of 40 second persons caught at
    300 frames. Not caught: a second person whose pose and place match the
    reflection's in nearly every frame, which no epipolar test tells from a reflection.

    Args:
        scores: ``(T,)`` px; NaN for frames without a candidate pair, inf for pairs
            sharing too few joints.
        threshold_px: the pairing's threshold, pixels.
        grey_scores: ``(T,)`` px, the same frames scored by a lower quantile (default:
            ``scores``).

    Returns:
        :class:`ReflectionCheck`.
    """
    s = np.asarray(scores, dtype=float)
    g = s if grey_scores is None else np.asarray(grey_scores, dtype=float)
    has = ~np.isnan(s)
    s, g = s[has], g[has]
    n = int(s.size)
    if n == 0:
        return ReflectionCheck(0, float("nan"), float("nan"), float("nan"), "too_few_frames")
    ok = s < threshold_px
    paired = float(np.mean(ok))
    median = float(np.median(s[ok])) if ok.any() else float("nan")
    low = GREY_LOW * (float(np.median(g[ok])) if ok.any() else float(threshold_px))
    grey = float(np.mean((g > low) & (g < GREY_HIGH * threshold_px)))
    if n < CHECK_MIN_FRAMES:
        verdict = "too_few_frames"
    elif paired < REFUSE_PAIRED_FRACTION and grey > REFUSE_GREY_FRACTION:
        verdict = "second_person"
    elif paired < DOUBT_PAIRED_FRACTION or grey > DOUBT_GREY_FRACTION:
        verdict = "doubtful"
    else:
        verdict = "ok"
    return ReflectionCheck(n, paired, grey, median, verdict)
