"""Per-camera keypoints of a rig, sorted into the person and their reflections, on one clock.

For each camera of a :class:`~mirrorgraph.rigs.config.RigConfig`: read the keypoints (any
format of :func:`mirrorgraph.io.read_keypoints`), read the intrinsics and undistort, then
sort every frame into the person and, for each mirror the camera sees, their reflection
(labels flipped to the real joints). Frames are put on the rig's clock with each camera's
frame rate (its input's, or the rig file's ``fps``) and time offset: found from the person
to a fraction of a frame (:mod:`.clocks`, the rig file's ``frame_offset`` the search's
centre; with ``clock_drift``, its clock rate too) or the rig file's as given. Each frame
lands on the rig frame nearest its instant, its keypoints interpolated to that instant
(:func:`~mirrorgraph.rigs.clocks.on_rig_clock`).

Who the person is, camera by camera:

* **Candidates**: in a camera with mirrors, the person of every (person, reflection) pair
  that fits a mirror's epipole (:func:`mirrorgraph.initial.pairing.pair_candidates`,
  :func:`mirrorgraph.initial.pairing.paired_people`); without mirrors every detection.
* **The first camera** (the reference) follows one person over time: tracks
  (:func:`mirrorgraph.rigs.tracking.track_labelled`), the subject the one seen longest
  or moving most (:func:`~mirrorgraph.rigs.tracking.subject_track`), and only the pairs
  holding its detection compete (:func:`mirrorgraph.initial.pairing.choose_pairs`). A
  warning names a second track seen in more than :data:`SECOND_PERSON_FRACTION` of the
  frames.
* **Every other camera** keeps per frame the candidate consistent with the first
  camera's person by epipolar geometry
  (:func:`mirrorgraph.rigs.matching.match_candidates`), with its reflections; when no
  candidate track fits, a :class:`~mirrorgraph.errors.DegenerateGeometryError` names the
  camera.
* **Left/right labels**: a frame whose labels disagree with the first camera's person's
  is not kept.

Shapes: ``(T, J, 3)`` arrays (x px, y px, confidence) on the rig's ``T`` frames,
undistorted pixels; NaN coordinates and confidence 0 where a camera has no observation.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from ..errors import DegenerateGeometryError, InputError
from ..intrinsics import Intrinsics, intrinsics_from_fov, load_intrinsics
from ..io import read_keypoints
from ..keypoints import PairedKeypoints, RawDetections
from ..initial.pair_candidates import PairingOptions
from ..initial.pairing import PairCandidates, choose_pairs, pair_candidates, paired_people
from ..preprocess import check_image_size, fraction_outside, undistort_keypoints
from ..skeleton_guess import AmbiguousSkeletonError, decide_body25
from ..skeletons import Skeleton, skeleton_by_name
from .clocks import (OFFSET_WINDOW, ClockEstimate, find_clocks, on_rig_clock, rig_instants,
                     rig_rates)
from .config import CameraEntry, RigConfig
from .matching import match_candidates
from .epipolar import inlier_threshold_px
from .failure import offset_hint
from .tracking import segments, subject_track, track_labelled, track_motion

__all__ = ["CameraObservations", "RigObservations", "load_observations", "DEFAULT_FOV_DEG"]

#: Horizontal field of view assumed for a camera without intrinsics, degrees.
DEFAULT_FOV_DEG = 60.0

#: The first camera warns when a second person pairs with a reflection in more
#: than this fraction of its frames.
SECOND_PERSON_FRACTION = 0.2

#: Detections per frame (the most confident) that a camera with mirrors pairs: two
#: bystanders in front of two mirrors make 9 (the single-camera default, 6, left
#: the subject's reflections out in a tenth of such frames).
MAX_PEOPLE = 12


@dataclass
class CameraObservations:
    """One camera's keypoints on the rig's clock.

    Attributes:
        name: camera name.
        intrinsics: its intrinsics (``K`` pixels, distortion already removed from
            the keypoints below).
        real: ``(T, J, 3)`` the person.
        reflections: mirror name -> ``(T, J, 3)`` the person's reflection in that
            mirror, labels flipped (entry ``j`` images the real joint ``j``).
        source: the keypoint input.
        lr_fixes: reflection frames whose left/right labels were corrected.
        people: ``T`` arrays ``(P_t, J, 3)``: the candidates for the person per frame
            (every detection without mirrors; with mirrors those that are the
            person of a pair fitting a mirror) among which the person was chosen;
            ``None`` for already paired input.
        matched: frames where the person kept is not the one the camera alone
            would take frame by frame (the most confident candidate; with mirrors
            the person of the frame's best pair): chosen by the cross-camera match
            or, in the first camera, by following the subject's track.
        clock: its time offset (:class:`~mirrorgraph.rigs.clocks.ClockEstimate`): the
            arrays above are on the rig's clock with it applied.
    """

    name: str
    intrinsics: Intrinsics
    real: np.ndarray
    reflections: dict[str, np.ndarray] = field(default_factory=dict)
    source: str = ""
    lr_fixes: int = 0
    people: list[np.ndarray] | None = None
    matched: int = 0
    clock: ClockEstimate | None = None


@dataclass
class RigObservations:
    """Every camera's observations on one clock.

    Attributes:
        skeleton: the keypoint layout (the same for every camera).
        frame_ids: ``(T,)`` rig frame numbers (at one frame rate: camera frame minus its
            offset; see :func:`~mirrorgraph.rigs.clocks.rig_rates` for several).
        cameras: per camera, in the rig file's order.
        mirrors: mirror names.
        fps: the rig clock's frame rate (the first camera's, or a whole multiple where a
            camera films faster), ``None`` where unknown.
        warnings: what the user should know (assumed intrinsics, several people
            with reflections in the first camera, ...).
    """

    skeleton: Skeleton
    frame_ids: np.ndarray
    cameras: list[CameraObservations]
    mirrors: tuple[str, ...]
    fps: float | None = None
    warnings: list[str] = field(default_factory=list)


#: The share of a camera's keypoints outside its image (enlarged by 10 % each side) above
#: which a warning says so; above half the rig is refused (:func:`check_image_size`).
OUTSIDE_WARNING = 0.10


def _intrinsics(entry: CameraEntry, data, warnings: list[str],
                estimate_focal: bool = True, fov_deg: float | None = None) -> Intrinsics:
    if entry.intrinsics is not None:
        section = entry.intrinsics_section
        if entry.intrinsics.suffix.lower() != ".toml" and section is not None:
            raise InputError("intrinsics_section applies to a .toml file only",
                             source=entry.intrinsics, field="intrinsics_section")
        intr = load_intrinsics(entry.intrinsics, camera=section)
    else:
        size = entry.image_size or data.image_size
        if size is None:
            raise InputError(f"camera {entry.name!r} has no intrinsics and its keypoints no "
                             "image size: add intrinsics = FILE or image_size = [W, H] to its "
                             "[[cameras]] table", source=data.source)
        fov = DEFAULT_FOV_DEG if fov_deg is None else float(fov_deg)
        intr = intrinsics_from_fov(size, fov)
        if not estimate_focal:
            warnings.append(f"camera {entry.name}: no intrinsics given, assumed a "
                            f"{fov:g} deg field of view")
    check_image_size(data, intr, warnings)
    if intr.image_size is not None:
        frac = fraction_outside(data, intr.image_size)
        if frac > OUTSIDE_WARNING:                  # refused above half (check_image_size)
            w, h = intr.image_size
            warnings.append(f"camera {entry.name}: {100 * frac:.0f}% of its keypoints lie "
                            f"outside its {w}x{h} image: are the keypoints and the "
                            "intrinsics in the same pixels?")
    mismatch = _size_mismatch(entry, data, intr)
    if mismatch:
        warnings.append(mismatch)
    return intr


def _size_mismatch(entry: CameraEntry, data, intr: Intrinsics) -> str | None:
    """The warning, one line, where the image size the camera's intrinsics file (or its
    rig-file ``image_size``) states differs from the size its keypoints carry (a
    video's, or an MMPose file's ``meta_info``); ``None`` where they agree or either is
    unknown. Pose2Sim's demo: the Qualisys calibration states 1088 x 1920 for cameras
    whose videos are 1080 x 1920 (an encoder's padding to 16 rows): K is used as given,
    the user should know."""
    if data.image_size is None:
        return None
    stated = intr.image_size if entry.intrinsics is not None else entry.image_size
    if stated is None or tuple(stated) == tuple(data.image_size):
        return None
    if entry.intrinsics is not None:
        where, used = f"its intrinsics ({entry.intrinsics})", "the intrinsics are used as given"
    else:
        where, used = "the rig file's image_size", "the principal point is that size's centre"
    return (f"camera {entry.name}: {where} state a {stated[0]}x{stated[1]} image, its "
            f"keypoints ({data.source}) {data.image_size[0]}x{data.image_size[1]}; {used}")


def _most_confident(raw: RawDetections, joints: np.ndarray) -> np.ndarray:
    """``(T, J, 3)``: per frame the detection with the largest summed confidence."""
    T, J = len(raw.people), raw.skeleton.num_joints
    out = np.full((T, J, 3), np.nan)
    out[..., 2] = 0.0
    for t, p in enumerate(raw.people):
        if len(p):
            conf = np.nan_to_num(np.asarray(p)[:, joints, 2])
            out[t] = p[int(np.argmax(conf.sum(1)))]
    return out


def _order_by_normal_x(K: np.ndarray, epipoles: list[np.ndarray]) -> np.ndarray:
    """Order of the mirrors by the ``x`` component of their normals (camera frame,
    normal turned to ``z > 0``): the mirror on the camera's left first."""
    xs = []
    for e in epipoles:
        n = np.linalg.solve(K, np.asarray(e, dtype=float))
        n = n / np.linalg.norm(n)
        xs.append(n[0] * (1.0 if n[2] >= 0 else -1.0))
    return np.argsort(xs, kind="stable")


@dataclass
class _Sorting:
    """One camera's keypoints sorted on its own frames ``T_c`` (before the rig's clock).

    Attributes:
        real, reflections, lr_fixes: as :class:`CameraObservations` (``(T_c, J, 3)``).
        people: ``T_c`` arrays ``(P_t, J, 3)``, the candidates for the person
            (``None``: already paired input).
        pairs: with mirrors and raw detections, every pair fitting a mirror.
        index: with ``pairs``, per frame the detection index (in the frame's list)
            of each candidate of ``people``.
        mirror_of: with ``pairs``, the mirror name of each of its epipoles.
        matched: see :attr:`CameraObservations.matched`.
    """

    real: np.ndarray
    reflections: dict[str, np.ndarray]
    lr_fixes: int
    people: list[np.ndarray] | None
    pairs: PairCandidates | None = None
    index: list[np.ndarray] | None = None
    mirror_of: list[str] = field(default_factory=list)
    matched: int = 0

    def several(self) -> bool:
        """Some frame holds more than one candidate for the person."""
        return self.people is not None and any(len(p) > 1 for p in self.people)


def _sort_camera(entry: CameraEntry, data, intr: Intrinsics) -> _Sorting:
    """Each frame's person and reflections as the camera alone sees them: the most
    confident detection, or the person and reflections of the frame's best pairs
    (:func:`mirrorgraph.initial.pairing.pair_reflections`), with the candidates for later."""
    joints = data.skeleton.calibration_joints
    k = len(entry.mirrors)
    if isinstance(data, PairedKeypoints):
        if k > 1:
            raise InputError(f"a paired .npz holds one reflection but camera {entry.name!r} "
                             f"lists {k} mirrors", source=data.source, field="mirrors")
        return _Sorting(data.real, {entry.mirrors[0]: data.mirror} if k else {}, 0, None)
    if k == 0:
        people = [np.asarray(p, dtype=float).reshape(-1, data.skeleton.num_joints, 3)
                  for p in data.people]
        return _Sorting(_most_confident(data, joints), {}, 0, people)
    pairs = pair_candidates(data, k, options=PairingOptions(max_people=MAX_PEOPLE))
    order = _order_by_normal_x(intr.K, pairs.epipoles)
    mirror_of = [""] * k
    for i, j in enumerate(order):
        mirror_of[j] = entry.mirrors[i]
    index = paired_people(pairs)
    J = data.skeleton.num_joints
    people = [np.asarray(data.people[t], dtype=float).reshape(-1, J, 3)[idx]
              for t, idx in enumerate(index)]
    sorting = _Sorting(np.empty(0), {}, 0, people, pairs, index, mirror_of)
    _apply_pairing(sorting, choose_pairs(pairs, data.skeleton.flip), entry.mirrors)
    return sorting


def _apply_pairing(sorting: _Sorting, pairing, mirrors: list[str]) -> None:
    """Take a :class:`~mirrorgraph.initial.pairing.MirrorPairing` as the camera's person and
    reflections (named in the rig file's order), in place."""
    by_name = dict(zip(sorting.mirror_of, pairing.reflections))
    sorting.real = pairing.real
    sorting.reflections = {m: by_name[m] for m in mirrors}
    sorting.lr_fixes = pairing.lr_fixes


def _keep_person(sorting: _Sorting, person: np.ndarray, flip: np.ndarray,
                 mirrors: list[str]) -> None:
    """Keep per frame only the pairs of the given person detection (``(T_c,)`` index
    into the frame's list, -1: none) and count the frames where that changed the
    person (:attr:`CameraObservations.matched`), in place."""
    before = sorting.real
    _apply_pairing(sorting, choose_pairs(sorting.pairs, flip, person), mirrors)
    both = (before[..., 2] > 0).any(1) & (sorting.real[..., 2] > 0).any(1)
    differ = (np.nan_to_num(before, nan=-1.0) != np.nan_to_num(sorting.real, nan=-1.0)).any((1, 2))
    sorting.matched = int(np.count_nonzero(both & differ))


def _follow_subject(name: str, sorting: _Sorting, skeleton: Skeleton, mirrors: list[str],
                    warnings: list[str], frame_ids: np.ndarray | None = None) -> None:
    """The first camera: keep the person whose track is seen (with mirrors: pairs with a
    reflection) in the most frames, between nearly equal ones the one that moves most,
    ties broken by confidence (see the module docstring), in place. Where the frames
    ``frame_ids`` or the people jump (:func:`~mirrorgraph.rigs.tracking.segments`:
    snapshots), no track crosses a jump and each stretch of frames keeps its own person
    (one frame alone: its most confident candidate)."""
    joints = skeleton.calibration_joints
    min_conf = PairingOptions().min_confidence
    # tracks read a detector's left/right swaps (those the assignment as labelled leaves
    # unlinked): tracked as labelled, a turning subject is split at each swap into
    # shorter tracks and loses to a person standing still in every frame (Demo_MultiPerson
    # since the detector's duplicate suppression: the subject's joints moved 208 px as
    # labelled, 23 px swapped, at cam01's frame 56; 56 + 44 frames against 100). Reading
    # swaps here was given up when the detector left duplicates of the subject, which the
    # swapped pass linked into the subject's track (mirrorgraph.video.nms removes them).
    tracks, swapped = track_labelled(sorting.people, joints, min_conf, skeleton.flip,
                                     frame_ids)
    conf = [np.nan_to_num(p[:, joints, 2]).sum(1) for p in sorting.people]
    # motion in each track's own labelling: a swapping person standing still would
    # otherwise move by the distance between their two sides
    own = [np.where(s[:, None, None], p[:, skeleton.flip], p)
           for p, s in zip(sorting.people, swapped)]
    motion = track_motion(tracks, own, joints, min_conf)
    stretch = (segments(frame_ids, len(tracks), sorting.people, joints, min_conf)
               if frame_ids is not None else segments(None, len(tracks)))
    chosen = np.full(len(tracks), -1, dtype=int)
    for s in np.unique(stretch):
        rows = np.flatnonzero(stretch == s)
        subject, frames = subject_track([tracks[t] for t in rows], motion,
                                        [conf[t] for t in rows])
        chosen[rows] = [(np.flatnonzero(tracks[t] == subject).tolist() or [-1])[0]
                        for t in rows]                          # a handful per frame
    what = "have reflections" if mirrors else "are in view"
    if not len(stretch) or stretch[-1] == 0:                  # one continuous stretch
        often = sum(n > SECOND_PERSON_FRACTION * len(tracks) for n in frames.values())
        if often > 1:
            warnings.append(f"camera {name}: {often} people {what}; calibrating from the one "
                            f"seen longest and moving most ({frames[subject]} of "
                            f"{len(tracks)} frames)")
    else:
        often = int(np.median([len(t) for t in tracks]))
        if often > 1:
            warnings.append(f"camera {name}: {often} people {what} in a frame (median); "
                            "calibrating from the one seen longest in each of its "
                            f"{stretch[-1] + 1} stretches of frames far apart in time")
    _keep_chosen(sorting, chosen, conf, skeleton, mirrors)


def _keep_chosen(sorting: _Sorting, chosen: np.ndarray, conf: list[np.ndarray],
                 skeleton: Skeleton, mirrors: list[str]) -> None:
    """Keep per frame the chosen candidate (``(T_c,)`` index into ``sorting.people[t]``,
    -1: none) as the person, with its reflections, in place."""
    if sorting.pairs is not None:
        person = np.array([idx[c] if c >= 0 else -1 for idx, c in zip(sorting.index, chosen)],
                          dtype=int)
        _keep_person(sorting, person, skeleton.flip, mirrors)
    else:
        J = skeleton.num_joints
        real = np.full((len(chosen), J, 3), np.nan)
        real[..., 2] = 0.0
        for t in np.flatnonzero(chosen >= 0):
            real[t] = sorting.people[t][chosen[t]]
        most = np.array([int(np.argmax(c)) if len(c) else -1 for c in conf])
        sorting.real = real
        sorting.matched = int(np.count_nonzero((chosen >= 0) & (chosen != most)))


def _match_camera(entry: CameraEntry, sorting: _Sorting, ref_name: str, ref_person: np.ndarray,
                  K_ref: np.ndarray, K: np.ndarray, skeleton: Skeleton, source: str,
                  frame_step: int = 1, frame_ids: np.ndarray | None = None) -> None:
    """Another camera: keep per frame the candidate consistent with the first camera's
    person (``ref_person`` ``(T_c, J, 3)`` on this camera's frames ``frame_ids``), in place.

    Raises:
        DegenerateGeometryError: no candidate track fits, naming the camera.
    """
    try:
        chosen, _ = match_candidates(ref_person, K_ref, sorting.people, K, skeleton,
                                     frame_ids=frame_ids)
    except DegenerateGeometryError as exc:
        hint = offset_hint(ref_person, K_ref, sorting.people, K, skeleton.calibration_joints,
                           inlier_threshold_px(ref_person, skeleton.calibration_joints,
                                               PairingOptions().min_confidence),
                           entry.frame_offset, frame_step)
        raise DegenerateGeometryError(
            f"camera {entry.name} ({source}): cannot tell which of the people it sees is "
            f"the person of camera {ref_name}: {exc}"
            + (f"; likeliest cause: {hint}" if hint else "")) from None
    conf = [np.nan_to_num(p[:, skeleton.calibration_joints, 2]).sum(1) for p in sorting.people]
    _keep_chosen(sorting, chosen, conf, skeleton, entry.mirrors)


def _place(a: np.ndarray, rows: np.ndarray, T: int) -> np.ndarray:
    """``(T, J, 3)``: a camera's ``(T_c, J, 3)`` at its rows of the rig's clock."""
    out = np.full((T,) + a.shape[1:], np.nan)
    out[..., 2] = 0.0
    out[rows] = a
    return out


def _read_cameras(config: RigConfig, skeleton: Skeleton | str | None, progress, video,
                  frame_progress) -> list:
    """Every camera's keypoints (:func:`mirrorgraph.io.read_keypoints`), one layout for
    the rig.

    Where a camera's keypoint count fits several layouts (25: BODY_25 and BODY_25B)
    and its own detections do not tell them apart (a camera seeing the subject from
    behind has no confident face joints: :class:`~mirrorgraph.skeleton_guess.AmbiguousSkeletonError`),
    the cameras that can tell decide for it, and where none can, all the undecided
    cameras' detections are pooled (:func:`~mirrorgraph.skeleton_guess.decide_body25`);
    such a camera is then read again in that layout.

    Raises:
        InputError: unreadable input; a layout that no camera's detections, nor all of
            them together, resolve (naming the rig file and the cameras).
    """
    read: list = []
    undecided: list[tuple[int, AmbiguousSkeletonError]] = []
    for i, entry in enumerate(config.cameras):
        if progress is not None:
            progress(entry.name)
        try:
            read.append(_read_camera(entry, entry.skeleton or skeleton, video, frame_progress))
        except AmbiguousSkeletonError as exc:
            read.append(None)
            undecided.append((i, exc))
    if not undecided:
        return read
    candidates = {s.name for s in undecided[0][1].candidates}
    decided = {d.skeleton.name for d in read if d is not None} & candidates
    names = ", ".join(config.cameras[i].name for i, _ in undecided)
    if len(decided) == 1:
        layout = skeleton_by_name(decided.pop())
    elif decided:                               # the cameras that tell disagree
        raise InputError(f"the cameras' keypoints use different skeletons "
                         f"({', '.join(sorted(decided))}) and cameras {names} cannot tell; "
                         "name one with skeleton = ... in each [[cameras]] table",
                         source=config.source, field="cameras")
    else:
        layout, why = decide_body25(np.concatenate([e.ratios for _, e in undecided]))
        if layout is None:
            fix = " or ".join(f'skeleton = "{n}"' for n in sorted(candidates))
            raise InputError(f"25 keypoints fit BODY_25 and BODY_25B and no camera tells them "
                             f"apart (cameras {names}: {why}); add {fix} to the cameras' "
                             "[[cameras]] tables", source=config.source, field="skeleton")
    for i, _ in undecided:
        read[i] = _read_camera(config.cameras[i], layout, video, frame_progress)
    return read


def _read_camera(entry: CameraEntry, skeleton, video, frame_progress):
    """One camera's keypoints (:func:`mirrorgraph.io.read_keypoints`)."""
    on_frame = None if frame_progress is None else \
        (lambda done, total, name=entry.name: frame_progress(name, done, total))
    return read_keypoints(entry.keypoints, skeleton=skeleton, progress=on_frame, video=video)


def _refuse_duplicates(config: RigConfig, read: list) -> None:
    """Refuse two cameras whose keypoints are identical (the same frames, the same people
    to the last digit): one camera's observations read twice put the second camera at
    the first's place, with confident stds.

    Raises:
        InputError: naming both cameras.
    """
    import hashlib

    seen: dict[str, str] = {}
    for entry, data in zip(config.cameras, read):
        h = hashlib.sha1(np.asarray(data.frame_ids, np.int64).tobytes())
        for p in data.people:
            a = np.ascontiguousarray(np.asarray(p, float))
            h.update(str(a.shape).encode())
            h.update(a.tobytes())
        key = h.hexdigest()
        if key in seen:
            raise InputError(f"cameras {seen[key]} and {entry.name} read identical keypoints "
                             "(the same frames and people): one camera's observations "
                             f"twice; give {entry.name} its own keypoints",
                             source=config.source, field="cameras")
        seen[key] = entry.name


def _frame_rates(config: RigConfig, read: list, warnings: list[str]) -> list[float | None]:
    """Every camera's frame rate: its rig-file ``fps``, else its input's (``None`` where
    neither says); a warning where both say and differ by more than 0.1 %."""
    out = []
    for entry, data in zip(config.cameras, read):
        own = data.fps if data.fps and np.isfinite(data.fps) and data.fps > 0 else None
        if entry.fps is not None and own is not None and abs(own / entry.fps - 1) > 1e-3:
            warnings.append(f"camera {entry.name}: its keypoints ({data.source}) say "
                            f"{own:g} fps, the rig file's fps {entry.fps:g}: the rig file's "
                            "is used")
        out.append(entry.fps if entry.fps is not None else own)
    return out


def _refuse_disjoint(per_camera: list, config: RigConfig, offsets: list[float]) -> None:
    """Refuse a camera whose rig frames (after its time offset, ``offsets``: the first
    camera's frames) span none of the first camera's: nothing is seen at once, whatever
    the people."""
    ref_entry, _, ref_frames, *_ = per_camera[0]
    for (entry, _, frames, *_), offset in zip(per_camera[1:], offsets[1:]):
        if len(frames) and len(ref_frames) and (frames.max() < ref_frames.min()
                                                or frames.min() > ref_frames.max()):
            raise InputError(f"camera {entry.name}'s frames {int(frames.min())}.."
                             f"{int(frames.max())} (after its time offset {offset:g}) share "
                             f"none with camera {ref_entry.name}'s {int(ref_frames.min())}.."
                             f"{int(ref_frames.max())}: check frame_offset",
                             source=config.source, field="frame_offset")


def load_observations(config: RigConfig, *, skeleton: Skeleton | str | None = None,
                      progress: Callable[[str], None] | None = None, video=None,
                      frame_progress: Callable[[str, int, int], None] | None = None,
                      estimate_focal: bool = True,
                      fov_deg: float | None = None, time_offsets: str = "search",
                      offset_window: int = OFFSET_WINDOW, seed: int = 0) -> RigObservations:
    """Read, undistort and sort every camera's keypoints (see the module docstring).

    Args:
        config: the rig.
        skeleton: layout for cameras whose table names none (default: from the
            keypoint count).
        progress: called with the camera's name before it is read.
        video: :class:`mirrorgraph.video.VideoOptions` for keypoints that name a video.
        frame_progress: ``(camera, done, total)`` per frame of a video being detected.
        estimate_focal: a camera without intrinsics gets a 60 deg field-of-view guess
            either way (``intrinsics.approximate``); without the estimate (``False``)
            a warning says so.
        fov_deg: the field of view of that guess (default
            :data:`~mirrorgraph.intrinsics.DEFAULT_FOV_DEG`).
        time_offsets: ``"search"``: every camera's time offset found from the person
            (:func:`~mirrorgraph.rigs.clocks.find_clocks`, the rig file's
            ``frame_offset`` the centre of the search) and applied, to a fraction of a
            frame; ``"fixed"``: the rig file's ``frame_offset`` as given.
        offset_window: frames (the first camera's) searched either way of a camera's
            given offset.
        seed: seed of the search's random choices.

    Raises:
        InputError: unreadable input (naming the file), cameras with different
            skeletons, a layout no camera resolves (:func:`_read_cameras`).
        DegenerateGeometryError: a camera's reflections cannot be sorted out, or
            none of the people a camera sees is the first camera's person (naming
            the camera).
    """
    warnings: list[str] = []
    per_camera = []
    read = _read_cameras(config, skeleton, progress, video, frame_progress)
    _refuse_duplicates(config, read)
    layouts = [data.skeleton for data in read]
    names = {s.name for s in layouts}
    if len(names) > 1:
        raise InputError(f"the cameras' keypoints use different skeletons ({', '.join(sorted(names))});"
                         " name one with skeleton = ... in each [[cameras]] table",
                         source=config.source, field="cameras")
    sk = layouts[0]
    rates, unit, rig_fps = rig_rates(_frame_rates(config, read, warnings))
    for entry, data, rate in zip(config.cameras, read, rates):
        intr = _intrinsics(entry, data, warnings, estimate_focal, fov_deg)
        data = undistort_keypoints(data, intr)
        sorting = _sort_camera(entry, data, intr)
        per_camera.append((entry, intr, np.asarray(data.frame_ids, np.int64), sorting,
                           data.source))
    ref_entry, ref_intr, _, ref, _ = per_camera[0]
    if ref.several():
        _follow_subject(ref_entry.name, ref, sk, ref_entry.mirrors, warnings,
                        per_camera[0][2])
    if rig_fps is not None and any(r != unit for r in rates):
        warnings.append("frame rates " + ", ".join(
            f"{e.name} {rig_fps / r:.4g}" for e, r in zip(config.cameras, rates))
            + f" fps: every camera on one {rig_fps:.4g} fps clock by its rate "
            f"(frame_offset in {ref_entry.name}'s frames)")
    clocks = find_clocks([(s.real, s.people) for _, _, _, s, _ in per_camera],
                         [f for _, _, f, *_ in per_camera],
                         [i.K for _, i, *_ in per_camera],
                         [e.frame_offset * unit for e in config.cameras],
                         sk.calibration_joints, rates=rates, unit=unit,
                         drift=config.clock_drift, search=time_offsets == "search",
                         window=offset_window, seed=seed)
    clocks = [replace(c, fps=rig_fps / r if rig_fps else None, rig_fps=rig_fps)
              for c, r in zip(clocks, rates)]
    warnings += [f"camera {e.name}: time offset: {c.note}" for e, c in
                 zip(config.cameras, clocks) if c.note]
    # every own frame at the rig frame nearest the instant it shows
    per_camera = [(e, i, np.round(rig_instants(f, r, c)).astype(np.int64), *rest)
                  for (e, i, f, *rest), c, r in zip(per_camera, clocks, rates)]
    _refuse_disjoint(per_camera, config, [c.reference_frames[0] for c in clocks])
    frame_ids = np.unique(np.concatenate([f for _, _, f, *_ in per_camera]))
    T, J = len(frame_ids), sk.num_joints
    rows = [np.searchsorted(frame_ids, f) for _, _, f, *_ in per_camera]
    ref_person = _place(ref.real, rows[0], T)
    for (entry, intr, f, sorting, source), r in zip(per_camera[1:], rows[1:]):
        if sorting.people is not None:      # one candidate a frame may still be another person
            step = int(np.median(np.diff(f))) if len(f) > 1 else 1
            _match_camera(entry, sorting, ref_entry.name, ref_person[r], ref_intr.K, intr.K,
                          sk, source, step, f)
    # the person each camera kept, placed at the instants of the rig's frames
    placed = [[on_rig_clock(a, f, r, c) for a in (s.real, *s.reflections.values())]
              for (_, _, _, s, _), f, r, c in
              zip(per_camera, [d.frame_ids for d in read], rates, clocks)]

    cameras = []
    for (entry, intr, _, sorting, source), r, clock, arrays in zip(per_camera, rows, clocks,
                                                                   placed):
        people = None
        if sorting.people is not None:
            people = [np.zeros((0, J, 3))] * T
            for row, p in zip(r, sorting.people):
                people[row] = p
        on_rows = [_place(a, np.searchsorted(frame_ids, ids), T) for ids, a in arrays]
        cameras.append(CameraObservations(
            name=entry.name, intrinsics=intr, real=on_rows[0],
            reflections=dict(zip(sorting.reflections, on_rows[1:])),
            source=source, lr_fixes=sorting.lr_fixes, people=people, matched=sorting.matched,
            clock=clock))
    return RigObservations(skeleton=sk, frame_ids=frame_ids, cameras=cameras,
                           mirrors=config.mirrors, fps=rig_fps or read[0].fps,
                           warnings=warnings)
