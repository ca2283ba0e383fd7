"""Pairing person and reflection on synthetic detections with known truth."""

import numpy as np
import pytest

from mirrorgraph.errors import InputError
from mirrorgraph.keypoints import RawDetections
from mirrorgraph.pairing import fix_left_right, pair_detections
from mirrorgraph.synth import make_scene


def _agreement(paired, scene):
    """Fraction of paired frames whose real/mirror rows match the clean truth."""
    ok = np.isfinite(paired.real[..., 0]).any(1)
    d_real = np.nanmedian(np.linalg.norm(paired.real[ok, :, :2] - scene.real_clean[ok], axis=-1), 1)
    d_mirr = np.nanmedian(np.linalg.norm(paired.mirror[ok, :, :2] - scene.mirror_clean[ok], axis=-1), 1)
    return np.mean((d_real < 20) & (d_mirr < 20)), ok


def test_pairs_shuffled_people_and_flips_reflection():
    scene = make_scene(frames=300, seed=11)
    paired = pair_detections(scene.detections)
    agree, ok = _agreement(paired, scene)
    assert ok.mean() > 0.97
    assert agree > 0.99
    assert paired.lr_fixes == 0


def test_left_right_confusions_are_detected_per_frame():
    scene = make_scene(frames=300, seed=12, lr_swap_rate=0.2)
    paired = pair_detections(scene.detections)
    agree, _ = _agreement(paired, scene)
    assert agree > 0.98
    assert abs(paired.lr_fixes - scene.lr_swapped.sum()) <= 0.05 * len(scene.lr_swapped)


def test_missing_single_and_extra_people():
    scene = make_scene(frames=300, seed=13, single_person_rate=0.15, extra_person_rate=0.2,
                       missing_rate=0.05, outlier_rate=0.05)
    paired = pair_detections(scene.detections)
    agree, ok = _agreement(paired, scene)
    assert agree > 0.97
    # frames with one person detected cannot be paired
    one = np.array([len(p) < 2 for p in scene.detections.people])
    assert not ok[one].any()


def test_fix_left_right_on_paired_input():
    scene = make_scene(frames=300, seed=14, lr_swap_rate=0.15)
    truth = scene.paired()
    # make the reflection's labels wrong where the detector swapped them
    bad = truth.mirror.copy()
    flip = truth.skeleton.flip
    bad[scene.lr_swapped] = bad[scene.lr_swapped][:, flip]
    from dataclasses import replace
    fixed = fix_left_right(replace(truth, mirror=bad))
    assert np.nanmax(np.abs(fixed.mirror[..., :2] - truth.mirror[..., :2])) < 1e-9 or \
        np.mean(np.isclose(fixed.mirror[..., 0], truth.mirror[..., 0]) | np.isnan(truth.mirror[..., 0])) > 0.99
    assert abs(fixed.lr_fixes - scene.lr_swapped.sum()) <= 3


def test_reflection_missing_everywhere_is_an_input_error():
    scene = make_scene(frames=50, seed=15)
    lonely = RawDetections(skeleton=scene.skeleton, frame_ids=scene.detections.frame_ids,
                           people=[p[:1] for p in scene.detections.people], source="lonely.json")
    with pytest.raises(InputError, match="lonely.json.*reflection is missing"):
        pair_detections(lonely)
