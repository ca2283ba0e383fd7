"""Rigs with a camera's intrinsics missing (issue 17): its focal length estimated in the
one graph, against the synthetic rig's truth; the rig file's ``image_size``."""

import dataclasses
import json

import numpy as np
import pytest

from mirrorgraph.errors import InputError
from mirrorgraph.pipelines.options import CalibrateOptions
from tests.helpers import rig_without_intrinsics


def test_rig_camera_without_intrinsics(tmp_path):
    from mirrorgraph.pipelines.rig import calibrate_rig
    from mirrorgraph.synth import make_rig

    r = make_rig("2cams1mirror", frames=300, seed=0, geometry="wide")
    cfg = rig_without_intrinsics(r, tmp_path / "rig")
    cal = calibrate_rig(cfg, CalibrateOptions(subject_height=r.subject_height))
    c = cal.cameras[1]
    est = c.intrinsics.estimated
    assert est["estimated"] and est["initial"]["method"].startswith("search through its mirror")
    assert abs(c.intrinsics.K[0, 0] / r.K[1][0, 0] - 1.0) < 0.02
    assert abs(c.intrinsics.K[0, 0] - r.K[1][0, 0]) < 4.0 * est["std_px"]
    assert np.allclose(cal.cameras[0].intrinsics.K, r.K[0])          # given: untouched
    from mirrorgraph.metrics import rotation_error_deg
    assert rotation_error_deg(c.pose[:3, :3], r.poses[1][:3, :3]) < 0.5


def test_rig_file_image_size(tmp_path):
    from mirrorgraph.rigs.config import load_rig_config
    kp = tmp_path / "kp.json"
    kp.write_text("[]")
    (tmp_path / "kp2.json").write_text("[]")
    (tmp_path / "cam.json").write_text(json.dumps({"K": [[1000, 0, 960], [0, 1000, 540],
                                                         [0, 0, 1]]}))
    # a second camera: one camera and no mirror is no rig
    other = '[[cameras]]\nname = "b"\nkeypoints = "kp2.json"\nintrinsics = "cam.json"\n'
    (tmp_path / "rig.toml").write_text('[[cameras]]\nname = "a"\nkeypoints = "kp.json"\n'
                                       'image_size = [1920, 1080]\n' + other)
    assert load_rig_config(tmp_path / "rig.toml").cameras[0].image_size == (1920, 1080)
    (tmp_path / "rig.toml").write_text('[[cameras]]\nname = "a"\nkeypoints = "kp.json"\n'
                                       'image_size = [1920]\n' + other)
    with pytest.raises(InputError, match="image_size"):
        load_rig_config(tmp_path / "rig.toml")
    (tmp_path / "rig.toml").write_text('[[cameras]]\nname = "a"\nkeypoints = "kp.json"\n'
                                       'intrinsics = "cam.json"\nimage_size = [1920, 1080]\n'
                                       + other)
    with pytest.raises(InputError, match="without intrinsics"):
        load_rig_config(tmp_path / "rig.toml")


def test_two_cameras_without_intrinsics_facing_the_calibrated_pair(tmp_path):
    # four cameras, the calibrated two facing each other across the person, the other
    # two (focal lengths 748 and 1880 px) without intrinsics: their resections start
    # 13 % and 31 % off, the calibrated cam03 7 deg off (placed through cam04; its own
    # edge to cam01 is 9 deg off: a face seen from behind is guessed); the graph brings
    # both focal lengths within a few per cent and every camera within a degree (a
    # bench run of work in progress failed here)
    from mirrorgraph.metrics import rotation_error_deg
    from mirrorgraph.rigs.config import load_rig_config
    from mirrorgraph.pipelines.rig import calibrate_rig
    from mirrorgraph.synth import make_rig, write_rig

    r = make_rig("4cams", frames=300, seed=1, geometry="wide")
    write_rig(r, tmp_path / "rig")
    cfg = load_rig_config(tmp_path / "rig" / "rig.toml")
    drop = (1, 3)
    cams = tuple(dataclasses.replace(c, intrinsics=None, image_size=tuple(r.image_size))
                 if i in drop else c for i, c in enumerate(cfg.cameras))
    cal = calibrate_rig(dataclasses.replace(cfg, cameras=cams),
                        CalibrateOptions(subject_height=r.subject_height, seed=1))
    for i in drop:
        c = cal.cameras[i]
        assert c.intrinsics.estimated["estimated"]
        assert c.intrinsics.estimated["initial"]["method"].startswith("resection")
        assert abs(c.intrinsics.K[0, 0] / r.K[i][0, 0] - 1.0) < 0.04
    for c, P in zip(cal.cameras, r.poses):
        assert rotation_error_deg(c.pose[:3, :3], np.asarray(P)[:3, :3]) < 1.0
    assert np.allclose(cal.cameras[2].intrinsics.K, r.K[2])


def test_calibrate_rig_fov_holds_a_known_field_of_view(tmp_path):
    """``calibrate-rig --fov DEG`` is ``calibrate --fov``: the camera without intrinsics
    starts at that field of view and is held near it (not estimated), and says so;
    ``--no-focal`` is ``--fov 60``. A wrong field of view is refused in one line."""
    from mirrorgraph.cli import main
    from mirrorgraph.pipelines.rig import calibrate_rig
    from mirrorgraph.synth import make_rig

    r = make_rig("2cams1mirror", frames=150, seed=0, geometry="wide")
    cfg = rig_without_intrinsics(r, tmp_path / "rig")
    true_fov = float(np.degrees(2 * np.arctan(r.image_size[0] / (2 * r.K[1][0, 0]))))
    cal = calibrate_rig(cfg, CalibrateOptions(subject_height=r.subject_height,
                                             fov_deg=true_fov, estimate_focal=False))
    f = cal.cameras[1].intrinsics.K[0, 0]
    assert abs(f / r.K[1][0, 0] - 1.0) < 0.05
    assert any(f"assumed a {true_fov:g} deg field of view" in w for w in cal.warnings)
    with pytest.raises(InputError, match="field of view"):
        calibrate_rig(cfg, CalibrateOptions(fov_deg=200.0, estimate_focal=False))
    out = tmp_path / "c.toml"
    assert main(["calibrate-rig", str(tmp_path / "rig" / "rig.toml"), "--out", str(out),
                 "--no-focal", "--quiet"]) == 0       # every camera has intrinsics: no-op
