"""The initial rig: pairwise estimates chained along a spanning tree.

0. A camera given without intrinsics starts from an initial focal length
   (:func:`initial_focals`: resected against the joints the calibrated cameras
   triangulate, or from a fundamental matrix), which the graph then estimates with
   everything else.
1. Every pair of cameras that sees the person (and reflections) in common frames
   gets a relative pose (:func:`~mirrorgraph.initial.relative.relative_pose`), every
   camera-mirror pair a plane (:func:`~mirrorgraph.initial.relative.mirror_sighting`).
2. The cameras are chained from the first one (the world frame) along a
   maximum spanning tree of the camera graph, edges weighted by their inlier
   counts (Prim's algorithm): each camera is reached through its best-supported
   chain.
3. Each mirror is placed in the world from the camera that saw it with the
   most inliers: ``n_w = R_c n_c``, ``d_w = d_c + n_w . c_c`` for the camera's pose
   ``(R_c, c_c)`` (camera-to-world). Its normal is then turned to point away from
   the world origin (``d > 0``) when the plane does not pass through it.
4. Every joint seen by two or more views (real or through a mirror) is
   triangulated (:func:`~mirrorgraph.geometry.triangulate`).

A camera that shares too few joints with the cameras already placed cannot be
chained: that is a :class:`~mirrorgraph.errors.DegenerateGeometryError` naming it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from ..errors import DegenerateGeometryError
from ..geometry import camera_projection, triangulate
from ..graph.options import RefineOptions
from ..graph.rig import Camera, Mirror, Rig, View
from ..graph.focal_search import focal_search
from ..graph.stage_config import single_mirror_config
from ..keypoints import DEFAULT_MIN_CONFIDENCE
from ..rigs.observations import RigObservations
from .relative import (MIN_CORRESPONDENCES, MirrorSighting, RelativePose, focal_from_fundamental,
                       golden_section_min, mirror_sighting, relative_pose)

__all__ = ["InitialRig", "initialise_rig", "initial_focals", "observed", "joint_masks",
           "MIN_CONFIDENCE"]

#: Joints below this detector confidence are not used.
MIN_CONFIDENCE = DEFAULT_MIN_CONFIDENCE


@dataclass
class InitialRig:
    """Camera poses and mirror planes before the refinement.

    Attributes:
        poses: ``(4, 4)`` camera-to-world pose per camera (the first: identity).
        planes: mirror name -> ``(n (3,), d)`` in the world frame.
        edges: ``(camera a, camera b)`` -> :class:`RelativePose` of every pair tried
            successfully.
        sightings: ``(camera, mirror)`` -> :class:`MirrorSighting`.
        tree: ``(parent, child)`` camera names of the spanning tree, in order.
        mirror_spread_deg: mirror name -> largest angle between the normals that
            different cameras see (0 for a mirror seen by one camera).
        K: ``(3, 3)`` per camera, the intrinsics the poses were found with (a camera
            given without intrinsics: its initial focal length, :func:`initial_focals`).
        focals: camera name -> ``{"focal_px", "method"}`` of those initial focal lengths.
    """

    poses: list[np.ndarray]
    planes: dict[str, tuple[np.ndarray, float]]
    edges: dict[tuple[str, str], RelativePose] = field(default_factory=dict)
    sightings: dict[tuple[str, str], MirrorSighting] = field(default_factory=dict)
    tree: list[tuple[str, str]] = field(default_factory=list)
    mirror_spread_deg: dict[str, float] = field(default_factory=dict)
    K: list[np.ndarray] = field(default_factory=list)
    focals: dict[str, dict] = field(default_factory=dict)


def observed(a: np.ndarray, joints_mask: np.ndarray | bool = True) -> np.ndarray:
    """``(..., J)`` bool: keypoints ``a`` ``(..., J, 3)`` at or above :data:`MIN_CONFIDENCE`,
    finite, and among ``joints_mask`` (broadcast against ``(..., J)``)."""
    return (a[..., 2] >= MIN_CONFIDENCE) & np.isfinite(a[..., :2]).all(-1) & joints_mask


def joint_masks(skeleton, joints: tuple[np.ndarray, np.ndarray] | None
                ) -> tuple[np.ndarray, np.ndarray]:
    """``(J,)`` bool masks of the joints used in the direct views and through mirrors
    (``joints`` from :func:`~mirrorgraph.joint_sets.resolve_joints`; ``None``: the
    calibration joints in both)."""
    limbs = np.asarray(skeleton.calibration_joints, dtype=int)
    direct, through = (limbs, limbs) if joints is None else joints
    dmask = np.zeros(skeleton.num_joints, dtype=bool)
    mmask = np.zeros(skeleton.num_joints, dtype=bool)
    dmask[np.asarray(direct, dtype=int)] = True
    mmask[np.asarray(through, dtype=int)] = True
    return dmask, mmask


def _plane_to_world(pose: np.ndarray, n: np.ndarray, d: float) -> tuple[np.ndarray, float]:
    nw = pose[:3, :3] @ n
    return nw, float(d + nw @ pose[:3, 3])


def initialise_rig(obs: RigObservations, height: float, *, seed: int = 0,
                   joints: tuple[np.ndarray, np.ndarray] | None = None,
                   estimate_focal: bool = True) -> InitialRig:
    """Initial poses and planes (see the module docstring).

    Args:
        obs: the sorted observations.
        height: the subject's height in the output unit (metres, or 1).
        seed: RANSAC seed.
        joints: ``(direct, mirror)`` joint indices used in the direct views and through
            mirrors (:func:`~mirrorgraph.joint_sets.resolve_joints`; default: the
            calibration joints in both).
        estimate_focal: start the cameras given without intrinsics (a field-of-view
            guess, ``intrinsics.approximate``) from an initial focal length
            (:func:`initial_focals`); ``False``: from the guess.

    Raises:
        DegenerateGeometryError: a camera cannot be chained, a mirror not estimated.
    """
    sk = obs.skeleton
    dmask, mmask = joint_masks(sk, joints)
    through = np.flatnonzero(mmask)
    cams = obs.cameras
    C = len(cams)
    K = [np.asarray(c.intrinsics.K, float) for c in cams]
    focals: dict[str, dict] = {}
    if estimate_focal and any(c.intrinsics.approximate for c in cams):
        focals = initial_focals(obs, height, seed=seed, joints=(dmask, mmask))
        for i, c in enumerate(cams):
            if c.name in focals:
                K[i] = _with_focal(K[i], focals[c.name]["focal_px"])

    sightings: dict[tuple[str, str], MirrorSighting] = {}
    for i, cam in enumerate(cams):
        for m, refl in cam.reflections.items():
            mask = observed(cam.real, mmask) & observed(refl, mmask)
            sightings[(cam.name, m)] = mirror_sighting(
                K[i], cam.real[..., :2], refl[..., :2], mask, sk, through, height,
                seed=seed, name=f"{cam.name}/{m}")

    edges = _edges(obs, K, range(C), height, seed, dmask, mmask)
    poses, tree = _spanning_tree(obs, edges, range(C), 0)
    if len(poses) < C:
        missing = [cams[i].name for i in range(C) if i not in poses]
        raise DegenerateGeometryError(
            f"camera(s) {', '.join(missing)} share too few joints (fewer than "
            f"{MIN_CORRESPONDENCES} consistent ones) with camera {cams[0].name} and the "
            "cameras linked to it: they cannot be placed (is the person visible in them at "
            "the same frames? are the frame offsets right?)")
    index = {c.name: i for i, c in enumerate(cams)}

    planes: dict[str, tuple[np.ndarray, float]] = {}
    spread: dict[str, float] = {}
    for m in obs.mirrors:
        seen = [(c, s) for (c, mm), s in sightings.items() if mm == m]
        if not seen:
            continue
        c_best, s_best = max(seen, key=lambda cs: cs[1].inliers)
        n, d = _plane_to_world(poses[index[c_best]], s_best.normal, s_best.distance)
        if d < 0:
            n, d = -n, -d
        planes[m] = (n, d)
        angles = []
        for c, s in seen:
            nw, _ = _plane_to_world(poses[index[c]], s.normal, s.distance)
            angles.append(np.degrees(np.arccos(np.clip(abs(nw @ n), -1.0, 1.0))))
        spread[m] = float(max(angles))
    return InitialRig(poses=[np.asarray(poses[i]) for i in range(C)], planes=planes,
                      edges=edges, sightings=sightings, tree=tree, mirror_spread_deg=spread,
                      K=K, focals=focals)


def _edges(obs: RigObservations, K: list[np.ndarray], cameras, height: float, seed: int,
           dmask: np.ndarray, mmask: np.ndarray) -> dict[tuple[str, str], RelativePose]:
    """Relative poses of every pair among ``cameras`` (indices) that shares enough joints
    (the person and the reflections both see)."""
    cams, idx = obs.cameras, list(cameras)
    direct = np.flatnonzero(dmask)
    edges: dict[tuple[str, str], RelativePose] = {}
    for ia, a in enumerate(idx):
        for b in idx[ia + 1:]:
            ca, cb = cams[a], cams[b]
            sets_a, sets_b = [ca.real], [cb.real]
            for m in set(ca.reflections) & set(cb.reflections):
                sets_a.append(ca.reflections[m])
                sets_b.append(cb.reflections[m])
            ua, ub = np.stack(sets_a), np.stack(sets_b)
            masks = np.stack([dmask] + [mmask] * (len(sets_a) - 1))[:, None, :]
            mask = observed(ua, masks) & observed(ub, masks)
            rel = relative_pose(K[a], K[b], ua[..., :2], ub[..., :2], mask, obs.skeleton,
                                direct, height, seed=seed)
            if rel is not None:
                edges[(ca.name, cb.name)] = rel
    return edges


def _spanning_tree(obs: RigObservations, edges: dict[tuple[str, str], RelativePose], cameras,
                   root: int) -> tuple[dict[int, np.ndarray], list[tuple[str, str]]]:
    """Prim's maximum spanning tree over ``cameras`` from ``root`` (its frame the world):
    camera index -> ``(4, 4)`` camera-to-world pose of every camera it reaches, and the
    tree's ``(parent, child)`` names in order."""
    cams = obs.cameras
    index = {c.name: i for i, c in enumerate(cams)}
    allowed = set(cameras)
    poses = {root: np.eye(4)}
    tree = []
    while True:
        best = None
        for (na, nb), rel in edges.items():
            a, b = index[na], index[nb]
            if a not in allowed or b not in allowed or (a in poses) == (b in poses):
                continue
            if best is None or rel.inliers > best[2].inliers:
                best = (a, b, rel)
        if best is None:
            return poses, tree
        a, b, rel = best
        T_ab = rel.pose_b_in_a                       # b's pose in a's frame
        if a in poses:
            poses[b] = poses[a] @ T_ab
            tree.append((cams[a].name, cams[b].name))
        else:
            poses[a] = poses[b] @ np.linalg.inv(T_ab)
            tree.append((cams[b].name, cams[a].name))


