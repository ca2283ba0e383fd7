"""Fuzzing the paired ``.npz`` reader: values, missing and extra arrays, dtypes, shapes,
frame ids, metadata and the file itself (the contract: ``tests/fuzzing.py``)."""

from __future__ import annotations

import io
import math
import zipfile

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from tests.fuzzing import (BASES, KNOWN_COUNTS, NONFINITE, NPZ, Case, check_keypoint_case,
                           field_re, frame_re, fuzz_settings, lit, prior_outputs)


def npz_bytes(arrays: dict) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


@st.composite
def npz_case(draw) -> Case:
    base = draw(st.sampled_from(BASES))
    a = {k: v.copy() for k, v in base.npz.items()}
    ids = a["frame_ids"].tolist()
    T, J = a["real"].shape[:2]
    kind = draw(st.sampled_from(["valid", "value", "value", "missing", "dtype", "shape",
                                 "frame_ids", "meta", "file"]))

    def case(what, read, names=(), close=False, data=None):
        return Case(f"npz: {what}", base, {NPZ: npz_bytes(a) if data is None else data},
                    NPZ, read, names, close)

    if kind == "valid":
        sub = draw(st.sampled_from(["as is", "minimal", "flipped", "float32", "shuffled"]))
        if sub == "minimal":
            for k in ("frame_ids", "skeleton", "image_size", "fps", "mirror_flipped"):
                a.pop(k, None)
        elif sub == "flipped":
            from mirrorgraph.skeletons import skeleton_by_name
            a["mirror"] = a["mirror"][:, skeleton_by_name(base.skeleton).flip]
            a["mirror_flipped"] = np.array(True)
        elif sub == "float32":
            a["real"], a["mirror"] = a["real"].astype(np.float32), a["mirror"].astype(np.float32)
        elif sub == "shuffled":
            order = np.random.default_rng(draw(st.integers(0, 99))).permutation(T)
            for k in ("real", "mirror", "frame_ids"):
                a[k] = a[k][order]
        return case(sub, "ok", close=True)
    if kind == "value":
        view = draw(st.sampled_from(["real", "mirror"]))
        t, j, c = draw(st.integers(0, T - 1)), draw(st.integers(0, J - 1)), draw(st.integers(0, 2))
        sub = draw(st.sampled_from(["nonfinite", "nan_missing", "confidence", "coordinate"]))
        where = (lit(NPZ), field_re(view), frame_re(ids[t]))
        if sub == "nonfinite":
            v = draw(st.sampled_from(NONFINITE))
            a[view][t, j, c] = v
            return case(f"{view}[{t}, {j}, {c}] = {v}", "error", where)
        if sub == "nan_missing":
            a[view][t, j] = [math.nan, math.nan, 0.0]
            return case(f"{view}[{t}, {j}] missing as NaN", "ok", close=True)
        if sub == "confidence":
            v = draw(st.one_of(st.floats(-1e300, -1e-9), st.floats(0, 1.5),
                               st.floats(1.5001, 1e300)))
            a[view][t, j, 2] = v
            bad = v < 0 or v > 1.5
            return case(f"{view}[{t}, {j}] confidence {v}", "error" if bad else "ok",
                        where + (rf"\bjoint {j}\b",) if bad else ())
        v = draw(st.one_of(st.floats(-1e6, 1e6), st.floats(1.0000001e6, 1e300),
                           st.floats(-1e300, -1.0000001e6)))
        a[view][t, j, draw(st.integers(0, 1))] = v
        far = abs(v) > 1e6 and a[view][t, j, 2] != 0
        return case(f"{view}[{t}, {j}] coordinate {v}", "error" if far else "ok",
                    where + (rf"\bjoint {j}\b",) if far else ())
    if kind == "missing":
        key = draw(st.sampled_from(["real", "mirror", "frame_ids", "skeleton", "image_size",
                                    "fps", "mirror_flipped"]))
        a.pop(key)
        if key in ("real", "mirror"):
            return case(f"without {key}", "error", (lit(NPZ), field_re(key)))
        return case(f"without {key}", "ok", close=key != "mirror_flipped")
    if kind == "dtype":
        key = draw(st.sampled_from(["real", "mirror"]))
        to = draw(st.sampled_from(["str", "complex", "bool", "object"]))
        if to == "object":
            a[key] = np.array([None] * 3, dtype=object)
        else:
            a[key] = a[key].astype({"str": str, "complex": complex, "bool": bool}[to])
        return case(f"{key} as {to}", "error", (lit(NPZ), field_re(key)))
    if kind == "shape":
        sub = draw(st.sampled_from(["2d", "xy", "4d", "mismatch", "no_frames", "joints"]))
        if sub == "2d":
            a["real"] = a["real"][:, :, 0]
        elif sub == "xy":
            a["mirror"] = a["mirror"][..., :2]
        elif sub == "4d":
            a["real"] = a["real"][..., None]
        elif sub == "mismatch":
            a["mirror"] = a["mirror"][:-1]
        elif sub == "no_frames":
            a["real"], a["mirror"] = a["real"][:0], a["mirror"][:0]
            a["frame_ids"] = a["frame_ids"][:0]
        else:
            n = draw(st.integers(1, 30).filter(lambda n: n != J))
            idx = np.arange(n) % J
            a["real"], a["mirror"] = a["real"][:, idx], a["mirror"][:, idx]
            keep = draw(st.booleans())
            if not keep:
                a.pop("skeleton")
            if not keep and n in KNOWN_COUNTS:   # read as another skeleton: any result
                return case(f"{n} joints, no skeleton name", "ok")
        field_name = {"xy": "mirror", "mismatch": "mirror"}.get(sub, "real")
        if sub == "joints" and keep:
            field_name = "real"
        return case(f"shape change {sub}", "error", (lit(NPZ), field_re(field_name)))
    if kind == "frame_ids":
        sub = draw(st.sampled_from(["length", "float", "duplicate", "huge", "2d"]))
        if sub == "length":
            a["frame_ids"] = a["frame_ids"][:-1]
        elif sub == "float":
            a["frame_ids"] = a["frame_ids"].astype(float)
        elif sub == "2d":
            a["frame_ids"] = a["frame_ids"][:, None]
        elif sub == "duplicate":
            k = draw(st.integers(1, T - 1))
            a["frame_ids"][k] = a["frame_ids"][k - 1]
            return case(f"frame id {ids[k - 1]} twice", "error",
                        (lit(NPZ), frame_re(ids[k - 1]), lit("duplicate")))
        else:
            a["frame_ids"] = a["frame_ids"].astype(np.uint64) + np.uint64(2**63)
            return case("frame ids beyond int64", "error", (lit(NPZ), lit("out of range")))
        return case(f"frame_ids {sub}", "error", (lit(NPZ), field_re("frame_ids")))
    if kind == "meta":
        key = draw(st.sampled_from(["skeleton", "image_size", "fps", "mirror_flipped"]))
        bad = {"skeleton": [np.array("COCO_99"), np.array(b"COCO_17"), np.array(17),
                            np.array(["COCO_17"]),
                            np.array("BODY_25" if base.skeleton == "COCO_17" else "COCO_17")],
               "image_size": [np.array([1920]), np.array([0, 1080]), np.array([1920.5, 1080]),
                              np.array([-1, 1080]), np.array([1e300, 1080]),
                              np.array(["1920", "1080"]), np.array([10**7, 1080])],
               "fps": [np.array(0.0), np.array(-30.0), np.array(math.nan), np.array("30"),
                       np.array([30.0, 25.0])],
               "mirror_flipped": [np.array(2), np.array(0.5), np.array([True]),
                                  np.array("yes")]}[key]
        v = draw(st.sampled_from(bad))
        a[key] = v
        # a known skeleton name that disagrees with the joint count: the count is at fault
        at = "real" if key == "skeleton" and v.dtype.kind == "U" and v.ndim == 0 \
            and str(v) != "COCO_99" else key
        return case(f"{key} = {v!r}", "error", (lit(NPZ), field_re(at)))
    # the file itself
    data = npz_bytes(a)
    sub = draw(st.sampled_from(["truncate", "flip", "npy", "empty_zip", "text"]))
    if sub == "truncate":
        k = draw(st.integers(0, len(data) - 1))
        return case(f"cut to {k} bytes", "error", (lit(NPZ),), data=data[:k])
    if sub == "flip":
        k = draw(st.integers(0, len(data) - 1))
        b = draw(st.integers(0, 255))
        return case(f"byte {k} = {b}", "either", (lit(NPZ),),
                    data=data[:k] + bytes([b]) + data[k + 1:])
    if sub == "npy":
        buf = io.BytesIO()
        np.save(buf, a["real"])
        return case("a .npy array", "error", (lit(NPZ),), data=buf.getvalue())
    if sub == "empty_zip":
        buf = io.BytesIO()
        zipfile.ZipFile(buf, "w").close()
        return case("an empty zip", "error", (lit(NPZ), field_re("real")), data=buf.getvalue())
    return case("a text file", "error", (lit(NPZ),), data=b"real,mirror\n1,2\n")


@fuzz_settings("npz")
@given(case=npz_case(), prior=prior_outputs)
def test_paired_npz(case, prior, capfd):
    check_keypoint_case(case, capfd, prior)
