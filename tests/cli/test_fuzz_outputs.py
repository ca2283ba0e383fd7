"""Fuzzing the outputs of the commands and the readers of the files they read back
(``export``, ``report``, ``view``, ``live``): odd output paths (missing folders, folders,
FIFOs, devices, symbolic links, the input itself, ``-``) and damaged calibration JSONs and
3D joints files. The contract is ``tests/fuzzing.py``'s: exit 0 with the output in place,
or exit 2 with one ``error:`` line; never a traceback, an internal error or a Python
warning; after a failure every file as it was, and no temporary left anywhere.
"""

from __future__ import annotations

import copy
import json
import os
import stat
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mirrorgraph.cli import main
from mirrorgraph.synth import make_scene, write_scene

from tests.fuzzing import fuzz_settings

PRIOR = b"the user's own bytes\n"


def _make_base() -> dict:
    """A small scene, its calibration JSON and its 3D joints as bytes (made once)."""
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        write_scene(make_scene(frames=40, seed=2), root, formats=("mmpose",))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert main(["calibrate", str(root / "keypoints_mmpose.json"), "--intrinsics",
                         str(root / "camera.json"), "--out", str(root / "c.json"),
                         "--joints3d", str(root / "j.npz"), "--quiet"]) == 0
        return {name: (root / name).read_bytes() for name in
                ("keypoints_mmpose.json", "camera.json", "c.json", "c.report.npz", "j.npz")}


BASE = _make_base()

#: What an output path may be, and whether a command must accept it.
KINDS = {"new": True, "existing": True, "symlink": True, "dangling_symlink": True,
         "missing_folder": False, "folder": False, "fifo": False, "device": False,
         "symlink_loop": False, "under_a_file": False, "input": False, "hardlink_input": False,
         "dash": False, "empty": False}


def snapshot(root: Path) -> dict:
    out = {}
    for p in sorted(root.rglob("*")):
        st_ = os.lstat(p)
        out[str(p)] = p.read_bytes() if stat.S_ISREG(st_.st_mode) else stat.S_IFMT(st_.st_mode)
    return out


def make_output(root: Path, kind: str, suffix: str, input_: Path) -> str:
    """An output path of ``kind`` under ``root`` (creating what it needs)."""
    target = root / f"out{suffix}"
    if kind == "existing":
        target.write_bytes(PRIOR)
    elif kind == "symlink":
        (root / f"real{suffix}").write_bytes(PRIOR)
        target.symlink_to(f"real{suffix}")
    elif kind == "dangling_symlink":
        target.symlink_to(f"made{suffix}")
    elif kind == "missing_folder":
        return str(root / "nodir" / f"out{suffix}")
    elif kind == "folder":
        target.mkdir()
    elif kind == "fifo":
        os.mkfifo(target)
    elif kind == "device":
        return "/dev/null"
    elif kind == "symlink_loop":
        target.symlink_to(target.name)
    elif kind == "under_a_file":
        (root / "afile").write_bytes(PRIOR)
        return str(root / "afile" / f"out{suffix}")
    elif kind == "input":
        return str(input_)
    elif kind == "hardlink_input":
        os.link(input_, target)
    elif kind == "dash":
        return "-"
    elif kind == "empty":
        return ""
    return str(target)


def run(argv: list[str], root: Path, capfd, *, must: bool | None) -> int:
    """``main(argv)`` under the contract; ``must``: True (exit 0), False (exit 2), None
    (either)."""
    before = snapshot(root)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code = main(argv)
    cap = capfd.readouterr()
    assert not caught, f"Python warning reached the user: {caught[0].message!r}"
    assert "Traceback" not in cap.err + cap.out and "internal error" not in cap.err, cap.err
    assert "Python warning" not in cap.err, cap.err
    left = [p for p in root.rglob(".*")]
    assert not left, f"temporaries left: {left}"
    if code == 0:
        assert must is not False, f"accepted: {argv}"
        assert all(line.startswith("warning: ") for line in cap.err.splitlines()), cap.err
    else:
        assert must is not True, (argv, cap.err)
        assert code == 2, (code, cap.err)
        assert cap.err.startswith("error: ") and cap.err.count("\n") == 1, cap.err
        assert snapshot(root) == before, "a failed run changed the user's files"
    return code


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs are POSIX")
@fuzz_settings("output_paths")
@given(kind=st.sampled_from(sorted(KINDS)),
       command=st.sampled_from(["export", "export", "view", "live", "calibrate"]))
