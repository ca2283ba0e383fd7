"""Fuzzing the keypoint folders (OpenPose, EasyMocap): empty folders, other files beside the
frames, a file of another format, names without a frame number, two files of one frame
(the contract: ``tests/fuzzing.py``)."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from tests.fuzzing import (BASES, EASYMOCAP, FRAMES, INPUT, OPENPOSE, Case, Frames,
                           check_keypoint_case, dumps, frame_re, fuzz_settings, lit,
                           prior_outputs)


@st.composite
def folder_case(draw) -> Case:
    """Empty folders, other files, mixed formats, bad file names."""
    fmt = draw(st.sampled_from([OPENPOSE, EASYMOCAP]))
    base = draw(st.sampled_from(BASES))
    fr = Frames(fmt, base)
    other = EASYMOCAP if fmt is OPENPOSE else OPENPOSE
    folder = INPUT[fmt.name]
    kind = draw(st.sampled_from(["empty", "no_json", "harmless", "intruder", "no_number",
                                 "duplicate", "huge_number"]))
    if kind == "empty":
        return fr.case("empty folder", "error", (lit(folder), lit("no JSON")), drop_all=True)
    if kind == "no_json":
        fr.extra = {"README.txt": b"frames", "000001.png": b"\x89PNG"}
        return fr.case("only non-JSON files", "error", (lit(folder), lit("no JSON")),
                       drop_all=True)
    if kind == "harmless":
        fr.extra = {"README.txt": b"keypoints", ".DS_Store": b"\x00\x01", "000001.png": b"",
                    "sub.json": None, "notes.JSON.bak": b"{"}
        return fr.case("other files beside the frames", "ok", close=True)
    if kind == "intruder":
        doc = draw(st.sampled_from(["other", "mmpose", "empty_object", "list"]))
        content = {"other": base.docs[other.name][0], "mmpose": base.docs["mmpose"][:2],
                   "empty_object": {}, "list": [1, 2]}[doc]
        name = draw(st.sampled_from(["000900.json", "video_000000000900_keypoints.json",
                                     "zzz_000900.json"]))
        fr.extra = {name: dumps(content)}
        first = sorted(fr.file_names + [name])[0] == name
        if first and doc == "other":     # the folder reads as the other format
            names = (lit(folder), lit("mixes formats"))
        elif first:
            names = (lit(folder), lit(name))
        else:
            names = (lit(name), lit("mixes formats"))
        return fr.case(f"{doc} file {name} among the frames", "error", names)
    if kind == "no_number":
        name = draw(st.sampled_from(["notes.json", "calib.json", "a.json"]))
        fr.extra = {name: dumps(fr.docs[0])}
        return fr.case(f"{name} among the frames", "error", (lit(name),))
    if kind == "duplicate":
        i = draw(st.integers(0, FRAMES - 1))
        t = fr.ids[i]
        fr.extra = {f"copy_{t:06d}.json": dumps(fr.docs[i])}
        return fr.case(f"two files of frame {t}", "error",
                       (lit(folder), frame_re(t), lit("duplicate")))
    digits = draw(st.integers(19, 40))
    fr.extra = {f"{'9' * digits}.json": dumps(fr.docs[0])}
    return fr.case(f"a frame number of {digits} digits", "error",
                   (lit(folder), lit("out of range")))


@fuzz_settings("folders")
@given(case=folder_case(), prior=prior_outputs)
def test_folders(case, prior, capfd):
    check_keypoint_case(case, capfd, prior)
