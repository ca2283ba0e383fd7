"""Property-based bad-input suite (hypothesis) over every reader and ``mirrorgraph calibrate``.

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
"""

from __future__ import annotations

import copy
import io
import json
import math
import os
import re
import tempfile
import warnings
import zipfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from mirrorgraph.cli import main
from mirrorgraph.errors import MirrorgraphError
from mirrorgraph.intrinsics import MAX_K_ENTRY, load_intrinsics
from mirrorgraph.io import read_keypoints
from mirrorgraph.metrics import normal_angle_deg
from mirrorgraph.skeleton_guess import MIN_DETECTIONS
from mirrorgraph.synth import make_scene, write_scene

from mirrorgraph.joint_sets import MIN_JOINTS   # the fewest joints --joints may name

#: Generated examples per test. The suite runs TOTAL_EXAMPLES cases (well under a minute
#: on a 2-core machine): 400 + 250 + 250 + 350 + 350 + 120 + 150 + 150 + 60 + 20 + 20 + 8 + 80 = 2208.
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
}
TOTAL_EXAMPLES = sum(EXAMPLES.values())

FRAMES = 16
MAX_NORMAL_ERROR_DEG = 3.0   # 16 frames, 4 px noise, no refinement: typically < 1 deg


#: ``MIRRORGRAPH_FUZZ_SCALE=20 pytest tests/test_fuzz.py`` runs 20 times the examples (a
#: longer bug hunt); the default runs EXAMPLES as planned.
SCALE = float(os.environ.get("MIRRORGRAPH_FUZZ_SCALE", "1"))


def fuzz_settings(name: str, **kw):
    """Hypothesis settings of one test of this suite."""
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
            assert code == 2 and err == f"error: {error}\n", (err, str(error))
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
    # image-size tests below); K comes from the camera file, so the result stands
    return fr.case(f"every file says {w}x{h}", "ok", close=True)


@fuzz_settings("openpose")
@given(case=folder_json_case(OPENPOSE), prior=prior_outputs)
def test_openpose_folder(case, prior, capfd):
    check_keypoint_case(case, capfd, prior)


@fuzz_settings("easymocap")
@given(case=folder_json_case(EASYMOCAP), prior=prior_outputs)
def test_easymocap_folder(case, prior, capfd):
    check_keypoint_case(case, capfd, prior)


# =============================================================================== folders
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


# =============================================================================== people
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


# =============================================================================== npz
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


# =============================================================================== intrinsics
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
            # too small for the keypoints is an error: test_image_size_far_smaller_...)
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
            assert code == 2 and err == f"error: {error}\n", (err, str(error))
        elif code == 0:
            check_calibration(out, case.base.normal if case.close else None)
        else:
            assert not case.close, f"valid intrinsics refused: {err}"


# =============================================================================== CLI options
@st.composite
def cli_options(draw):
    """Options of ``calibrate`` that argparse accepts, some of them wrong for the data.

    Returns ``(base, camera, out, args, wrong)``: ``wrong`` holds a pattern for each
    option that is wrong for the data; a refusal must match one of them (the first wrong
    option met is refused).
    """
    from mirrorgraph.skeletons import skeleton_by_name
    base = draw(st.sampled_from(BASES))
    args, wrong = [], []
    skel = skeleton_by_name(base.skeleton)
    sk = draw(st.sampled_from([None, None, base.skeleton, "COCO_17", "BODY_25", "COCO_18",
                               "coco17", "HALPE_26"]))
    if sk is not None:
        args += ["--skeleton", sk]
        if sk != base.skeleton:
            wrong.append(lit(MM))
    joints = draw(st.sampled_from([None, None, "subset", "unknown", "empty"]))
    if joints == "subset":
        chosen = draw(st.lists(st.sampled_from(list(skel.joints)), min_size=1, max_size=8,
                               unique=True))
        args += ["--joints", ",".join(chosen)]
        if len(chosen) < MIN_JOINTS:     # too few joints to name: refused as an option
            wrong.append(field_re("joints") + ".*at least")
    elif joints == "unknown":
        args += ["--joints", "left_wrist,tail"]
        wrong.append(field_re("joints") + ".*tail")
    elif joints == "empty":
        args += ["--joints", ""]
    if draw(st.booleans()):
        args += ["--min-confidence", repr(draw(st.floats(0.0, 1.0)))]
    if draw(st.booleans()):
        args += ["--threshold", repr(draw(st.floats(1e-3, 1e4)))]
    args += ["--estimator", draw(st.sampled_from(["reflective", "eightpoint", "reflective8"]))]
    args += [f"--seed={draw(st.integers(0, 2**40))}"]
    camera = draw(st.sampled_from(["file", "file", "size", "none"]))
    if camera == "size":
        w, h = draw(st.integers(640, 4000)), draw(st.integers(480, 3000))
        args += ["--image-size", f"{w}x{h}"]
    if camera != "file" and draw(st.booleans()):
        fov = draw(st.floats(1e-3, 1000.0))
        args += ["--fov", repr(fov)]
        if fov >= 180:
            wrong.append(field_re("fov_deg"))
    if camera == "none":
        wrong.append(lit(MM) + ".*image size")
    args += [draw(st.sampled_from(["--quiet", "--verbose", "--debug"]))]
    out = draw(st.sampled_from(["fresh", "fresh", "existing", "folder", "no_parent",
                                "parent_is_file"]))
    return base, camera, out, args, tuple(wrong)


