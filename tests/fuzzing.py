"""The property-based bad-input suite (hypothesis): what its test modules share.

The suite fuzzes every reader and ``mirrorgraph calibrate``, one test module per subject:

* ``tests/io/test_fuzz_json.py``: MMPose JSON, OpenPose and EasyMocap folders;
* ``tests/io/test_fuzz_folders.py``: the folders themselves (empty, mixed, odd names);
* ``tests/io/test_fuzz_npz.py``: paired ``.npz`` files;
* ``tests/test_fuzz_intrinsics.py``: camera files (JSON, OpenCV YAML);
* ``tests/test_fuzz_calibrate.py``: what the calibration makes of odd inputs (0 to 5
  people a frame, the factor graph, image sizes, degenerate geometry);
* ``tests/cli/test_fuzz_cli.py``: the options of ``calibrate``;
* ``tests/cli/test_fuzz_outputs.py``: the output paths of ``export``, ``view``, ``live``
  and ``calibrate`` (missing folders, folders, FIFOs, devices, symbolic links, the input
  itself, ``-``), damaged calibration JSONs (``export``, ``view``) and 3D joints files
  (``view --joints3d``);
* ``tests/test_fuzzing.py``: the plan below (every planned test exists, the total).

Each test draws a small valid input (a 16-frame synthetic scene, COCO-17 or BODY_25) and,
mostly, one corruption of it: truncated or garbled text, wrong types, wrong keypoint counts,
NaN and infinite values, absurd confidences, each format's own markers of a missing joint
(EasyMocap's ``[0, 0, -1]``, Pose2Sim's NaN joints, SimCC scores <= 0 and above 1), people
without keypoints, frames with 0, 1, 2 or 5 people,
empty folders, mixed formats in one folder, huge coordinates and frame ids, intrinsics with a
singular K or a negative focal length, image sizes that disagree with the keypoints. Then:

* the reader (``read_keypoints`` / ``load_intrinsics``) returns, or raises an ``InputError``
  whose one-line message names the file, and the frame and field where the corruption is;
* ``mirrorgraph calibrate --no-refine`` exits 0 with a well-formed calibration JSON (near
  the ground truth where the input is valid), or exits 2 with exactly one line
  ``error: ...`` on stderr (the reader's own message when the reader refused the input);
  never a traceback, an internal error or a Python warning; the output file is absent after
  a failed run, or byte for byte what it was before, and no temporary file is left beside it.

Planned cases: see ``EXAMPLES`` (examples per test); ``TOTAL_EXAMPLES`` is their sum.
On CI (``CI`` set) the examples are derandomised, so every run checks the same cases;
elsewhere each run explores new ones.

This module holds the base scenes, the generated cases, the checks of that contract and
the mutations of the JSON formats, which several of the test modules draw from.
"""

from __future__ import annotations

import copy
import json
import math
import os
import re
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from mirrorgraph.cli import main
from mirrorgraph.cli.args import error_message
from mirrorgraph.errors import MirrorgraphError
from mirrorgraph.io import read_keypoints
from mirrorgraph.metrics import normal_angle_deg
from mirrorgraph.synth import make_scene, write_scene

#: Generated examples per test. The suite runs TOTAL_EXAMPLES cases (about a minute on a
#: 2-core machine): 400 + 250 + 250 + 350 + 350 + 120 + 150 + 150 + 60 + 20 + 20
#: + 8 + 80 + 80 + 100 + 80 = 2468.
EXAMPLES = {
    "mmpose": 400,
    "openpose": 250,
    "easymocap": 250,
    "npz": 350,
    "intrinsics": 350,
    "folders": 120,
    "people": 150,
    "cli_options": 150,
    "refine": 60,
    "image_size_small": 20,
    "image_size_impossible": 20,
    "joints3d_without_refine": 8,
    "usage_errors": 80,
    "output_paths": 80,
    "calibration_json": 100,
    "joints_npz": 80,
}
TOTAL_EXAMPLES = sum(EXAMPLES.values())

FRAMES = 16
MAX_NORMAL_ERROR_DEG = 3.0   # 16 frames, 4 px noise, no refinement: typically < 1 deg


#: ``MIRRORGRAPH_FUZZ_SCALE=20 pytest tests -k fuzz`` runs 20 times the examples (a
#: longer bug hunt); the default runs EXAMPLES as planned.
SCALE = float(os.environ.get("MIRRORGRAPH_FUZZ_SCALE", "1"))


