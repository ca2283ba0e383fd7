"""``calibration.json``: the schema written, and files of the earlier schema read."""

import json

import numpy as np

import mirrorgraph as mg
from mirrorgraph.result.mirror import SCHEMA_VERSION, read_calibration
from mirrorgraph.report import options_from_calibration
from mirrorgraph.stature import LIMB_CHOSEN
from mirrorgraph.synth import make_scene


def test_schema_1_files_are_read_with_their_scale_description(tmp_path):
    """Schema 1 wrote the scale's kind as ``refinement.scale_source`` and its description as
    ``scale_method``; schema 2 writes the description as ``scale_source`` (as a rig does).
    A schema-1 file reads into the same calibration, and a report's options from it keep
    the limbs the user asked for."""
    scene = make_scene(frames=80, seed=4)
    opts = mg.CalibrateOptions(subject_height=scene.subject_height,
                               refine_options=mg.RefineOptions(scale_from="limbs"))
    cal = mg.calibrate(scene.detections, scene.intrinsics, opts).calibration
    new = cal.to_dict()
    assert new["schema_version"] == SCHEMA_VERSION == 2
    assert new["refinement"]["scale_source"] == LIMB_CHOSEN
    assert "scale_method" not in new["refinement"]
    old = json.loads(json.dumps(new))
    del old["schema_version"]
    old["input"].pop("scale_from")
    ref = old["refinement"]
    ref["scale_method"], ref["scale_source"] = ref["scale_source"], "subject_height"
    path = tmp_path / "old.json"
    path.write_text(json.dumps(old))
    back = read_calibration(path)
    assert back.refinement["scale_source"] == LIMB_CHOSEN
    assert "scale_method" not in back.refinement
    assert np.array_equal(back.normal, cal.normal) and back.distance == cal.distance
    assert options_from_calibration(old).refine_options.scale_from == "limbs"
    assert options_from_calibration(new).refine_options.scale_from == "limbs"