def test_fuzz_output_paths(kind, command, capfd):
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        for name, data in BASE.items():
            (root / name).write_bytes(data)
        kp, cam, cal = root / "keypoints_mmpose.json", root / "camera.json", root / "c.json"
        if command == "export":
            out = make_output(root, kind, ".toml", cal)
            argv = ["export", str(cal), "--to", "pose2sim", out]
        elif command == "view":
            out = make_output(root, kind, ".rrd", cal)
            argv = ["view", str(cal), "--save", out]
        elif command == "live":
            out = make_output(root, kind, ".jsonl", kp)
            argv = ["live", str(kp), "--intrinsics", str(cam), "--jsonl", out,
                    "--as-fast-as-possible", "--quiet"]
        else:
            out = make_output(root, kind, ".json", kp)
            argv = ["calibrate", str(kp), "--intrinsics", str(cam), "--out", out,
                    "--no-refine", "--quiet"]
        must = KINDS[kind] or (kind == "dash" and command == "live")
        if command == "view" and kind == "empty":
            must = None                     # no --save value: the viewer, without a display
            os.environ.pop("DISPLAY", None)
            os.environ.pop("WAYLAND_DISPLAY", None)
        code = run(argv, root, capfd, must=must)
        if code == 0 and kind != "dash" and out:
            written = Path(out)
            assert written.is_file(), out
            if kind == "symlink":
                assert written.is_symlink() and (root / f"real{written.suffix}").read_bytes() \
                    != PRIOR
            if kind == "dangling_symlink":
                assert (root / f"made{written.suffix}").is_file()


# ------------------------------------------------------------------------- readers
def _mutate_json(draw, doc):
    kind = draw(st.sampled_from(["truncate", "schema", "delete", "type", "nonfinite",
                                 "unchanged"]))
    if kind == "truncate":
        text = json.dumps(doc).encode()
        return kind, text[:draw(st.integers(0, len(text) - 1))]
    doc = copy.deepcopy(doc)
    if kind == "schema":
        doc["schema_version"] = draw(st.sampled_from([0, -1, 3, 99, 2**70, "2", 2.0, None,
                                                      True, [2]]))
    elif kind in ("delete", "type", "nonfinite"):
        paths = [(k,) for k in doc] + [("mirror", k) for k in doc["mirror"]] + \
            [("intrinsics", k) for k in doc["intrinsics"]]
        path = draw(st.sampled_from(paths))
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        if kind == "delete":
            del parent[path[-1]]
        elif kind == "type":
            parent[path[-1]] = draw(st.sampled_from(["x", None, True, [], {}, 1e300, -1,
                                                     [[1, 2], [3]]]))
        else:
            parent[path[-1]] = draw(st.sampled_from([float("nan"), float("inf"), 1e308]))
    return kind, json.dumps(doc).encode()


@fuzz_settings("calibration_json")
@given(data=st.data(), command=st.sampled_from(["export", "view"]))
def test_fuzz_calibration_json(data, command, capfd):
    doc = json.loads(BASE["c.json"])
    kind, text = _mutate_json(data.draw, doc)
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        (root / "c.json").write_bytes(text)
        if command == "export":
            argv = ["export", str(root / "c.json"), "--to",
                    data.draw(st.sampled_from(["pose2sim", "anipose"])), str(root / "o.toml")]
        else:
            argv = ["view", str(root / "c.json"), "--save", str(root / "v.rrd")]
        run(argv, root, capfd, must=True if kind == "unchanged" else None)


@fuzz_settings("joints_npz")
@given(data=st.data())
def test_fuzz_joints_npz(data, capfd):
    import io
    with np.load(io.BytesIO(BASE["j.npz"])) as z:
        arrays = {k: z[k] for k in z.files}
    kind = data.draw(st.sampled_from(["truncate", "garble", "drop", "dtype", "shape", "value",
                                      "unchanged"]))
    T, J = arrays["valid"].shape
    blob = None
    if kind in ("truncate", "garble"):
        raw = BASE["j.npz"]
        k = data.draw(st.integers(0, len(raw) - 1))
        blob = raw[:k] if kind == "truncate" else raw[:k] + b"\xff" + raw[k + 1:]
    elif kind == "drop":
        arrays.pop(data.draw(st.sampled_from(sorted(arrays))))
    elif kind == "dtype":
        key = data.draw(st.sampled_from(["joints3d", "valid", "frame_ids", "fps", "joint_names"]))
        arrays[key] = np.array(["text"] * max(1, arrays[key].size)).reshape(
            arrays[key].shape if arrays[key].size else (1,))
    elif kind == "shape":
        key = data.draw(st.sampled_from(["joints3d", "valid", "frame_ids", "joint_names"]))
        arrays[key] = arrays[key][..., :-1] if arrays[key].ndim else arrays[key]
    elif kind == "value":
        X = arrays["joints3d"].copy()
        t, j, c = (data.draw(st.integers(0, T - 1)), data.draw(st.integers(0, J - 1)),
                   data.draw(st.integers(0, 2)))
        X[t, j, c] = data.draw(st.sampled_from([np.nan, np.inf, -np.inf, 1e300, -1e300, 0.0,
                                                -1.0, 1e-300]))
        arrays["joints3d"] = X
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        (root / "c.json").write_bytes(BASE["c.json"])
        path = root / "joints.npz"
        if blob is not None:
            path.write_bytes(blob)
        else:
            np.savez(path, **arrays)
        run(["view", str(root / "c.json"), "--joints3d", str(path), "--save",
             str(root / "v.rrd")], root, capfd, must=True if kind == "unchanged" else None)