def fuzz_settings(name: str, **kw):
    """Hypothesis settings of the suite's test ``name`` (a key of :data:`EXAMPLES`)."""
    return settings(max_examples=max(1, round(EXAMPLES[name] * SCALE)), deadline=None,
                    derandomize=bool(os.environ.get("CI")),
                    suppress_health_check=[HealthCheck.function_scoped_fixture,
                                           HealthCheck.too_slow, HealthCheck.data_too_large],
                    **kw)


# =============================================================================== base data
class Base:
    """One valid scene in every input format, as plain data (plain class: short repr).

    ``docs``: format -> list of frame documents (MMPose entries, or one per file);
    ``names``: format -> file names of a folder format (``None`` for MMPose);
    ``ids``: frame ids; ``npz``: the paired arrays; ``camera``: ``camera.json``.
    """

    def __init__(self, **kw) -> None:
        self.__dict__.update(kw)

    def __repr__(self) -> str:
        return f"<base {self.name}>"


def _make_base(seed: int, skeleton: str) -> Base:
    scene = make_scene(frames=FRAMES, seed=seed, skeleton=skeleton)
    with tempfile.TemporaryDirectory() as d:
        paths = write_scene(scene, d)
        mm = json.loads(paths["mmpose"].read_text())
        docs, names = {"mmpose": mm}, {"mmpose": None}
        for fmt in ("openpose", "easymocap"):
            files = sorted(paths[fmt].iterdir())
            names[fmt] = [f.name for f in files]
            docs[fmt] = [json.loads(f.read_text()) for f in files]
        with np.load(paths["npz"]) as z:
            npz = {k: z[k] for k in z.files}
        camera = json.loads(paths["camera"].read_text())
    assert all(len(e["instances"]) == 2 for e in mm)   # person and reflection everywhere
    return Base(name=f"{skeleton}/seed {seed}", skeleton=skeleton,
                J=scene.skeleton.num_joints, normal=np.asarray(scene.normal, float),
                K=np.asarray(scene.K).tolist(), image_size=tuple(scene.image_size),
                docs=docs, names=names, ids=[int(e["frame_id"]) for e in mm], npz=npz,
                camera=camera)


BASES = (_make_base(3, "COCO_17"), _make_base(8, "BODY_25"))
KNOWN_COUNTS = (17, 18, 25, 26)

#: Input names chosen to be unlike any word of an error message.
MM, OP, EM, NPZ, CAM = "mm_input.json", "op_input", "em_input", "pairs_input.npz", "cam_input"


# =============================================================================== cases
class Case:
    """A generated input: files to write and what must happen to them.

    ``read``: what the reader must do, ``"ok"``, ``"error"`` or ``"either"``;
    ``names``: regular expressions every error message must match (file, frame, field);
    ``close``: the input is valid: the CLI must succeed and be near the ground truth.
    (A plain class: hypothesis prints its short repr, not the file contents.)
    """

    def __init__(self, what: str, base: Base, files: dict, input: str, read: str = "either",
                 names: tuple = (), close: bool = False) -> None:
        self.what, self.base, self.files, self.input = what, base, files, input
        self.read, self.names, self.close = read, tuple(names), close

    def __repr__(self) -> str:
        return (f"Case({self.what!r}, base={self.base.name!r}, read={self.read!r}, "
                f"names={self.names!r}, close={self.close})")


def lit(text: str) -> str:
    return re.escape(text)


def frame_re(t: int) -> str:
    return rf"\bframe {t}\b"


def field_re(name: str) -> str:
    return re.escape(f"field '{name}'")


def at_re(p: int, j: int) -> str:
    return rf"\bperson {p}, joint {j}\b"


def materialise(case: Case, root: Path) -> Path:
    for rel, data in case.files.items():
        path = root / rel
        if data is None:
            path.mkdir(parents=True, exist_ok=True)
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
    return root / case.input


def dumps(obj) -> bytes:
    return json.dumps(obj).encode()   # NaN and Infinity written as JSON's common extension