def write_mmpose_and_camera(root: Path, base, camera: dict | None = None) -> tuple[Path, Path]:
    """Write a base scene's MMPose predictions and camera JSON into ``root``."""
    kp = root / MM
    kp.write_bytes(dumps(base.docs["mmpose"]))
    cam = root / f"{CAM}.json"
    cam.write_text(json.dumps(base.camera if camera is None else camera))
    return kp, cam


@fuzz_settings("cli_options")
@given(opts=cli_options())
def test_cli_options(opts, capfd):
    base, camera, out_kind, args, wrong = opts
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        kp, cam = write_mmpose_and_camera(root, base)
        out, prior, out_names = root / "out" / "calibration.json", None, ()
        out.parent.mkdir()
        if out_kind == "existing":
            prior = b"precious"
        elif out_kind == "folder":
            out.mkdir()
            out_names = (lit("--out"),)
        elif out_kind == "no_parent":
            out = root / "out" / "no_such_folder" / "calibration.json"
            out_names = (lit("no_such_folder"),)
        elif out_kind == "parent_is_file":
            (root / "out" / "plain_file").write_text("x")
            out = root / "out" / "plain_file" / "calibration.json"
            out_names = (lit("plain_file"),)
        argv = ["calibrate", str(kp), "--out", str(out), "--no-refine", *args]
        if camera == "file":
            argv += ["--intrinsics", str(cam)]
        if out_kind in ("folder", "no_parent", "parent_is_file"):
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                code = main(argv)
            err = capfd.readouterr().err
            if "--verbose" in args:
                err = not_verbose(err)
            assert not caught, caught[0].message
            assert code == 2 and err.startswith("error: ") and err.count("\n") == 1, err
            assert "Traceback" not in err
            assert out.is_dir() if out_kind == "folder" else not out.exists()
            if out_kind == "folder":
                assert not any(out.iterdir())
            # the output is at fault, or (before the output is written) an option or data
            # that determine no mirror
            patterns = out_names + ((*wrong, lit(MM)) if out_kind != "folder" else ())
            assert any(re.search(p_, err) for p_ in patterns), err
            return
        code, err = run_cli(argv, out, capfd, prior=prior)
        if wrong:
            assert code == 2, "accepted options that are wrong for the data"
            assert any(re.search(p_, err) for p_ in wrong), (wrong, err)
        if code == 2:
            # every refusal names the input, the camera file or the option at fault
            assert MM in err or CAM in err or "field '" in err, err
        else:
            check_calibration(out, None)


# =============================================================================== image size
# Image sizes that disagree with the keypoints (pipeline.check_image_size):
# * intrinsics whose image size cannot hold most of the keypoints (more than half of the
#   detected joints outside the image enlarged by 10% on each side) are an InputError
#   naming that size and the field image_size, as an impossible --image-size is: the
#   keypoints and K are not in the same pixels (a resized video, the wrong camera file),
#   and the normal found with that K would be wrong;
# * without intrinsics, an image size that cannot hold most keypoints is an InputError
#   naming the size and the field image_size: the guessed K comes from that size alone.
# (An EasyMocap or npz image size unlike the camera file's is no error either: see the
# "every file says WxH" and "other size" cases above.)
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


# =============================================================================== regressions
# Bugs this suite found in the CLI and pipeline.py, fixed since; they stay as tests.
@fuzz_settings("joints3d_without_refine", phases=[Phase.explicit, Phase.generate])
@given(base=st.sampled_from(BASES), prior=st.sampled_from([None, b"precious"]))
def test_joints3d_without_refine_leaves_outputs_alone(base, prior, capfd):
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        kp, cam = write_mmpose_and_camera(root, base)
        out = root / "calibration.json"
        code, err = run_cli(["calibrate", str(kp), "--intrinsics", str(cam), "--out", str(out),
                             "--no-refine", "--joints3d", str(root / "j.npz")], out, capfd,
                            prior=prior)
        assert code == 2 and "--joints3d" in err


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


BAD_OPTIONS = {
    "--seed": ["-1", "-1099511627776", "x", "1.5", ""],       # a negative seed crashed
    "--fov": ["0", "-1", "nan", "inf", "x"],
    "--min-confidence": ["-0.1", "1.5", "nan", "x"],
    "--threshold": ["0", "-3", "inf", "x"],
    "--image-size": ["12", "0x0", "1920x", "axb", "-5x5"],
    "--estimator": ["magic", ""],
    "--subject-height": ["0", "-1.7", "x"],
}


@fuzz_settings("usage_errors")
@given(option=st.sampled_from(sorted(BAD_OPTIONS) + ["--no-such-option", "no --out"]),
       data=st.data(), prior=prior_outputs)
def test_usage_errors(option, data, prior, capfd):
    """Options argparse refuses: one line naming the option, exit 2, nothing written."""
    base = BASES[0]
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        kp, cam = write_mmpose_and_camera(root, base)
        out = root / "calibration.json"
        argv = ["calibrate", str(kp), "--intrinsics", str(cam), "--no-refine"]
        if option == "no --out":
            named = "--out"
        else:
            argv += ["--out", str(out)]
            if option == "--no-such-option":
                argv.append(option)
            else:
                argv.append(f"{option}={data.draw(st.sampled_from(BAD_OPTIONS[option]))}")
            named = option
        code, err = run_cli(argv, out, capfd, prior=prior)
        assert code == 2 and named in err, err


def test_total_examples_is_recorded():
    """The number of generated cases stated in the module docstring stays true."""
    assert TOTAL_EXAMPLES == sum(EXAMPLES.values()) == 2208
