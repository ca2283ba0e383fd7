"""Fuzzing the JSON keypoint readers (MMPose predictions, OpenPose and EasyMocap folders)
through ``read_keypoints`` and ``mirrorgraph calibrate``: every value, structure and byte
of a valid file mutated (the contract and the mutations: ``tests/fuzzing.py``)."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from tests.fuzzing import (BASES, EASYMOCAP, FRAMES, MMPOSE, OPENPOSE, Case, Fmt, Frames,
                           check_keypoint_case, field_re, frame_re, fuzz_settings, json_case,
                           lit, prior_outputs)


@fuzz_settings("mmpose")
@given(case=json_case(MMPOSE), prior=prior_outputs)
def test_mmpose_json(case, prior, capfd):
    check_keypoint_case(case, capfd, prior)


@st.composite
def folder_json_case(draw, fmt: Fmt) -> Case:
    """As json_case, plus width/height of EasyMocap files."""
    if fmt.name == "easymocap" and draw(st.integers(0, 3)) == 0:
        return draw(easymocap_size_mutation())
    return draw(json_case(fmt))


@st.composite
def easymocap_size_mutation(draw) -> Case:
    fr = Frames(EASYMOCAP, draw(st.sampled_from(BASES)))
    i = draw(st.integers(0, FRAMES - 1))
    file_re, t_re = fr.where(i)
    key = draw(st.sampled_from(["width", "height"]))
    kind = draw(st.sampled_from(["delete_one", "delete_both", "type", "value", "differs",
                                 "all"]))
    doc = fr.docs[i]
    if kind == "delete_one":
        del doc[key]
        return fr.case(f"file #{i} without {key}", "error", (file_re, t_re, field_re(key)))
    if kind == "delete_both":
        del doc["width"], doc["height"]
        return fr.case(f"file #{i} without an image size", "ok", close=True)
    if kind == "type":
        v = draw(st.sampled_from(["1920", 1920.0, None, True, [1920]]))
        doc[key] = v
        return fr.case(f"file #{i} {key} = {v!r}", "error", (file_re, t_re, field_re(key)))
    if kind == "value":
        v = draw(st.one_of(st.integers(-10**6, 0), st.integers(10**6 + 1, 10**30)))
        doc[key] = v
        return fr.case(f"file #{i} {key} = {v}", "error", (file_re, t_re, field_re(key)))
    if kind == "differs":
        v = doc[key] + draw(st.integers(1, 500))
        doc[key] = v
        k = 1 if i == 0 else i     # the file that disagrees with an earlier one
        names = (lit(fr.file_names[k]), frame_re(fr.ids[k]), field_re(key))
        return fr.case(f"file #{i} {key} = {v}", "error", names)
    w, h = draw(st.integers(1, 10**6)), draw(st.integers(1, 10**6))
    for d in fr.docs:
        d["width"], d["height"] = w, h
    # the image size disagrees with the keypoints: not an input error (see the
    # image-size tests of test_fuzz_calibrate.py); K comes from the camera file, so the
    # result stands
    return fr.case(f"every file says {w}x{h}", "ok", close=True)


@fuzz_settings("openpose")
@given(case=folder_json_case(OPENPOSE), prior=prior_outputs)
def test_openpose_folder(case, prior, capfd):
    check_keypoint_case(case, capfd, prior)


@fuzz_settings("easymocap")
@given(case=folder_json_case(EASYMOCAP), prior=prior_outputs)
def test_easymocap_folder(case, prior, capfd):
    check_keypoint_case(case, capfd, prior)