# =============================================================================== checks
def check_reader(read, case_names, expect: str) -> object | None:
    """Call ``read()``: a result, or an InputError as ``expect`` allows; returns the error."""
    try:
        read()
    except MirrorgraphError as e:
        msg = str(e)
        assert expect != "ok", f"refused a valid input: {msg}"
        assert "\n" not in msg, msg
        for pattern in case_names:
            assert re.search(pattern, msg), f"{pattern!r} not in {msg!r}"
        return e
    assert expect != "error", "accepted a corrupted input"
    return None


def check_calibration(path: Path, truth: np.ndarray | None) -> dict:
    """A well-formed calibration JSON (and near ``truth`` if given)."""
    cal = json.loads(path.read_text())
    n = np.asarray(cal["mirror"]["normal"], float)
    assert n.shape == (3,) and np.isfinite(n).all() and abs(np.linalg.norm(n) - 1) < 1e-9
    R = np.asarray(cal["virtual_camera"]["R"], float)
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-9) and np.isclose(np.linalg.det(R), 1.0)
    F = np.asarray(cal["fundamental_matrix"], float)
    assert np.isfinite(F).all() and np.allclose(F, -F.T)
    assert cal["scale"] in ("unknown", "subject_height")
    assert 0 < cal["pairs_used"] <= cal["pairs_total"] and 0 < cal["inlier_ratio"] <= 1
    assert cal["frames_read"] >= cal["frames_paired"] >= cal["frames_used"] > 0
    assert isinstance(cal["warnings"], list)
    if truth is not None:
        err = normal_angle_deg(n, truth)
        assert err < MAX_NORMAL_ERROR_DEG, f"normal {err:.2f} deg from the truth"
    return cal


def check_refined(cal: dict, joints3d: Path, height: float | None) -> None:
    """A refined calibration and its 3D joints."""
    assert cal["refined"] is True
    unc = cal["uncertainty"]
    assert np.isfinite(unc["rotation_std_deg"]) and unc["rotation_std_deg"] >= 0
    cov = np.asarray(unc["normal_cov"], float)
    assert cov.shape == (3, 3) and np.isfinite(cov).all() and np.allclose(cov, cov.T)
    if height is not None:
        assert cal["scale"] == "subject_height" and cal["mirror"]["distance"] > 0
    with np.load(joints3d) as z:
        X, valid = z["joints3d"], z["valid"]
        assert X.shape[:2] == valid.shape and X.shape[2] == 3
        assert np.isfinite(X[valid]).all()


def not_verbose(err: str) -> str:
    """The lines of stderr that are not the free-text report of ``--verbose``."""
    keep = ("error: ", "warning: ", "internal error", "Traceback")
    return "".join(ln for ln in err.splitlines(keepends=True) if ln.startswith(keep))


def run_cli(args: list[str], out: Path, capfd, *, prior: bytes | None):
    """Run ``main(args)`` and check the contract; returns ``(code, stderr)``.

    stderr is captured at the file-descriptor level, so that what C++ libraries print
    counts too; with ``--verbose`` only its ``error:``, ``warning:``, ``internal error``
    and ``Traceback`` lines are checked (the verbose report is free text).
    """
    if prior is not None:
        out.write_bytes(prior)
    before = set(os.listdir(out.parent))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code = main(args)
    cap = capfd.readouterr()
    if "--verbose" in args:
        cap = type(cap)(cap.out, not_verbose(cap.err))
    # a Python warning would be one more line on the user's stderr
    assert not caught, f"Python warning reached the user: {caught[0].message!r}"
    assert "Traceback" not in cap.err and "Traceback" not in cap.out
    assert "internal error" not in cap.err, cap.err
    assert "Python warning" not in cap.err, cap.err      # the CLI's line for NumPy's warnings
    left = {n for n in set(os.listdir(out.parent)) - before if n.startswith(".")}
    assert not left, f"temporary files left behind: {left}"
    if code == 0:
        assert all(line.startswith("warning: ") for line in cap.err.splitlines()), cap.err
        assert out.is_file()
    else:
        assert code == 2, (code, cap.err)
        assert cap.err.startswith("error: ") and cap.err.count("\n") == 1, cap.err
        if prior is None:
            assert not out.exists(), "a failed run wrote the output"
        else:
            assert out.read_bytes() == prior, "a failed run clobbered the existing output"
    return code, cap.err


