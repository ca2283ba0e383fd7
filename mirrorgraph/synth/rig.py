"""Synthetic rigs of several cameras and mirrors, with ground truth.

The test and benchmark data of ``mirrorgraph calibrate-rig RIG.toml``: the
person of :mod:`mirrorgraph.synth` (an individual body, :mod:`.body`, doing the
procedural exercises of :mod:`.motion`: moving, stepping and turning up to
+-70 deg) is filmed by one or more cameras, directly and in one or two planar
mirrors. :func:`make_rig` builds the rig and simulates the pose detector of
each camera; :func:`write_rig` writes what a user of ``calibrate-rig`` would
have (keypoints, an intrinsics file, ``rig.toml``) next to the ground truth;
:func:`read_rig_ground_truth` reads the ground truth back.

One job per module: this one holds :func:`make_rig` (it builds the rig, checks
its placement and runs the detector) and re-exports the data classes of
:mod:`.rig_types` (:class:`SyntheticRig`, :class:`RigView`,
:class:`RigBystander`, :func:`bystander_name`) and the files of
:mod:`.rig_files` (:func:`write_rig`, :func:`read_rig_ground_truth`);
:mod:`.rig_placement` places the cameras, mirrors and the person and decides
what each camera sees; :mod:`.rig_bystanders` places the bystanders.

Frames, units and conventions
-----------------------------
* World frame = camera 0's frame: ``x`` right, ``y`` down, ``z`` forward,
  metres. Camera poses are camera-to-world ``(4, 4)`` matrices ``[[R, C], [0, 1]]``
  (``R`` the camera's axes in world coordinates, ``C`` its centre): a world
  point ``X`` is ``R^T (X - C)`` in the camera's frame. Camera 0's pose is the
  identity.
* A mirror is the plane ``n . X = d`` in the world frame, ``n`` a unit vector
  pointing away from camera 0, so ``d > 0`` is camera 0's distance to it. Its
  reflective side is ``n . X < d`` (the side of the room, where the cameras and
  the person are). In the frame of another camera ``i`` the same plane is
  ``n_i = R_i^T n``, ``d_i = d - n . C_i``; since every camera that sees the
  mirror stands on its reflective side, ``d_i > 0`` there too
  (:meth:`SyntheticRig.mirror_in_camera` gives the plane oriented away from any
  camera, flipping the sign where a camera is on the far side). The reflection
  is ``S(X) = X - 2 (n . X - d) n``.
* Images: pinhole cameras without distortion, ``fx = fy = (w / 2) / tan(fov / 2)``
  (``fov`` horizontal), principal point within +-4 px of the centre (drawn
  per camera, as in :mod:`.scene`); pixel origin at the top-left corner.
* Time: frames ``0 .. T-1`` at ``fps`` (30), every camera synchronised
  (``frame_offset = 0``).

The rigs (a *room frame* with ``Y`` up is used to build them; every number
below is drawn uniformly from the range given, from the seed):

``"4cams"``
    No mirror. Four cameras around the person at azimuths ``a0 + 90 k + (+-10)``
    deg (``a0`` any), 3-5 m from the centre of the person's motion, 1.0-1.6 m
    high, looking at that centre (the middle of the motion's vertical extent)
    with +-5 cm of aim jitter and +-2 deg of roll. The person faces any way.
    Each camera is redrawn until it sees the whole person in at least 90 % of
    the frames.
``"2cams1mirror"``
    A wall mirror (the whole wall, vertical) named ``"wall"``. The person
    stands 1.3-2.2 m in front of it, facing it (60 %) or the cameras (40 %),
    +-20 deg. Two cameras on the person's side, 3-5 m from the person, 1.0-1.6 m
    high, at azimuths (around the person, from the mirror's normal) 40-90 deg
    apart, each 15-60 deg off the normal (so the reflection is not hidden
    behind the person), each aimed between the person and the reflection.
``"1cam2mirrors"``
    Two mirrors meeting at a vertical edge with an interior angle of
    ``corner_angle_deg`` (default 90: the two walls of a room corner; 60-140),
    named ``"mirror_left"`` and ``"mirror_right"`` as the camera sees them.
    Each is a half-plane bounded by the edge (a point of one mirror is on the
    reflective side of the other), floor to ceiling. The person stands 2.0-2.6
    m from the edge, 5-12 deg off the bisector, facing the camera or the corner
    (50 % each, +-25 deg); the camera stands 3.5-4.5 m further from the edge,
    3-8 deg off the bisector on the other side (so that the double reflection,
    the person turned about the edge, is not hidden behind the person),
    1.0-1.6 m high, aimed at the middle of the person and both reflections.
    With ``double_reflections=True`` the double reflections (the ray meets one
    mirror, then the other) are detected too: at 90 deg both orders give the
    same virtual person, one view named ``"mirror_left+mirror_right"``; at
    other angles two views ``"mirror_left>mirror_right"`` (seen in
    ``mirror_left``, which shows ``mirror_right``) and
    ``"mirror_right>mirror_left"``. Above 90 deg they are rarely visible (as in
    a real corner of two mirrors); below it, reflections of three and more
    bounces exist physically but are not generated.

In the mirror rigs the placement is redrawn until each camera sees the whole
person in at least 90 % of the frames and the whole of each single reflection
it sees in at least 75 %, the torsos (shoulders and hips) of the person and of
each single reflection do not overlap horizontally in the image in at least
90 % of the frames, and every joint stays 0.2 m in front of every mirror.
(``double_reflections`` has no effect on the other kinds.)

Visibility of a joint in a view (direct, or through a sequence of mirrors) is
geometric (see :mod:`.rig_placement`). A view (the person, a reflection) is
detected in a frame only with at least 5 visible joints; hidden joints are
missing (NaN, confidence 0). Occlusion of one view by another is not modelled.

Bystanders (``bystanders=N``, default none): other people near the subject,
the common case of a gym or a dance studio, where everyone in front of the
mirror has a reflection too. Each has their own body, motion and height and is
in the room for part of the frames; :mod:`.rig_bystanders` draws them and
places them near the subject, seen by the cameras and apart from the subject's
views (a ``ValueError`` when none of its draws passes). They are detected
by the same detector model, directly and through every mirror, wherever
visible; their views are named ``"bystander1"``, ``"bystander1/wall"``, ...
(:attr:`SyntheticRig.views`, :attr:`SyntheticRig.detection_views`), their truth
is in :attr:`SyntheticRig.bystanders`. They draw from their own generator
(``default_rng([seed, 1])``): with the same seed the rig, the subject and the
subject's detections are those without bystanders.

Detector model (that of :mod:`.scene`, per camera): Gaussian noise of
``noise_std`` px per coordinate (zero mean), outliers, confidences, missing
people and joints as in :func:`mirrorgraph.synth.make_scene`; coordinates
clipped to the image. A single reflection is labelled the way the detector
sees it: anatomically, so its left/right labels are swapped
(:attr:`~mirrorgraph.skeletons.Skeleton.flip`: the detection's ``left_wrist``
images the real right wrist), except in a fraction ``lr_swap_rate`` of the
frames (per camera and mirror) where the detector keeps the real joints'
labels. A double reflection is a proper (rotated) image: its labels are those
of the real joints. People are listed per frame in random order.
"""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from ..keypoints import RawDetections
from ..skeletons import Skeleton, skeleton_by_name
from . import rig_files as _files, rig_placement as _placement
from .body import make_body, skeleton_points
from .motion import generate_motion
from .rig_bystanders import bystander_rng, make_bystanders
from .rig_files import read_rig_ground_truth, write_rig
from .rig_placement import (PERSON, TORSOS_APART, MAX_ATTEMPTS, PERSON_FULL, REFLECTION_FULL,
                            RIG_PRESETS, RigRanges, apart_fraction, build_1cam2mirrors,
                            build_2cams1mirror, build_4cams, camera_views, full_fraction,
                            mirror_distances_ok, resolve_rig_ranges)