def _with_focal(K: np.ndarray, f: float) -> np.ndarray:
    K = np.array(K, dtype=float, copy=True)
    K[0, 0] = K[1, 1] = float(f)
    return K


def initial_focals(obs: RigObservations, height: float, *, seed: int = 0,
                   joints: tuple[np.ndarray, np.ndarray] | None = None,
                   fov_deg: tuple[float, float] = (20.0, 120.0)) -> dict[str, dict]:
    """Initial focal lengths of the cameras given without intrinsics.

    * Two cameras with intrinsics or more, placed relative to each other: the person's
      joints triangulated with them, and each camera without intrinsics resected
      against those 3D joints: the focal length whose PnP pose (OpenCV's
      ``solvePnPRansac``) reprojects them best (a log grid over ``fov_deg``, then a
      golden-section search; square pixels, the principal point at the image centre).
      Well conditioned: the person spans depth, thousands of joints, no degenerate
      relative placement.
    * Otherwise, a camera that sees mirrors: the focal length that makes the body most
      rigid between the person and the reflections (the single mirror's search,
      :func:`~mirrorgraph.graph.focal_search.focal_search`, on that camera alone): the
      relative pose of two cameras needs a focal length within ~10 % (a synthetic
      two-camera rig's started 99 deg off with the 60 deg guess, 8 % off).
    * Otherwise from the fundamental matrix with the camera sharing most joints
      (:func:`~mirrorgraph.initial.relative.focal_from_fundamental`: one unknown with a
      calibrated partner, both with none), unstable where the two optical axes meet
      (on synthetic four-camera rigs a camera facing the first one came out at the
      end of the search range): a result at either end of the range is not used.
    * A camera no method reaches keeps its guess; the graph estimates its focal length
      with the rest either way (:attr:`~mirrorgraph.graph.rig.Camera.estimate_focal`).

    Args:
        obs: the sorted observations (a camera without intrinsics has
            ``intrinsics.approximate``).
        height: the subject's height in the output unit.
        seed: RANSAC seed.
        joints: ``(direct, mirror)`` joint masks or indices (default: calibration joints);
            the direct views' limbs (the calibration joints) are used whatever it says.
        fov_deg: the horizontal fields of view searched, degrees.

    Returns:
        camera name -> ``{"focal_px", "method"}`` for the cameras it could start.
    """
    sk = obs.skeleton
    _, mmask = joint_masks(sk, None if joints is None else tuple(
        np.flatnonzero(j) if np.asarray(j).dtype == bool else j for j in joints))
    # the limbs alone, whatever the graph uses: on synthetic four-camera rigs the face and
    # feet (seen from behind, the face is guessed) take a resection from -3 % to +28 %
    dmask, _ = joint_masks(sk, None)
    cams = obs.cameras
    unknown = [i for i, c in enumerate(cams) if c.intrinsics.approximate]
    known = [i for i, c in enumerate(cams) if not c.intrinsics.approximate]
    K = [np.asarray(c.intrinsics.K, float) for c in cams]
    out: dict[str, dict] = {}
    if len(known) >= 2:
        edges = _edges(obs, K, known, height, seed, dmask, mmask)
        poses, _ = _spanning_tree(obs, edges, known, known[0])
        if len(poses) >= 2:
            placed = sorted(poses)
            X, ok = triangulate([camera_projection(K[i], poses[i]) for i in placed],
                                [cams[i].real[..., :2] for i in placed],
                                [observed(cams[i].real, dmask) for i in placed])
            for u in unknown:
                f = _focal_by_resection(X, ok, cams[u].real, dmask, K[u], fov_deg, seed)
                if f is not None:
                    out[cams[u].name] = {"focal_px": float(f), "method": "resection against "
                                         + ", ".join(cams[i].name for i in placed)}
    for u in unknown:
        if cams[u].name in out or not cams[u].reflections:
            continue
        f = _focal_through_mirrors(obs, u, height, seed, dmask, mmask)
        if f is not None:
            out[cams[u].name] = {"focal_px": f, "method": "search through its mirror(s) "
                                 + ", ".join(cams[u].reflections)}
    for u in unknown:
        if cams[u].name in out:
            continue
        partners = [i for i in range(len(cams)) if i != u]
        best = None
        for i in partners:
            m = observed(cams[u].real, dmask) & observed(cams[i].real, dmask)
            if best is None or m.sum() > best[1].sum():
                best = (i, m)
        if best is None or best[1].sum() < MIN_CORRESPONDENCES:
            continue
        i, m = best
        both = not (i in known or cams[i].name in out)
        Ki = K[i] if cams[i].name not in out else _with_focal(K[i], out[cams[i].name]["focal_px"])
        res = focal_from_fundamental(Ki, K[u], cams[i].real[..., :2][m], cams[u].real[..., :2][m],
                                     unknown="both" if both else "b", fov_deg=fov_deg, seed=seed)
        if res is None:
            continue
        lo, hi = (float(K[u][0, 2]) / np.tan(0.5 * np.radians(x)) for x in (fov_deg[1], fov_deg[0]))
        if lo * 1.02 < res[1] < hi / 1.02:
            out[cams[u].name] = {"focal_px": float(res[1]),
                                 "method": f"fundamental matrix with {cams[i].name}"}
    return out


