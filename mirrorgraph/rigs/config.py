"""The rig description: a TOML file naming the cameras, their inputs and the mirrors.

Form (paths are relative to the rig file)::

    subject_height = 1.72          # optional, metres; gives the scale
    joints = "auto"                # optional: "auto" (default), "limbs", "all", or names
    clock_drift = false            # optional: estimate each camera's clock rate too
    [[cameras]]
    name = "cam01"
    keypoints = "pose/cam01_json"  # any input mirrorgraph.io.read_keypoints takes (a video too)
    intrinsics = "Calib.toml"      # JSON, OpenCV YAML, or Pose2Sim / anipose TOML ...
    intrinsics_section = "cam01"   # ... with the section to read where it holds several
    image_size = [1920, 1080]      # without intrinsics, where the keypoints carry no size
                                   # (the focal length is then estimated)
    skeleton = "BODY_25B"          # optional where the keypoint count is ambiguous
    mirrors = ["wall"]             # optional: mirrors this camera sees
    frame_offset = 0               # optional: this camera's frame f shows rig frame f - offset
    fps = 30.0                     # optional: its frame rate, where the keypoints carry none
    [[mirrors]]
    name = "wall"

The first camera defines the world frame and the clock. Cameras at one frame rate
are synchronised frame by frame: frame ``f`` of a camera with ``frame_offset = o`` is
rig frame ``f - o``; ``frame_offset`` counts the first camera's frames, and a camera at
another frame rate (its input's, or ``fps``) is put on the rig's clock by its rate
(:mod:`mirrorgraph.rigs.clocks`).
A camera that sees several mirrors lists them in the order of their normals'
``x`` component in that camera (the mirror on the camera's left first: the
images cannot tell two mirrors apart otherwise); a mirror seen by several
cameras is the same plane in all of them.
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass
from pathlib import Path


from ..anthropometry import height_problem
from ..errors import InputError
from ..intrinsics import check_size
from ..joint_sets import JOINT_SETS
from ..skeletons import skeleton_by_name

__all__ = ["CameraEntry", "RigConfig", "load_rig_config"]

#: The conventional name of a rig file (what ``mirrorgraph synth --rig`` writes and
#: ``mirrorgraph batch`` looks for in a recording's folder).
RIG_FILE = "rig.toml"

#: Frames searched either way of a camera's ``frame_offset`` when its time offset is found
#: from the people (:mod:`mirrorgraph.rigs.clocks`).
OFFSET_WINDOW = 15

@dataclass(frozen=True)
class CameraEntry:
    """One ``[[cameras]]`` table, paths resolved.

    Attributes:
        name: camera name (unique).
        keypoints: path of the keypoint input.
        intrinsics: path of the intrinsics file, or ``None`` (then the focal length is
            estimated from a 60 deg field of view guess, square pixels and the principal
            point at the image centre: :func:`mirrorgraph.pipelines.rig.calibrate_rig`).
        image_size: ``(width, height)`` px of a camera without intrinsics whose keypoints
            do not carry it (OpenPose folders), or ``None``.
        intrinsics_section: the camera's section in a TOML file holding several.
        skeleton: keypoint layout name, or ``None`` (from the keypoint count).
        mirrors: names of the mirrors the camera sees.
        frame_offset: the camera's frame ``f`` is rig frame ``f - frame_offset`` (the
            first camera's frames).
        fps: its frame rate, or ``None`` (its input's); where the input carries another
            (by more than 0.1 %), this one is used, with a warning.
    """

    name: str
    keypoints: Path
    intrinsics: Path | None = None
    intrinsics_section: str | None = None
    skeleton: str | None = None
    mirrors: tuple[str, ...] = ()
    frame_offset: int = 0
    image_size: tuple[int, int] | None = None
    fps: float | None = None


@dataclass(frozen=True)
class RigConfig:
    """A parsed rig file.

    Attributes:
        source: the rig file.
        cameras: the cameras, world frame = the first one's.
        mirrors: mirror names.
        subject_height: metres, or ``None`` (the scale is then the subject's height = 1).
        joints: ``"auto"``, ``"limbs"``, ``"all"`` or joint names (see
            :func:`mirrorgraph.joint_sets.resolve_joints`), or ``None`` (``"auto"``).
        clock_drift: estimate every camera's clock rate against the first camera's
            besides its time offset (long clips; :mod:`mirrorgraph.rigs.clocks`).
    """

    source: Path
    cameras: tuple[CameraEntry, ...]
    mirrors: tuple[str, ...] = ()
    subject_height: float | None = None
    joints: str | tuple[str, ...] | None = None
    clock_drift: bool = False


_CAMERA_KEYS = {"name", "keypoints", "intrinsics", "intrinsics_section", "skeleton", "mirrors",
                "frame_offset", "image_size", "fps"}


def _string(value, source, field_name) -> str:
    if not isinstance(value, str) or not value.strip():
        raise InputError("must be a non-empty string", source=source, field=field_name)
    return value


def load_rig_config(path: str | os.PathLike) -> RigConfig:
    """Read and check a rig file (see the module docstring).

    Raises:
        InputError: naming the file and the field: missing file, malformed TOML,
            no cameras, duplicate names, unknown keys, a mirror not declared, a
            skeleton name not known, a missing keypoint or intrinsics path, a
            non-positive height, a non-integer offset, a non-positive frame rate, a
            clock_drift other than true or false.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("no such file", source=path)
    try:
        with open(path, "rb") as f:
            doc = tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML: {exc}", source=path) from None
    except UnicodeDecodeError:
        raise InputError("not a text file", source=path) from None
    joints, height = _rig_settings(doc, path)
    mirror_names = _mirror_names(doc, path)
    cams_doc = doc.get("cameras")
    if not isinstance(cams_doc, list) or not cams_doc or \
            not all(isinstance(c, dict) for c in cams_doc):
        raise InputError("needs at least one [[cameras]] table", source=path, field="cameras")
    cameras: list[CameraEntry] = []
    for i, c in enumerate(cams_doc):
        cameras.append(_camera_entry(c, f"cameras[{i}]", path, mirror_names, cameras))
    for i, e in enumerate(cameras):
        for other in cameras[:i]:
            try:
                same = os.path.samefile(e.keypoints, other.keypoints)
            except OSError:
                same = False
            if same:
                raise InputError(f"cameras {other.name} and {e.name} read the same keypoints "
                                 f"({e.keypoints}): one camera's observations twice; give "
                                 f"{e.name} its own", source=path, field=f"cameras[{i}].keypoints")
    seen_mirrors = {m for e in cameras for m in e.mirrors}
    unused = [m for m in mirror_names if m not in seen_mirrors]
    if unused:
        raise InputError(f"mirror(s) {', '.join(unused)} seen by no camera (add them to a "
                         "camera's mirrors list)", source=path, field="mirrors")
    if sum(1 + len(e.mirrors) for e in cameras) < 2:
        raise InputError("one camera and no mirror: one view of the person, nothing to "
                         "calibrate (add a camera, or the mirror the camera sees to its "
                         "mirrors list)", source=path, field="cameras")
    skeletons = {e.skeleton for e in cameras if e.skeleton is not None}
    if len(skeletons) > 1:
        raise InputError(f"cameras use different skeletons ({', '.join(sorted(skeletons))}); "
                         "one layout per rig", source=path, field="cameras")
    drift = doc.get("clock_drift", False)
    if not isinstance(drift, bool):
        raise InputError("must be true or false", source=path, field="clock_drift")
    return RigConfig(source=path, cameras=tuple(cameras), mirrors=tuple(mirror_names),
                     subject_height=height, joints=joints, clock_drift=drift)


def _rig_settings(doc: dict, path: Path) -> tuple[str | tuple[str, ...] | None, float | None]:
    """The rig file's top-level keys checked: ``(joints, subject_height)``."""
    unknown = set(doc) - {"subject_height", "joints", "clock_drift", "cameras", "mirrors"}
    if unknown:
        raise InputError(f"unknown key(s) {', '.join(sorted(unknown))}; expected "
                         "subject_height, joints, clock_drift, [[cameras]], [[mirrors]]",
                         source=path)
    joints = doc.get("joints")
    if joints is not None:
        ok = (isinstance(joints, str) and joints in JOINT_SETS) or (
            isinstance(joints, list) and joints and all(isinstance(j, str) for j in joints))
        if not ok:
            raise InputError("must be \"auto\", \"limbs\", \"all\" or a list of joint names",
                             source=path, field="joints")
        joints = joints if isinstance(joints, str) else tuple(joints)

    height = doc.get("subject_height")
    if height is not None:
        if isinstance(height, bool) or not isinstance(height, (int, float)):
            raise InputError("must be a height in metres", source=path, field="subject_height")
        problem = height_problem(float(height))      # the range of --subject-height
        if problem is not None:
            raise InputError(problem, source=path, field="subject_height")
        height = float(height)
    return joints, height


def _mirror_names(doc: dict, path: Path) -> list[str]:
    """The names of the ``[[mirrors]]`` tables, checked."""
    mirrors_doc = doc.get("mirrors", [])
    if not isinstance(mirrors_doc, list) or not all(isinstance(m, dict) for m in mirrors_doc):
        raise InputError("must be an array of tables [[mirrors]]", source=path, field="mirrors")
    mirror_names: list[str] = []
    for i, m in enumerate(mirrors_doc):
        name = _string(m.get("name"), path, f"mirrors[{i}].name")
        if set(m) - {"name"}:
            raise InputError(f"unknown key(s) {', '.join(sorted(set(m) - {'name'}))}",
                             source=path, field=f"mirrors[{i}]")
        if name in mirror_names:
            raise InputError(f"mirror {name!r} declared twice", source=path,
                             field=f"mirrors[{i}].name")
        mirror_names.append(name)
    return mirror_names


def _camera_entry(c: dict, where: str, path: Path, mirror_names: list[str],
                  cameras: list[CameraEntry]) -> CameraEntry:
    """One ``[[cameras]]`` table (``where``: its field name), checked against the mirrors
    declared and the cameras before it."""
    base = path.parent
    extra = set(c) - _CAMERA_KEYS
    if extra:
        raise InputError(f"unknown key(s) {', '.join(sorted(extra))}; known: "
                         f"{', '.join(sorted(_CAMERA_KEYS))}", source=path, field=where)
    name = _string(c.get("name"), path, f"{where}.name")
    if any(e.name == name for e in cameras):
        raise InputError(f"camera {name!r} declared twice", source=path,
                         field=f"{where}.name")
    kp = base / _string(c.get("keypoints"), path, f"{where}.keypoints")
    if not kp.exists():
        raise InputError(f"keypoints {kp} not found", source=path,
                         field=f"{where}.keypoints")
    intr = None
    if c.get("intrinsics") is not None:
        intr = base / _string(c.get("intrinsics"), path, f"{where}.intrinsics")
        if not intr.is_file():
            raise InputError(f"intrinsics {intr} not found", source=path,
                             field=f"{where}.intrinsics")
    section = c.get("intrinsics_section")
    if section is not None:
        section = _string(section, path, f"{where}.intrinsics_section")
    skeleton = c.get("skeleton")
    if skeleton is not None:
        skeleton = _string(skeleton, path, f"{where}.skeleton")
        try:
            skeleton_by_name(skeleton)
        except ValueError as exc:
            raise InputError(str(exc), source=path, field=f"{where}.skeleton") from None
    mirrors = c.get("mirrors", [])
    if not isinstance(mirrors, list) or not all(isinstance(m, str) for m in mirrors):
        raise InputError("must be a list of mirror names", source=path,
                         field=f"{where}.mirrors")
    for m in mirrors:
        if m not in mirror_names:
            raise InputError(f"mirror {m!r} is not declared in [[mirrors]]", source=path,
                             field=f"{where}.mirrors")
    if len(set(mirrors)) != len(mirrors):
        raise InputError("a mirror is listed twice", source=path, field=f"{where}.mirrors")
    offset = c.get("frame_offset", 0)
    if isinstance(offset, bool) or not isinstance(offset, int):
        raise InputError("must be an integer number of frames", source=path,
                         field=f"{where}.frame_offset")
    fps = c.get("fps")
    if fps is not None:
        if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not fps > 0 \
                or fps == float("inf"):
            raise InputError(f"must be a frame rate in frames per second (> 0), got {fps!r}",
                             source=path, field=f"{where}.fps")
        fps = float(fps)
    size = c.get("image_size")
    if size is not None:
        if not (isinstance(size, list) and len(size) == 2):
            raise InputError(f"expected [width, height], got {size!r}", source=path,
                             field=f"{where}.image_size")
        size = check_size(size[0], size[1], path, f"{where}.image_size")
        if intr is not None:
            raise InputError("applies to a camera without intrinsics (the intrinsics file "
                             "holds its size)", source=path, field=f"{where}.image_size")
    return CameraEntry(name=name, keypoints=kp, intrinsics=intr, intrinsics_section=section,
                       skeleton=skeleton, mirrors=tuple(mirrors), frame_offset=int(offset),
                       image_size=size, fps=fps)