from .rig_types import RigBystander, RigView, SyntheticRig, bystander_name
from .camera import check_camera_args, random_camera_matrix
from .detector import observe_keypoints

__all__ = ["KINDS", "RigView", "RigBystander", "SyntheticRig", "make_rig", "write_rig",
           "read_rig_ground_truth", "bystander_name"]

#: The rig kinds :func:`make_rig` builds.
KINDS = ("1cam2mirrors", "2cams1mirror", "4cams")

_MIN_JOINTS = 5         # visible joints for a view to be detected in a frame

# Importable from here as before the split, though not in __all__: the names of
# the files write_rig writes, and placement helpers tests/synth/test_synth_rig.py uses.
CALIB_NAME, GROUND_TRUTH_NAME, JOINTS3D_NAME, RIG_NAME = (
    _files.CALIB_NAME, _files.GROUND_TRUTH_NAME, _files.JOINTS3D_NAME, _files.RIG_NAME)
_Mirror, _path_visible = _placement._Mirror, _placement._path_visible


def _detect(rng, views: list, size: tuple[int, int], noise_std: float, outlier_rate: float,
            missing_rate: float, lr_swap_rate: float, flip: np.ndarray,
            joint_bias_px: float = 0.0, rng_bias: np.random.Generator | None = None
            ) -> tuple[list[np.ndarray], dict[str, RigView], np.ndarray]:
    """The detector on one camera's views of one person (:func:`camera_views` list).

    With ``joint_bias_px`` every view and joint also gets a constant offset (the
    detector's systematic error, as :func:`mirrorgraph.synth.make_scene`'s), and the
    Gaussian noise comes from ``rng_bias`` too (the subject's other draws unchanged).

    Returns:
        per view the ``(T, J, 3)`` detections with the detector's labels, the
        :class:`RigView` per view name, and ``(V, T)`` detected.
    """
    V = len(views)
    T = views[0][3].shape[0]
    clean = np.stack([v[3] for v in views])                    # (V, T, J, 2)
    visible = np.stack([v[4] for v in views])                  # (V, T, J)
    filled = np.where(visible[..., None], clean, 0.0)
    obs, miss, outl, detected = observe_keypoints(rng, filled, size, 0.0, noise_std,
                                         outlier_rate, missing_rate, 0.0, 0.0,
                                         joint_bias_px, rng_bias)
    detected &= visible.sum(-1) >= _MIN_JOINTS
    miss |= ~visible
    detected &= ~miss.all(-1)
    miss |= ~detected[..., None]
    outl &= ~miss
    obs[miss] = (np.nan, np.nan, 0.0)
    swapped = np.zeros((V, T), dtype=bool)
    rows_by_view, cam_views = [], {}
    for i, (vname, paths, flipped, _, _) in enumerate(views):
        if flipped:
            swapped[i] = (rng.random(T) < lr_swap_rate) & detected[i]
            labelled = np.where(swapped[i][:, None, None], obs[i], obs[i][:, flip])
        else:
            labelled = obs[i]
        rows_by_view.append(labelled)
        cam_views[vname] = RigView(
            name=vname, paths=paths, flipped=flipped,
            clean=np.where(visible[i][..., None], clean[i], np.nan), visible=visible[i],
            detected=detected[i], observed=obs[i], outliers=outl[i],
            lr_swapped=swapped[i])
    return rows_by_view, cam_views, detected


