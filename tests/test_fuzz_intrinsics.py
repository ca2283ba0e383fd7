"""Fuzzing the intrinsics (``load_intrinsics``: camera JSON and OpenCV YAML) and
``mirrorgraph calibrate --intrinsics``: K, distortion, image size and the document
itself (the contract: ``tests/fuzzing.py``)."""

from __future__ import annotations

import copy
import os
import tempfile
from pathlib import Path

import cv2
import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from mirrorgraph.cli.args import error_message
from mirrorgraph.intrinsics import MAX_K_ENTRY, load_intrinsics

from tests.fuzzing import (BASES, CAM, MM, NONFINITE, Base, Case, check_calibration,
                           check_reader, dumps, field_re, fuzz_settings, lit, prior_outputs,
                           run_cli)


class CamCase(Case):
    """A generated intrinsics file: its bytes and suffix instead of keypoint files."""

    def __init__(self, what: str, base: Base, text: bytes, suffix: str, read: str,
                 names: tuple = (), close: bool = False) -> None:
        super().__init__(what, base, {}, "", read, names, close)
        self.text, self.suffix = text, suffix


def _yaml_text(K, dist=None, size=None) -> bytes:
    with tempfile.TemporaryDirectory() as d:
        p = os.path.join(d, "c.yml")
        fs = cv2.FileStorage(p, cv2.FILE_STORAGE_WRITE)
        if K is not None:
            fs.write("camera_matrix", np.asarray(K, float))
        if dist is not None:
            fs.write("distortion_coefficients", np.asarray(dist, float))
        if size is not None:
            for k, v in zip(("image_width", "image_height"), size):
                if v is not None:
                    fs.write(k, int(v))
        fs.release()
        return Path(p).read_bytes()


def singular_K(K: list, draw) -> list:
    """K with last row [0, 0, 1], positive fx, fy and a zero determinant."""
    K = copy.deepcopy(K)
    s = draw(st.floats(1.0, 1e4))
    K[0][1], K[1][0] = s, K[0][0] * K[1][1] / s
    return K