def check_keypoint_case(case: Case, capfd, prior: bytes | None, *, refine: bool = False,
                        height: float | None = None) -> None:
    """The reader, then the CLI, on a keypoint input (with the base's valid camera).

    ``refine``: run the factor graph too, writing ``--joints3d`` (and with ``height``,
    ``--subject-height``); else ``--no-refine``.
    """
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        path = materialise(case, root)
        error = check_reader(lambda: read_keypoints(path), case.names, case.read)
        cam = root / f"{CAM}.json"
        cam.write_text(json.dumps(case.base.camera))
        out = root / "out" / "calibration.json"
        out.parent.mkdir()
        joints3d = out.parent / "joints3d.npz"
        extra = ["--no-refine"] if not refine else ["--joints3d", str(joints3d)] + (
            [] if height is None else ["--subject-height", repr(height)])
        code, err = run_cli(["calibrate", str(path), "--intrinsics", str(cam), "--out",
                             str(out), *extra], out, capfd, prior=prior)
        assert joints3d.is_file() == (refine and code == 0)
        if error is not None:
            # the reader's error, its arguments said as the CLI's flags
            assert code == 2 and err == f"error: {error_message(error)}\n", (err, str(error))
        elif code == 0:
            cal = check_calibration(out, case.base.normal if case.close else None)
            if refine:
                check_refined(cal, joints3d, height)
        else:
            assert not case.close, f"valid input refused: {err}"
            # the pipeline's refusals (too few pairs, degenerate lines) name the input
            assert Path(case.input).name in err, err


prior_outputs = st.sampled_from([None, None, b"precious calibration\n"])


# =============================================================================== JSON formats
@dataclass(frozen=True)
class Fmt:
    """One JSON format, and what its tools write as confidences (see the readers'
    docstrings): ``max_conf`` is the largest score read (clipped to 1), larger ones are
    refused; a negative score is a missing joint in all three."""

    name: str
    persons: str        # key of a frame's list of people
    kp: str             # key of a person's keypoints
    folder: bool
    max_conf: float = math.inf

    def conf_ok(self, v: float) -> bool:
        """Whether the reader must accept confidence ``v`` (finite)."""
        return v <= self.max_conf

    def kp_field(self, p: int, c: int = 0) -> str:
        if self.name == "mmpose" and c == 2:
            return f"instances[{p}].keypoint_scores"
        return f"{self.persons}[{p}].{self.kp}"


MMPOSE = Fmt("mmpose", "instances", "keypoints", False)
OPENPOSE = Fmt("openpose", "people", "pose_keypoints_2d", True)
EASYMOCAP = Fmt("easymocap", "annots", "keypoints", True, max_conf=1.5)
INPUT = {"mmpose": MM, "openpose": OP, "easymocap": EM}


def get_value(fmt: Fmt, person: dict, j: int, c: int):
    if fmt.name == "openpose":
        return person[fmt.kp][3 * j + c]
    if fmt.name == "mmpose" and c == 2:
        return person.get("keypoint_scores", [1.0] * len(person["keypoints"]))[j]
    return person[fmt.kp][j][c]


def set_value(fmt: Fmt, person: dict, j: int, c: int, value) -> None:
    if fmt.name == "openpose":
        person[fmt.kp][3 * j + c] = value
    elif fmt.name == "mmpose" and c == 2:
        person["keypoint_scores"][j] = value
    else:
        person[fmt.kp][j][c] = value


def resize(fmt: Fmt, person: dict, n: int, what: str = "both") -> None:
    """Give a person ``n`` keypoints (repeating the last one), or only ``n`` scores."""
    if fmt.name == "openpose":
        flat = person[fmt.kp]
        person[fmt.kp] = (flat + flat[-3:] * n)[:3 * n]
        return
    if what in ("keypoints", "both"):
        kp = person[fmt.kp]
        person[fmt.kp] = (kp + [list(kp[-1])] * n)[:n]
    if fmt.name == "mmpose" and what in ("scores", "both"):
        s = person["keypoint_scores"]
        person["keypoint_scores"] = (s + [s[-1]] * n)[:n]