# --------------------------------------------------------------------------- make_rig
def make_rig(kind: str, *, frames: int = 300, seed: int | None = 0,
             skeleton: str | Skeleton = "BODY_25", noise_std: float = 4.0,
             subject_height: float | None = None, outlier_rate: float = 0.0,
             missing_rate: float = 0.0, lr_swap_rate: float = 0.0,
             double_reflections: bool = False, image_size: tuple[int, int] = (1920, 1080),
             fov_deg: float = 60.0, fps: float = 30.0, corner_angle_deg: float = 90.0,
             bystanders: int = 0, joint_bias_px: float = 0.0,
             geometry: str | RigRanges | None = None) -> SyntheticRig:
    """Generate a synthetic rig (see the module docstring for the geometry and model).

    Args:
        kind: ``"1cam2mirrors"``, ``"2cams1mirror"`` or ``"4cams"``.
        frames: number of frames ``T`` (>= 1).
        seed: seed of :func:`numpy.random.default_rng`; the same seed gives
            identical rigs.
        skeleton: keypoint layout or its name (``BODY_25``, ``COCO_17``, ``COCO_18``).
        noise_std: Gaussian detector noise per coordinate, px (zero mean).
        subject_height: metres (``None``: uniform 1.55-1.95).
        outlier_rate: fraction of observations replaced by gross errors (30-150 px).
        missing_rate: fraction of joint observations missing (beyond the hidden ones).
        lr_swap_rate: fraction of frames, per camera and mirror, whose single
            reflection the detector labels with the real joints' labels.
        double_reflections: also detect double reflections (``"1cam2mirrors"``).
        image_size: ``(width, height)`` px, every camera.
        fov_deg: horizontal field of view, degrees, every camera.
        fps: frame rate.
        corner_angle_deg: interior angle between the two mirrors of
            ``"1cam2mirrors"`` (60-140; 90 = the two walls of a room corner).
        bystanders: other people near the subject, each with their reflections
            (see the module docstring). Drawn from their own generator
            (``default_rng([seed, 1])``): the subject's detections, the rig and
            the truth are those of ``bystanders=0`` with the same seed, only
            the bystanders' rows are added (interleaved at random).
        joint_bias_px: standard deviation (px) of a constant offset per camera view
            and joint, the same in every frame: a detector's systematic error,
            which more frames do not average out. Drawn with the Gaussian noise
            from ``default_rng([seed, 2])``; 0 (default) keeps every output as before.
        geometry: the placement's ranges: a name of
            :data:`~mirrorgraph.synth.rig_placement.RIG_PRESETS` (``"favourable"``,
            the default and the ranges above; ``"gym"``; ``"wide"``) or a
            :class:`~mirrorgraph.synth.rig_placement.RigRanges`. With a focal range
            each camera's focal length is drawn (``fov_deg`` then only checked).

    Raises:
        ValueError: an unknown kind, an option out of range, or no placement
            found (a field of view too narrow for the rig).
    """
    options = dict(kind=kind, frames=frames, seed=seed,
                   skeleton=skeleton if isinstance(skeleton, str) else skeleton.name,
                   noise_std=noise_std, subject_height=subject_height,
                   outlier_rate=outlier_rate, missing_rate=missing_rate,
                   lr_swap_rate=lr_swap_rate, double_reflections=bool(double_reflections),
                   image_size=list(image_size), fov_deg=fov_deg, fps=fps,
                   corner_angle_deg=corner_angle_deg)
    if bystanders:
        options["bystanders"] = int(bystanders)       # absent by default: files as before
    if joint_bias_px:
        options["joint_bias_px"] = float(joint_bias_px)
    g = resolve_rig_ranges(geometry)
    if RIG_PRESETS.get(g.name) is not g or g.name != "favourable":
        options["geometry"] = g.name if RIG_PRESETS.get(g.name) is g else asdict(g)
    T, w, h = _check_rig_args(options, image_size, joint_bias_px, bystanders)
    skel = skeleton_by_name(skeleton) if isinstance(skeleton, str) else skeleton
    size = (w, h)
    n_cams = {"1cam2mirrors": 1, "2cams1mirror": 2, "4cams": 4}[kind]
    names = [f"cam{i + 1:02d}" for i in range(n_cams)]

    rng = np.random.default_rng(seed)
    Ks = [random_camera_matrix(rng, size, fov_deg) for _ in range(n_cams)]
    body = make_body(rng)
    local = skeleton_points(generate_motion(body, T, fps, rng), skel)
    H = float(subject_height) if subject_height is not None else float(rng.uniform(1.55, 1.95))

    torso = np.array([skel.index(f"{s}_{j}") for s in ("left", "right")
                      for j in ("shoulder", "hip")])
    X_r, cams, mirrors_r, info, views_r = _place_rig(
        rng, kind, g, Ks, size, local, H, np.radians(corner_angle_deg), double_reflections,
        torso, fov_deg)
    rng_b = bystander_rng(seed)
    extra = make_bystanders(rng_b, int(bystanders), skel, fps, cams, Ks, size, X_r,
                             mirrors_r, double_reflections, views_r, torso)
    if extra:
        info["bystanders"] = [b[3] for b in extra]
    frame = _in_camera0_frame(names, cams, X_r, mirrors_r, extra)
    detect = dict(size=size, noise_std=noise_std, outlier_rate=outlier_rate,
                  missing_rate=missing_rate, lr_swap_rate=lr_swap_rate, flip=skel.flip,
                  joint_bias_px=float(joint_bias_px),
                  rng_bias=np.random.default_rng([0 if seed is None else seed, 2])
                  if joint_bias_px else None)
    detections, views, det_views = _detect_rig(rng, rng_b, names, views_r, extra, skel, T,
                                               f"synthetic-rig({kind}, seed={seed})", fps,
                                               detect)
    return SyntheticRig(
        kind=kind, skeleton=skel, frame_ids=np.arange(T, dtype=np.int64), camera_names=names,
        K=Ks, image_size=size, subject_height=H, detections=detections,
        options=options, fps=float(fps), seed=seed, views=views,
        detection_views=det_views, body=body,
        placement=dict(info, room_to_world=frame.pop("room_to_world")), **frame)


