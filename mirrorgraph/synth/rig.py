"""Synthetic rigs of several cameras and mirrors, with ground truth.

The test and benchmark data of ``mirrorgraph calibrate-rig RIG.toml``: the person of
:mod:`mirrorgraph.synth` (:mod:`.body`, doing the exercises of :mod:`.motion`) filmed by
one or more cameras, directly and in one or two planar mirrors. :func:`make_rig` builds
the rig and simulates each camera's pose detector; :func:`write_rig` writes what a user
of ``calibrate-rig`` would have (keypoints, intrinsics, ``rig.toml``) next to the ground
truth; :func:`read_rig_ground_truth` reads it back. Data classes live in :mod:`.rig_types`,
files in :mod:`.rig_files`, placement in :mod:`.rig_placement`, bystanders in
:mod:`.rig_bystanders`.

Frames, units and conventions:

* World frame = camera 0's frame (``x`` right, ``y`` down, ``z`` forward), metres.
  Camera poses are camera-to-world ``(4, 4)`` matrices ``[[R, C], [0, 1]]``; a world
  point ``X`` is ``R^T (X - C)`` in the camera's frame.
* A mirror is ``n . X = d``, ``n`` unit and pointing away from camera 0; its reflective
  side ``n . X < d``; in camera ``i``'s frame ``n_i = R_i^T n``, ``d_i = d - n . C_i``
  (:meth:`SyntheticRig.mirror_in_camera`). The reflection is ``S(X) = X - 2 (n . X - d) n``.
* Images: pinhole cameras without distortion, ``fx = fy = (w / 2) / tan(fov / 2)``,
  principal point within +-4 px of the centre; pixel origin at the top-left corner.
* Time: frames ``0 .. T-1`` at ``fps`` (30), every camera synchronised.

The rig kinds (``"4cams"``, the mirror rigs, the corner of two mirrors with
``double_reflections``), their placement ranges and acceptance rules, the bystanders and
the detector model (that of :mod:`.scene`; a single reflection labelled anatomically,
swapped in a fraction ``lr_swap_rate`` of frames): ``docs/internals.md``. Bystanders draw
from their own generator (``default_rng([seed, 1])``), so with the same seed the subject's
detections are those without bystanders.
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

# Importable from here, though not in __all__: the names of the files write_rig
# writes, and placement helpers tests/synth/test_synth_rig.py uses.
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
            from ``default_rng([seed, 2])``; 0 (default) draws nothing more: the scene
            is the one of the same seed without it.
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
        options["bystanders"] = int(bystanders)       # absent by default: files without the key
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
    joints3d, poses = _placement.first_camera_frame(cams, X_r)
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