class Frames:
    """The frame documents of one JSON-format input, with helpers to build a Case."""

    def __init__(self, fmt: Fmt, base: Base) -> None:
        self.fmt, self.base = fmt, base
        self.docs = copy.deepcopy(base.docs[fmt.name])
        self.ids = list(base.ids)
        self.file_names = list(base.names[fmt.name] or [])
        self.extra: dict = {}          # further files, relative to the input folder

    def persons(self, i: int) -> list:
        return self.docs[i][self.fmt.persons]

    def where(self, i: int) -> tuple:
        """Patterns naming file and frame of frame ``i``."""
        file = self.file_names[i] if self.fmt.folder else MM
        return lit(file), frame_re(self.ids[i])

    def case(self, what: str, read: str, names: tuple = (), close: bool = False,
             texts: dict | None = None, drop_all: bool = False) -> Case:
        inp = INPUT[self.fmt.name]
        if not self.fmt.folder:
            files = {inp: (texts or {}).get(0, dumps(self.docs))}
        else:
            files = {inp: None}
            if not drop_all:
                for i, (name, doc) in enumerate(zip(self.file_names, self.docs)):
                    files[f"{inp}/{name}"] = (texts or {}).get(i, dumps(doc))
            files.update({f"{inp}/{k}": v for k, v in self.extra.items()})
        return Case(f"{self.fmt.name}: {what}", self.base, files, inp, read, names, close)


NONFINITE = (math.nan, math.inf, -math.inf)
WRONG_TYPES = ("1.5", None, True, False, [], {}, [1.0, 2.0], "NaN")
NOT_OBJECTS = ("person", 3, None, [], [1.0, 2.0], True)
NOT_LISTS = ("people", 3, None, {}, True, 2.5)
GARBAGE_CHARS = ('{', '}', '[', ']', ',', ':', '"', '\\', 'x', '0', '-', ' ', '\x00', '\u00e9')


@st.composite
def keypoint_value_mutation(draw, fr: Frames) -> Case:
    """One keypoint value replaced: non-finite, wrong type, confidence or coordinate."""
    fmt, J = fr.fmt, fr.base.J
    i = draw(st.integers(0, FRAMES - 1))
    p = draw(st.integers(0, len(fr.persons(i)) - 1))
    j = draw(st.integers(0, J - 1))
    c = draw(st.integers(0, 2))
    person = fr.persons(i)[p]
    kind = draw(st.sampled_from(["nonfinite", "type", "number", "number", "marker"]))
    file_re, t_re = fr.where(i)
    if kind == "marker":
        # the format's own "missing" marker on one joint (or every joint of one person,
        # or an empty keypoint list): read as missing, the calibration unharmed
        marker = {"mmpose": [0.0, 0.0, -0.3], "easymocap": [0.0, 0.0, -1.0],
                  "openpose": draw(st.sampled_from([[0.0, 0.0, -1.0], [math.nan] * 3]))}
        whole = draw(st.sampled_from(["joint", "joint", "person", "no_keypoints"]))
        if whole == "no_keypoints" and fmt.name != "mmpose":
            if fmt.name == "openpose":
                person[fmt.kp] = []
            else:
                del person[fmt.kp]
            return fr.case(f"frame #{i} person {p} without keypoints", "ok", close=True)
        for jj in (range(J) if whole != "joint" else [j]):
            for cc in range(3):
                set_value(fmt, person, jj, cc, marker[fmt.name][cc])
        return fr.case(f"frame #{i} person {p} {whole} {j} = {marker[fmt.name]}", "ok",
                       close=True)
    if kind == "nonfinite":
        v = draw(st.sampled_from(NONFINITE))
        names = (file_re, t_re, field_re(fmt.persons), at_re(p, j))
        read = "error"
    elif kind == "type":
        v = draw(st.sampled_from(WRONG_TYPES))
        names = (file_re, t_re, field_re(fmt.kp_field(p, c)))
        read = "error"
    elif c == 2:
        # negative: missing in every JSON format; above 1: clipped up to the format's max
        v = draw(st.one_of(st.floats(-1e300, -1e-9), st.floats(1e-6, 1.0), st.just(0.0),
                           st.floats(1.0, 1.5), st.floats(1.5001, 1e300)))
        bad = not fmt.conf_ok(v)
        names = (file_re, t_re, field_re(fmt.persons), at_re(p, j)) if bad else ()
        read = "error" if bad else "ok"
    else:
        v = draw(st.one_of(st.floats(-1e6, 1e6), st.integers(-5000, 5000),
                           st.floats(1.0000001e6, 1e300), st.floats(-1e300, -1.0000001e6)))
        conf = get_value(fmt, person, j, 2)
        far = abs(v) > 1e6 and conf > 0
        names = (file_re, t_re, field_re(fmt.persons), at_re(p, j)) if far else ()
        read = "error" if far else "ok"
    set_value(fmt, person, j, c, v)
    return fr.case(f"frame #{i} person {p} joint {j} component {c} = {v!r}", read, names)