# --------------------------------------------------------------------------- make_rig's steps
def _check_rig_args(options: dict, image_size: tuple[int, int], joint_bias_px: float,
                    bystanders) -> tuple[int, int, int]:
    """Raise ValueError naming the first of :func:`make_rig`'s options out of range
    (``options``: the ones it records); ``(T, width, height)``."""
    kind = options["kind"]
    if kind not in KINDS:
        raise ValueError(f"unknown rig kind {kind!r}; known: {', '.join(KINDS)}")
    T, w, h = check_camera_args(options["frames"], image_size, options["fov_deg"],
                                options["fps"], options["noise_std"])
    for name in ("outlier_rate", "lr_swap_rate", "missing_rate"):
        v = options[name]
        if not 0.0 <= v <= 1.0:
            raise ValueError(f"{name} must be in [0, 1], got {v}")
    subject_height = options["subject_height"]
    if subject_height is not None and not subject_height > 0:
        raise ValueError(f"subject_height must be positive, got {subject_height}")
    corner_angle_deg = options["corner_angle_deg"]
    if not 60.0 <= corner_angle_deg <= 140.0:
        raise ValueError(f"corner_angle_deg must be in [60, 140], got {corner_angle_deg}")
    if not joint_bias_px >= 0:
        raise ValueError(f"joint_bias_px must be >= 0, got {joint_bias_px}")
    if int(bystanders) != bystanders or bystanders < 0:
        raise ValueError(f"bystanders must be a non-negative integer, got {bystanders}")
    return T, w, h


