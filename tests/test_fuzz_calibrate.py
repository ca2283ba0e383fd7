"""Fuzzing what ``mirrorgraph calibrate`` makes of odd but readable inputs: frames with 0 to
5 people, the factor graph on them, image sizes that cannot hold the keypoints, and
keypoints that determine no mirror (the contract: ``tests/fuzzing.py``)."""

from __future__ import annotations

import copy
import json
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import Phase, given
from hypothesis import strategies as st

from mirrorgraph.cli import main
from mirrorgraph.skeleton_guess import MIN_DETECTIONS

from tests.fuzzing import (BASES, EASYMOCAP, FRAMES, MM, MMPOSE, OPENPOSE, Case, Frames,
                           check_calibration, check_keypoint_case, dumps, fuzz_settings,
                           get_value, json_case, prior_outputs, run_cli, set_value,
                           write_mmpose_and_camera)


@st.composite
def people_case(draw) -> Case:
    """Frames with zero, one, two or five people, in every JSON format."""
    fmt = draw(st.sampled_from([MMPOSE, OPENPOSE, EASYMOCAP]))
    fr = Frames(fmt, draw(st.sampled_from(BASES)))
    counts = draw(st.lists(st.sampled_from([0, 1, 2, 2, 5]), min_size=FRAMES,
                           max_size=FRAMES))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    for i, n in enumerate(counts):
        people = fr.persons(i)
        if n == 0:
            people.clear()
        elif n == 1:
            people.pop(int(rng.integers(2)))
        elif n == 5:
            for _ in range(3):    # bystanders: a copy of someone, moved and shrunk
                q = copy.deepcopy(people[rng.integers(len(people))])
                dx, dy, s = rng.uniform(-400, 400), rng.uniform(-200, 200), rng.uniform(.5, 1)
                for j in range(fr.base.J):
                    for c, off in ((0, dx), (1, dy)):
                        v = get_value(fmt, q, j, c)
                        set_value(fmt, q, j, c, 960 + s * (v - 960) + off)
                people.insert(int(rng.integers(len(people) + 1)), q)
    close = all(n == 2 for n in counts)
    # 25 keypoints: BODY_25 or BODY_25B, told apart only with enough people
    read = "ok" if fr.base.J != 25 or sum(counts) >= MIN_DETECTIONS else "either"
    return fr.case(f"people per frame {counts}", read, close=close)


@fuzz_settings("people")
@given(case=people_case(), prior=prior_outputs)
def test_people_per_frame(case, prior, capfd):
    check_keypoint_case(case, capfd, prior)


@fuzz_settings("refine")
@given(case=st.one_of(people_case(), json_case(MMPOSE), json_case(OPENPOSE)),
       height=st.one_of(st.none(), st.floats(1.2, 2.2)), prior=prior_outputs)
def test_refinement_on_odd_inputs(case, height, prior, capfd):
    """The factor graph (and --joints3d, --subject-height) on the same kinds of input."""
    check_keypoint_case(case, capfd, prior, refine=True, height=height)


# =============================================================================== image size
# Image sizes that disagree with the keypoints (preprocess.check_image_size):
# * intrinsics whose image size cannot hold most of the keypoints (more than half of the
#   detected joints outside the image enlarged by 10% on each side) are an InputError
#   naming that size and the field image_size, as an impossible --image-size is: the
#   keypoints and K are not in the same pixels (a resized video, the wrong camera file),
#   and the normal found with that K would be wrong;
# * without intrinsics, an image size that cannot hold most keypoints is an InputError
#   naming the size and the field image_size: the guessed K comes from that size alone.
# (An EasyMocap or npz image size unlike the camera file's is no error either: see the
# "every file says WxH" case of io/test_fuzz_json.py and "other size" of
# test_fuzz_intrinsics.py.)
@fuzz_settings("image_size_small", phases=[Phase.explicit, Phase.generate])
@given(base=st.sampled_from(BASES), scale=st.one_of(st.floats(0.02, 0.3), st.floats(1.0, 3.0)))
def test_image_size_far_smaller_than_keypoints_is_an_error(base, scale, capfd):
    w, h = (max(1, int(v * scale)) for v in base.image_size)
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        kp, cam = write_mmpose_and_camera(root, base, {"K": base.K, "image_size": [w, h]})
        out = root / "calibration.json"
        code, err = run_cli(["calibrate", str(kp), "--intrinsics", str(cam), "--out", str(out),
                             "--no-refine", "--quiet"], out, capfd, prior=None)
        if scale < 0.5:
            assert code == 2 and f"{w}x{h}" in err and "image_size" in err, err
        else:
            assert code == 0, err
            check_calibration(out, base.normal)


@fuzz_settings("image_size_impossible", phases=[Phase.explicit, Phase.generate])
@given(base=st.sampled_from(BASES), w=st.integers(1, 300), h=st.integers(1, 150))
def test_impossible_image_size_without_intrinsics_is_an_error(base, w, h, capfd):
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        kp = root / MM
        kp.write_bytes(dumps(base.docs["mmpose"]))
        out = root / "calibration.json"
        code, err = run_cli(["calibrate", str(kp), "--image-size", f"{w}x{h}", "--out",
                             str(out), "--no-refine", "--quiet"], out, capfd, prior=None)
        assert code == 2 and f"{w}x{h}" in err and "image_size" in err, err


# Found by this suite in pipeline.py, fixed since; it stays as a test.
def test_degenerate_geometry_error_names_the_input(capfd):
    kp = np.array([[100.0 + 30 * j, 500.0, 1.0] for j in range(17)])
    real = np.repeat(kp[None], 20, axis=0)   # every pair on the line y = 500
    mirror = real.copy()
    mirror[..., 0] += 400.0
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        path = root / "flat_line.npz"
        np.savez(path, real=real, mirror=mirror)
        cam = root / "cam.json"
        cam.write_text(json.dumps(BASES[0].camera))
        code = main(["calibrate", str(path), "--intrinsics", str(cam), "--out",
                     str(root / "c.json"), "--no-refine"])
        err = capfd.readouterr().err
        assert code == 2 and "flat_line.npz" in err, err
