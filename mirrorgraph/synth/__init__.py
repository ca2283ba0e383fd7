"""Synthetic mirror scenes with ground truth, for tests and benchmarks.

A person with individually varied, left/right symmetric proportions
(:mod:`.body`) exercises (:mod:`.motion`) between a camera and a planar mirror;
:func:`make_scene` places them, projects joints and reflection, and simulates a
pose detector (noise, outliers, left/right swaps, missing joints and people,
bystanders, lens distortion) (:mod:`.scene`; the camera in :mod:`.camera`, the
placement in :mod:`.placement`, the detector in :mod:`.detector`);
:func:`write_scene` writes the detections in every supported format with the
ground truth (:mod:`.writer`).
Instead of the procedural exercises the person can move as a motion-capture
take does: ``make_scene(motion="take.bvh")`` reads a CMU-skeleton BVH file and
maps it to the body model's joints (:mod:`.mocap`, the file read by
:mod:`mirrorgraph.io.bvh`). :func:`make_rig` films the
same person with several cameras and mirrors (four cameras; two cameras and a
wall mirror; one camera and two mirrors at an angle; optionally bystanders
with their own reflections) for ``mirrorgraph calibrate-rig``, and :func:`write_rig` writes such a rig with its ``rig.toml``
and ground truth (:mod:`.rig`).

Geometries (:mod:`.geometry`): ``make_scene(geometry=...)`` chooses the ranges
of the placement, ``"favourable"`` (the default), ``"gym"`` (a typical gym or studio: the person 0.8-2.5 m in front of a
mirror 3.5-8 m away, the epipole near the person), ``"wide"`` and
``"low_parallax"``; :func:`scene_geometry_stats` measures a scene (distance of
the person from the epipole, angle between a joint's two rays). Detector
models beyond Gaussian noise (:mod:`.detector`): outliers along the epipolar
line, left/right swaps in both views, a per-label bias. :func:`make_wide_scene`
makes the scene of a seed in a geometry slice and detector model
(:mod:`.sampling`).

    >>> from mirrorgraph.synth import make_scene
    >>> scene = make_scene(frames=300, seed=1, outlier_rate=0.05)
    >>> scene.detections.people[0].shape[1:]
    (17, 3)
"""

from .geometry import DEFAULT_GEOMETRY, PRESETS, GeometryPreset, scene_geometry_stats
from .rig import SyntheticRig, make_rig, read_rig_ground_truth, write_rig
from .sampling import NOISE_MODELS, SLICES, make_wide_scene, sample_scene_params
from .camera import tilted_normal
from .scene import SyntheticScene, make_scene
from .writer import read_ground_truth, write_scene

__all__ = ["DEFAULT_GEOMETRY", "GeometryPreset", "NOISE_MODELS", "PRESETS", "SLICES",
           "SyntheticRig", "SyntheticScene", "make_rig", "make_scene", "make_wide_scene",
           "read_ground_truth", "read_rig_ground_truth", "sample_scene_params",
           "scene_geometry_stats", "tilted_normal", "write_rig", "write_scene"]