def _place_rig(rng: np.random.Generator, kind: str, g: RigRanges, Ks: list, size: tuple[int, int],
               local: np.ndarray, H: float, corner_angle: float, double_reflections: bool,
               torso: np.ndarray, fov_deg: float):
    """Place cameras, mirrors and the person in the room frame, drawn again until every
    camera sees the person (and the reflections) whole and apart:
    ``(X_r, cams, mirrors_r, info, views_r)`` (``Ks`` get the drawn focal lengths)."""
    w, h = size
    built = None
    for attempt in range(MAX_ATTEMPTS):
        if g.focal_px is not None:
            for K in Ks:
                K[0, 0] = K[1, 1] = rng.uniform(*g.focal_px)
        if kind == "4cams":
            built = build_4cams(rng, local, H, Ks, size, g)
        elif kind == "2cams1mirror":
            built = build_2cams1mirror(rng, local, H, g)
        else:
            built = build_1cam2mirrors(rng, local, H, corner_angle, g)
        if built is None:
            continue
        X_r, cams, mirrors_r, info = built
        views_r = [camera_views(c, K, size, X_r, mirrors_r, double_reflections)
                   for c, K in zip(cams, Ks)]
        ok = mirror_distances_ok(cams, mirrors_r, g)
        for vs in views_r:
            main = [v for v in vs if v[0] == PERSON or len(v[1][0]) == 1]
            for name, _, _, uv, vis in main:
                ok &= full_fraction(vis) >= (PERSON_FULL if name == PERSON
                                              else REFLECTION_FULL)
            for i, a in enumerate(main):
                for b in main[i + 1:]:
                    ok &= apart_fraction(a[3], b[3], torso) >= TORSOS_APART
        if ok:
            break
        built = None
    if built is None:
        raise ValueError(f"cannot build a {kind!r} rig in which every camera sees the person "
                         f"(and the reflections) with a {fov_deg:g} deg field of view in "
                         f"{w}x{h} images; try a wider field of view")
    info["attempts"] = attempt + 1
    if g.focal_px is not None:
        info["focal_px"] = [float(K[0, 0]) for K in Ks]
    return X_r, cams, mirrors_r, info, views_r