@st.composite
def camera_case(draw) -> CamCase:
    base = draw(st.sampled_from(BASES))
    K = copy.deepcopy(base.K)
    w, h = base.image_size
    cam = {"K": K, "image_size": [w, h]}
    kind = draw(st.sampled_from(["valid", "K", "K", "dist", "image_size", "document", "yaml"]))

    def case(what, read, names=(), close=False, text=None, suffix=".json"):
        file = f"{CAM}{suffix}"
        names = tuple(lit(file) if n == "FILE" else n for n in names)
        return CamCase(f"camera: {what}", base, dumps(cam) if text is None else text, suffix,
                       read, names, close)

    if kind == "valid":
        sub = draw(st.sampled_from(["as is", "zero dist", "no image size", "other size",
                                    "tiny dist"]))
        if sub == "zero dist":
            cam["dist"] = [0.0] * draw(st.sampled_from([4, 5, 8, 12, 14]))
        elif sub == "no image size":
            del cam["image_size"]
        elif sub == "other size":   # larger than the video; K is still right (a size
            # too small for the keypoints is an error: test_fuzz_calibrate.py)
            cam["image_size"] = [draw(st.integers(w, 10**6)), draw(st.integers(h, 10**6))]
        elif sub == "tiny dist":
            cam["dist"] = [draw(st.floats(-1e-4, 1e-4)) for _ in range(5)]
        return case(sub, "ok", close=True)
    if kind == "K":
        sub = draw(st.sampled_from(["singular", "focal", "nonfinite", "last_row", "shape",
                                    "type", "missing", "huge", "tiny"]))
        if sub == "singular":
            cam["K"] = singular_K(K, draw)
        elif sub == "focal":
            k = draw(st.sampled_from([(0, 0), (1, 1)]))
            K[k[0]][k[1]] = draw(st.sampled_from([0.0, -1.0, -K[k[0]][k[1]], -1e300]))
        elif sub == "nonfinite":
            K[draw(st.integers(0, 1))][draw(st.integers(0, 2))] = draw(st.sampled_from(NONFINITE))
        elif sub == "last_row":
            K[2] = draw(st.sampled_from([[0, 0, 0], [0, 0, 2], [1e-3, 0, 1], [0, 0, -1]]))
        elif sub == "shape":
            cam["K"] = draw(st.sampled_from([K[:2], [r + [0.0] for r in K],
                                             sum(K, []), [K], [[1.0]], []]))
        elif sub == "type":
            cam["K"] = draw(st.sampled_from(["K", None, 1400.0, {"fx": 1400},
                                             [["a", 0, 0], [0, 1, 0], [0, 0, 1]],
                                             [[True, 0, 0], [0, True, 0], [0, 0, True]]]))
        elif sub == "missing":
            del cam["K"]
        else:   # absurd: a result, or a clean refusal beyond MAX_K_ENTRY
            f = draw(st.floats(1e6, 1e300) if sub == "huge" else st.floats(1e-6, 10.0))
            K[0][0] = K[1][1] = f
            if f > MAX_K_ENTRY:
                return case(f"K focal {f}", "error", ("FILE", field_re("K")))
            return case(f"K focal {f}", "ok")
        return case(f"K {sub}: {cam.get('K')!r}", "error", ("FILE", field_re("K")))
    if kind == "dist":
        sub = draw(st.sampled_from(["length", "nonfinite", "type", "large"]))
        if sub == "length":
            cam["dist"] = [0.01] * draw(st.sampled_from([0, 1, 2, 3, 6, 7, 9, 13, 15, 30]))
        elif sub == "nonfinite":
            cam["dist"] = [0.0, draw(st.sampled_from(NONFINITE)), 0.0, 0.0, 0.0]
        elif sub == "type":
            cam["dist"] = draw(st.sampled_from(["none", [0, "a", 0, 0, 0], [[0, 0], [0]],
                                                {"k1": 0}, [True, 0, 0, 0]]))
        else:   # a lens no camera has: a result or a clean refusal
            cam["dist"] = [draw(st.floats(-1e30, 1e30)) for _ in range(5)]
            return case(f"dist {cam['dist']}", "ok")
        return case(f"dist {cam['dist']!r}", "error", ("FILE", field_re("dist")))
    if kind == "image_size":
        v = draw(st.sampled_from([[0, 1080], [-1920, 1080], [1920.5, 1080], ["1920", 1080],
                                  [True, 1080], [1920], [1920, 1080, 3], "1920x1080",
                                  {"w": 1920}, [10**7, 1080], [10**400, 1]]))
        cam["image_size"] = v
        return case(f"image_size {v!r}", "error", ("FILE", field_re("image_size")))
    if kind == "document":
        data = dumps(cam)
        sub = draw(st.sampled_from(["truncate", "list", "string", "empty", "number"]))
        if sub == "truncate":
            k = draw(st.integers(0, len(data) - 1))
            return case(f"cut to {k} bytes", "error", ("FILE",), text=data[:k])
        text = {"list": b"[[1400, 0, 960], [0, 1400, 540], [0, 0, 1]]", "string": b'"K"',
                "empty": b"", "number": b"1400"}[sub]
        return case(sub, "error", ("FILE",), text=text)
    # OpenCV YAML
    sub = draw(st.sampled_from(["valid", "truncate", "garble", "singular", "negative",
                                "one_side", "no_matrix", "matrix_key"]))
    if sub == "valid":
        return case("yaml", "ok", close=True, text=_yaml_text(K, [0.0] * 5, (w, h)),
                    suffix=".yml")
    if sub in ("truncate", "garble"):
        data = _yaml_text(K, [0.0] * 5, (w, h))
        k = draw(st.integers(0, len(data) - 1))
        if sub == "garble":
            b = draw(st.one_of(st.integers(0, 255).map(lambda v: bytes([v])),
                               st.sampled_from([b"", b"[", b":", b"-", b"\n", b"!", b"  "])))
            return case(f"yaml byte {k} -> {b!r}", "either", ("FILE",),
                        text=data[:k] + b + data[k + 1:], suffix=".yml")
        return case(f"yaml cut to {k} bytes", "either", ("FILE",), text=data[:k],
                    suffix=".yml")
    if sub == "matrix_key":   # OpenCV's own reader corrupted memory without 'cols'
        key = draw(st.sampled_from(["rows", "cols", "dt", "data"]))
        lines = _yaml_text(K, [0.0] * 5, (w, h)).decode().splitlines(keepends=True)
        first = next(i for i, ln in enumerate(lines) if ln.strip().startswith(f"{key}:"))
        text = "".join(lines[:first] + lines[first + 1:]).encode()
        # (OpenCV's parser itself refuses a matrix ending without 'data': no field then)
        names = ("FILE",) if key == "data" else ("FILE", field_re("camera_matrix"), lit(key))
        return case(f"yaml camera_matrix without {key}", "error", names, text=text,
                    suffix=".yml")
    if sub == "singular":
        return case("yaml singular K", "error", ("FILE", field_re("camera_matrix")),
                    text=_yaml_text(singular_K(K, draw)), suffix=".yml")
    if sub == "negative":
        K[0][0] = -K[0][0]
        return case("yaml negative fx", "error", ("FILE", field_re("camera_matrix")),
                    text=_yaml_text(K), suffix=".yml")
    if sub == "one_side":
        return case("yaml image_width only", "error", ("FILE", field_re("image_height")),
                    text=_yaml_text(K, None, (w, None)), suffix=".yml")
    return case("yaml without camera_matrix", "error", ("FILE", field_re("camera_matrix")),
                text=_yaml_text(None, [0.0] * 5), suffix=".yml")


@fuzz_settings("intrinsics")
@given(case=camera_case(), prior=prior_outputs)
def test_intrinsics(case, prior, capfd):
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        cam = root / f"{CAM}{case.suffix}"
        cam.write_bytes(case.text)
        error = check_reader(lambda: load_intrinsics(cam), case.names, case.read)
        kp = root / MM
        kp.write_bytes(dumps(case.base.docs["mmpose"]))
        out = root / "calibration.json"
        code, err = run_cli(["calibrate", str(kp), "--intrinsics", str(cam), "--out",
                             str(out), "--no-refine", "--quiet"], out, capfd, prior=prior)
        if error is not None:
            assert code == 2 and err == f"error: {error_message(error)}\n", (err, str(error))
        elif code == 0:
            check_calibration(out, case.base.normal if case.close else None)
        else:
            assert not case.close, f"valid intrinsics refused: {err}"
