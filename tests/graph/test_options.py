"""Tests of the refinement's options (mirrorgraph.graph.options): the groups by concern
are the one object's fields, each setting in one group, and bad values are refused
by name; the subject height has one home per front end."""

from __future__ import annotations

import dataclasses

import pytest

import mirrorgraph as mg
from mirrorgraph.errors import InputError
from mirrorgraph.graph.options import (FocalOptions, GaugeOptions, PriorOptions,
                                       RefineOptions, ScheduleOptions, SolverOptions)
from mirrorgraph.synth import make_scene

GROUPS = (PriorOptions, ScheduleOptions, SolverOptions, GaugeOptions)


def _names(kind) -> set[str]:
    return {f.name for f in dataclasses.fields(kind)}


def test_every_setting_lives_in_exactly_one_group():
    seen: dict[str, str] = {}
    for g in GROUPS:
        for name in _names(g):
            assert name not in seen, f"{name} in {seen.get(name)} and {g.__name__}"
            seen[name] = g.__name__
    # and the nested group of the cameras whose focal length is estimated
    assert set(seen) | {"focal"} == _names(RefineOptions)
    assert isinstance(RefineOptions().focal, FocalOptions)
    assert {"bone_sigma", "use_hip"} <= _names(PriorOptions)
    assert {"robust_kernel", "min_parallax_deg"} <= _names(ScheduleOptions)
    assert {"max_iterations", "workers"} <= _names(SolverOptions)
    assert {"subject_height", "scale_from", "keypoint_offset"} <= _names(GaugeOptions)


def test_groups_round_trip_and_keep_their_defaults():
    opts = RefineOptions(bone_sigma=0.02, max_iterations=7, scale_from="limbs")
    assert opts.priors.bone_sigma == 0.02 and opts.solver.max_iterations == 7
    assert opts.gauge.scale_from == "limbs"
    opts = RefineOptions(bone_sigma=0.02, max_iterations=7, scale_from="limbs",
                         focal=FocalOptions(principal_point=True))
    again = RefineOptions.from_groups(priors=opts.priors, schedule=opts.schedule,
                                      solver=opts.solver, gauge=opts.gauge, focal=opts.focal)
    assert again == opts
    only = RefineOptions.from_groups(solver=SolverOptions(marginals=False))
    assert only.marginals is False and only.bone_sigma == RefineOptions().bone_sigma
    with pytest.raises(TypeError):
        RefineOptions(4.0)                        # keyword arguments only


@pytest.mark.parametrize("bad, field", [
    (dict(subject_height=-1.7), "subject_height"),
    (dict(subject_height=float("inf")), "subject_height"),
    (dict(robust_kernel="gemanmcclure"), "robust_kernel"),
    (dict(final_kernel="cauchyy"), "final_kernel"),
    (dict(scale_from="bones"), "scale_from"),
    (dict(keypoint_offset=-0.01), "keypoint_offset"),
    (dict(keypoint_offset=float("nan")), "keypoint_offset"),
    (dict(height_sigma=-0.01), "height_sigma"),
    (dict(height_sigma=float("inf")), "height_sigma"),
    (dict(height_sigma="2 %"), "height_sigma"),
    (dict(pixel_sigma=0.0), "pixel_sigma"),
])
def test_bad_values_are_refused_by_name(bad, field):
    with pytest.raises(InputError) as info:
        RefineOptions(**bad)
    assert info.value.field == field


def test_calibrate_takes_the_height_once():
    scene = make_scene(frames=60, seed=4)
    inner = mg.CalibrateOptions(refine=False,
                                refine_options=RefineOptions(subject_height=1.70))
    with pytest.raises(InputError, match="give the height once"):
        mg.calibrate(scene.detections, scene.intrinsics,
                     mg.CalibrateOptions(subject_height=1.80, refine=False,
                                         refine_options=RefineOptions(subject_height=1.70)))
    run = mg.calibrate(scene.detections, scene.intrinsics, inner)
    # the refinement's height is the run's: recorded, not silently dropped
    assert run.calibration.input["subject_height"] == pytest.approx(1.70)


def test_lines_frames_must_be_positive():
    """``FocalOptions(lines_frames=0)`` is refused by name."""
    from mirrorgraph.errors import InputError
    from mirrorgraph.graph.options import FocalOptions
    with pytest.raises(InputError) as info:
        FocalOptions(lines_frames=0)
    assert info.value.field == "lines_frames"