def _in_camera0_frame(names: list[str], cams: list, X_r: np.ndarray, mirrors_r: dict,
                      extra: list) -> dict:
    """The rig from the room frame to camera 0's: the :class:`SyntheticRig` fields
    ``joints3d``, ``poses``, ``mirror_names``, ``mirrors``, ``mirror_limits``, ``sees`` and
    ``bystanders``, and ``room_to_world``."""
    R0, C0 = cams[0].R, cams[0].C
    room_to_world = np.eye(4)
    room_to_world[:3, :3] = R0.T
    room_to_world[:3, 3] = -R0.T @ C0
    joints3d = (X_r - C0) @ R0
    poses = []
    for c in cams:
        P = np.eye(4)
        P[:3, :3] = R0.T @ c.R
        P[:3, 3] = R0.T @ (c.C - C0)
        poses.append(P)
    poses[0] = np.eye(4)
    mirror_names = list(mirrors_r)
    mirrors, limits = [], {}
    for name in mirror_names:
        m = mirrors_r[name]
        n_w = R0.T @ m.n
        d_w = float(m.d - m.n @ C0)        # > 0: camera 0 is on the reflective side
        mirrors.append((n_w, d_w))
        limits[name] = [(R0.T @ a, float(b - a @ C0)) for a, b in m.limits]
    sees = {}
    for cname, c, P in zip(names, cams, poses):
        xs = [(P[:3, :3].T @ mirrors[mirror_names.index(m)][0])[0] for m in c.sees]
        sees[cname] = [c.sees[i] for i in np.argsort(xs, kind="stable")]
    truth = [RigBystander(name=bname, joints3d=(Xb - C0) @ R0, height=Hb, present=present,
                          body=bbody) for bname, (Xb, Hb, present, bbody), _, _ in extra]
    return dict(joints3d=joints3d, poses=poses, mirror_names=mirror_names, mirrors=mirrors,
                mirror_limits=limits, sees=sees, bystanders=truth, room_to_world=room_to_world)


def _detect_rig(rng: np.random.Generator, rng_b: np.random.Generator, names: list[str],
                views_r: list, extra: list, skel: Skeleton, T: int, source: str, fps: float,
                detect: dict):
    """The detector on every camera: ``(detections, views, det_views)`` by camera name,
    the subject's and the bystanders' rows in random order per frame."""
    J = skel.num_joints
    detections, views, det_views = {}, {}, {}
    for c, (cname, vs) in enumerate(zip(names, views_r)):
        rows_by_view, cam_views, detected = _detect(rng, vs, **detect)
        groups = [np.flatnonzero(d) for d in detected]
        vnames = [v[0] for v in vs]
        keys = [rng.random(sum(len(g) for g in groups))]         # random order per frame
        for bname, _, bviews, _ in extra:                        # after the subject's draws
            b_rows, b_views, b_detected = _detect(rng_b, bviews[c], **detect)
            b_groups = [np.flatnonzero(d) for d in b_detected]
            rows_by_view += b_rows
            cam_views.update(b_views)
            groups += b_groups
            vnames += [v[0] for v in bviews[c]]
            keys.append(rng_b.random(sum(len(g) for g in b_groups)))
        row_frame = np.concatenate(groups)
        row_view = np.concatenate([np.full(len(g), i) for i, g in enumerate(groups)])
        order = np.lexsort((np.concatenate(keys), row_frame))
        allrows = np.concatenate([rows_by_view[i][g] for i, g in enumerate(groups)])[order]
        vnames = np.array(vnames, dtype=object)[row_view[order]]
        splits = np.cumsum(np.bincount(row_frame, minlength=T))[:-1]
        people = np.split(allrows.reshape(-1, J, 3), splits)
        det_views[cname] = [tuple(x) for x in np.split(vnames, splits)]
        detections[cname] = RawDetections(
            skeleton=skel, frame_ids=np.arange(T, dtype=np.int64), people=people,
            source=f"{source}:{cname}", format="synthetic",
            image_size=detect["size"], fps=float(fps))
        views[cname] = cam_views
    return detections, views, det_views