@st.composite
def structure_mutation(draw, fr: Frames) -> Case:
    """Counts, types and keys of people and frames."""
    fmt, J = fr.fmt, fr.base.J
    i = draw(st.integers(0, FRAMES - 1))
    p = draw(st.integers(0, len(fr.persons(i)) - 1))
    file_re, t_re = fr.where(i)
    kinds = ["count", "person_type", "persons_type", "delete_kp", "delete_persons"]
    if fmt.name == "mmpose":
        kinds += ["scores_count", "frame_type", "frame_id", "delete_frame_id", "delete_scores"]
    kind = draw(st.sampled_from(kinds))
    if kind == "count":
        n = draw(st.integers(0, 30).filter(lambda n: n != J))
        resize(fmt, fr.persons(i)[p], n, "both")
        if n == 0 and fmt.name == "openpose":    # OpenPose's body detector off: left out
            return fr.case(f"frame #{i} person {p} has no keypoints", "ok")
        first = i == 0 and p == 0
        if first and n in KNOWN_COUNTS:   # the first person fixes the skeleton
            names = (lit(fmt.kp),)
        else:
            names = (file_re, t_re, field_re(fmt.kp_field(p)))
        return fr.case(f"frame #{i} person {p} has {n} keypoints", "error", names)
    if kind == "scores_count":
        n = draw(st.integers(0, 30).filter(lambda n: n != J))
        resize(fmt, fr.persons(i)[p], n, "scores")
        return fr.case(f"frame #{i} person {p} has {n} scores", "error",
                       (file_re, t_re, field_re(fmt.kp_field(p, 2))))
    if kind == "person_type":
        v = draw(st.sampled_from(NOT_OBJECTS))
        fr.persons(i)[p] = v
        return fr.case(f"frame #{i} person {p} is {v!r}", "error",
                       (file_re, t_re, field_re(f"{fmt.persons}[{p}]")))
    if kind == "persons_type":
        v = draw(st.sampled_from(NOT_LISTS))
        fr.docs[i][fmt.persons] = v
        return fr.case(f"frame #{i} {fmt.persons} = {v!r}", "error",
                       (file_re, t_re, field_re(fmt.persons)))
    if kind == "delete_kp":
        del fr.persons(i)[p][fmt.kp]
        if fmt.name == "easymocap":   # a bounding box only (EasyMocap's YOLO stage)
            return fr.case(f"frame #{i} person {p} without {fmt.kp}", "ok")
        return fr.case(f"frame #{i} person {p} without {fmt.kp}", "error",
                       (file_re, t_re, field_re(fmt.kp_field(p))))
    if kind == "delete_persons":
        del fr.docs[i][fmt.persons]
        if fmt.folder:   # then the file is of no known format
            return fr.case(f"frame #{i} without {fmt.persons}", "error", (file_re,))
        return fr.case(f"frame #{i} without {fmt.persons}", "error",
                       (file_re, t_re, field_re(fmt.persons)))
    if kind == "frame_type":
        v = draw(st.sampled_from(NOT_OBJECTS))
        fr.docs[i] = v
        # a first entry that is no object makes the file no MMPose file at all
        return fr.case(f"frame entry {i} is {v!r}", "error",
                       (file_re, lit(f"frame entry {i}") if i else lit("not MMPose")))
    if kind == "delete_frame_id":
        del fr.docs[i]["frame_id"]
        return fr.case(f"frame entry {i} without frame_id", "error",
                       (file_re, lit(f"frame entry {i}"), field_re("frame_id")))
    if kind == "delete_scores":
        for entry in fr.docs:
            for inst in entry["instances"]:
                inst.pop("keypoint_scores", None)
        return fr.case("no keypoint_scores (confidence 1)", "ok", close=True)
    # frame_id
    sub = draw(st.sampled_from(["type", "duplicate", "huge", "negative"]))
    if sub == "type":
        v = draw(st.sampled_from(["3", 3.0, None, True, [3], {}]))
        fr.docs[i]["frame_id"] = v
        return fr.case(f"frame entry {i} frame_id = {v!r}", "error",
                       (file_re, lit(f"frame entry {i}"), field_re("frame_id")))
    if sub == "duplicate":
        k = draw(st.integers(0, FRAMES - 1).filter(lambda k: k != i))
        fr.docs[i]["frame_id"] = fr.ids[k]
        return fr.case(f"frame entry {i} repeats frame id {fr.ids[k]}", "error",
                       (file_re, frame_re(fr.ids[k]), lit("duplicate")))
    if sub == "huge":
        v = draw(st.one_of(st.integers(2**63, 10**40), st.integers(-10**40, -2**63 - 1)))
        fr.docs[i]["frame_id"] = v
        return fr.case(f"frame entry {i} frame_id = {v}", "error", (file_re, frame_re(v)))
    v = draw(st.integers(-1000, -1))
    fr.docs[i]["frame_id"] = v
    return fr.case(f"frame entry {i} frame_id = {v}", "ok", close=True)