def _focal_through_mirrors(obs: RigObservations, u: int, height: float, seed: int,
                           dmask: np.ndarray, mmask: np.ndarray) -> float | None:
    """The focal search of one camera with its mirrors (the rig of that camera alone);
    ``None`` where a mirror cannot be estimated or the search fails."""
    cam = obs.cameras[u]
    sk = obs.skeleton
    K = np.asarray(cam.intrinsics.K, float)
    mirrors, views, planes = [], [View("direct", cam.name, None, cam.real[..., :2],
                                       observed(cam.real, dmask))], []
    for m, refl in cam.reflections.items():
        mask = observed(cam.real, mmask) & observed(refl, mmask)
        try:
            s = mirror_sighting(K, cam.real[..., :2], refl[..., :2], mask, sk,
                                np.flatnonzero(mmask), height, seed=seed, name=f"{cam.name}/{m}")
        except DegenerateGeometryError:
            return None
        mirrors.append(Mirror(m, s.normal, s.distance))
        planes.append((s.normal, s.distance))
        views.append(View(m, cam.name, m, refl[..., :2], mask))
    camera = Camera(cam.name, K, estimate_focal=True)
    rig = Rig(cameras=(camera,), mirrors=tuple(mirrors), views=tuple(views), skeleton=sk,
              frame_ids=np.asarray(obs.frame_ids), joints=np.flatnonzero(dmask | mmask))
    opts = RefineOptions()
    try:
        rig2, _, record = focal_search(rig, [v.mask for v in views], [np.eye(4)], planes, opts,
                                       replace(single_mirror_config(opts), first_rejection=False),
                                       None)
    except DegenerateGeometryError:
        return None
    f = float(record["focal_px"])
    fs = record["candidates_px"]
    return f if min(fs) * 1.02 < f < max(fs) / 1.02 else None