@st.composite
def text_mutation(draw, fr: Frames) -> Case:
    """The bytes of a file: truncated, one character garbled, not UTF-8, BOM, empty."""
    i = draw(st.integers(0, FRAMES - 1)) if fr.fmt.folder else 0
    data = dumps(fr.docs[i] if fr.fmt.folder else fr.docs)
    file = fr.file_names[i] if fr.fmt.folder else MM
    kind = draw(st.sampled_from(["truncate", "garble", "bytes"]))
    if kind == "truncate":
        k = draw(st.integers(0, len(data) - 1))
        return fr.case(f"file #{i} cut to {k} bytes", "error", (lit(file),),
                       texts={i: data[:k]})
    if kind == "garble":
        k = draw(st.integers(0, len(data) - 1))
        ch = draw(st.sampled_from(GARBAGE_CHARS)).encode()
        return fr.case(f"file #{i} byte {k} -> {ch!r}", "either", (lit(file),),
                       texts={i: data[:k] + ch + data[k + 1:]})
    prefix = draw(st.sampled_from([b"\xff\xfe", b"\xef\xbb\xbf", b"\x80", b"", b"\x00"]))
    whole = prefix == b"" or draw(st.booleans())
    text = prefix if whole else prefix + data
    return fr.case(f"file #{i} = {prefix!r} + {'nothing' if whole else 'the JSON'}",
                   "error", (lit(file),), texts={i: text})


@st.composite
def top_level_mutation(draw, fr: Frames) -> Case:
    """The whole MMPose document replaced, or wrapped as MMPose's demo scripts do."""
    kind = draw(st.sampled_from(["replace", "wrap", "extra_keys"]))
    if kind == "wrap":
        fr.docs = {"meta_info": {"dataset_name": "coco"}, "instance_info": fr.docs}
        return fr.case("wrapped in instance_info", "ok", close=True)
    if kind == "extra_keys":
        for entry in fr.docs:
            entry["unknown"] = {"a": [1, 2]}
            for inst in entry["instances"]:
                inst["track_id"] = None
        return fr.case("unknown keys added", "ok", close=True)
    v = draw(st.sampled_from([[], {}, 42, "text", None, [1, 2], [[]], {"instance_info": 5},
                              {"instance_info": None}, [{"instances": []}]]))
    fr.docs = v
    return fr.case(f"document = {v!r}", "error", (lit(MM),))


@st.composite
def json_case(draw, fmt: Fmt) -> Case:
    fr = Frames(fmt, draw(st.sampled_from(BASES)))
    kinds = [keypoint_value_mutation, keypoint_value_mutation, structure_mutation,
             text_mutation]
    if fmt.name == "mmpose":
        kinds.append(top_level_mutation)
    if draw(st.integers(0, 9)) == 0:
        return fr.case("unchanged", "ok", close=True)
    return draw(draw(st.sampled_from(kinds))(fr))


def write_mmpose_and_camera(root: Path, base, camera: dict | None = None) -> tuple[Path, Path]:
    """Write a base scene's MMPose predictions and camera JSON into ``root``."""
    kp = root / MM
    kp.write_bytes(dumps(base.docs["mmpose"]))
    cam = root / f"{CAM}.json"
    cam.write_text(json.dumps(base.camera if camera is None else camera))
    return kp, cam