def _focal_by_resection(X: np.ndarray, ok: np.ndarray, person: np.ndarray, dmask: np.ndarray,
                        K0: np.ndarray, fov_deg: tuple[float, float], seed: int,
                        threshold_px: float = 8.0) -> float | None:
    """The focal length (px) whose PnP pose reprojects the 3D joints ``X`` ``(T, J, 3)``
    (``ok``: ``(T, J)``) best onto this camera's ``person`` ``(T, J, 3)``; ``None`` with
    under :data:`MIN_CORRESPONDENCES` of them."""
    m = ok & observed(person, dmask)
    if np.count_nonzero(m) < MIN_CORRESPONDENCES:
        return None
    obj = np.ascontiguousarray(X[m], dtype=np.float64)
    img = np.ascontiguousarray(person[..., :2][m], dtype=np.float64)

    def cost(f: float) -> float:
        K = _with_focal(K0, f)
        cv2.setRNGSeed(int(seed))
        good, rvec, tvec, _ = cv2.solvePnPRansac(obj, img, K, None, iterationsCount=200,
                                                 reprojectionError=threshold_px,
                                                 flags=cv2.SOLVEPNP_EPNP)
        if not good:
            return np.inf
        proj, _ = cv2.projectPoints(obj, rvec, tvec, K, None)
        r2 = np.sum((proj.reshape(-1, 2) - img) ** 2, axis=1)
        return float(np.mean(np.minimum(r2, (3.0 * threshold_px) ** 2)))

    fov = np.radians(np.geomspace(fov_deg[1], fov_deg[0], 31))
    fs = float(K0[0, 2]) / np.tan(0.5 * fov)
    costs = np.array([cost(f) for f in fs])
    if not np.isfinite(costs).any():
        return None
    i = int(np.argmin(costs))
    return golden_section_min(cost, fs[max(i - 1, 0)], fs[min(i + 1, len(fs) - 1)], iterations=25)
