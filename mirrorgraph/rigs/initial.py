"""The initial rig: pairwise estimates chained along a spanning tree.

1. Every pair of cameras that sees the person (and reflections) in common frames
   gets a relative pose (:func:`~mirrorgraph.rigs.relative.relative_pose`), every
   camera-mirror pair a plane (:func:`~mirrorgraph.rigs.relative.mirror_sighting`).
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

from dataclasses import dataclass, field

import numpy as np

from ..errors import DegenerateGeometryError
from ..keypoints import DEFAULT_MIN_CONFIDENCE
from .observations import RigObservations
from .relative import MIN_CORRESPONDENCES, MirrorSighting, RelativePose, mirror_sighting, relative_pose

__all__ = ["InitialRig", "initialise_rig", "observed", "joint_masks", "MIN_CONFIDENCE"]

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
    """

    poses: list[np.ndarray]
    planes: dict[str, tuple[np.ndarray, float]]
    edges: dict[tuple[str, str], RelativePose] = field(default_factory=dict)
    sightings: dict[tuple[str, str], MirrorSighting] = field(default_factory=dict)
    tree: list[tuple[str, str]] = field(default_factory=list)
    mirror_spread_deg: dict[str, float] = field(default_factory=dict)


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
                   joints: tuple[np.ndarray, np.ndarray] | None = None) -> InitialRig:
    """Initial poses and planes (see the module docstring).

    Args:
        obs: the sorted observations.
        height: the subject's height in the output unit (metres, or 1).
        seed: RANSAC seed.
        joints: ``(direct, mirror)`` joint indices used in the direct views and through
            mirrors (:func:`~mirrorgraph.joint_sets.resolve_joints`; default: the
            calibration joints in both).

    Raises:
        DegenerateGeometryError: a camera cannot be chained, a mirror not estimated.
    """
    sk = obs.skeleton
    dmask, mmask = joint_masks(sk, joints)
    direct, through = np.flatnonzero(dmask), np.flatnonzero(mmask)
    cams = obs.cameras
    C = len(cams)

    sightings: dict[tuple[str, str], MirrorSighting] = {}
    for cam in cams:
        for m, refl in cam.reflections.items():
            mask = observed(cam.real, mmask) & observed(refl, mmask)
            sightings[(cam.name, m)] = mirror_sighting(
                cam.intrinsics.K, cam.real[..., :2], refl[..., :2], mask, sk, through, height,
                seed=seed, name=f"{cam.name}/{m}")

    edges: dict[tuple[str, str], RelativePose] = {}
    for a in range(C):
        for b in range(a + 1, C):
            ca, cb = cams[a], cams[b]
            sets_a, sets_b = [ca.real], [cb.real]
            for m in set(ca.reflections) & set(cb.reflections):
                sets_a.append(ca.reflections[m])
                sets_b.append(cb.reflections[m])
            ua, ub = np.stack(sets_a), np.stack(sets_b)
            masks = np.stack([dmask] + [mmask] * (len(sets_a) - 1))[:, None, :]
            mask = observed(ua, masks) & observed(ub, masks)
            rel = relative_pose(ca.intrinsics.K, cb.intrinsics.K, ua[..., :2], ub[..., :2],
                                mask, sk, direct, height, seed=seed)
            if rel is not None:
                edges[(ca.name, cb.name)] = rel

    # Prim's maximum spanning tree from camera 0
    poses: list[np.ndarray | None] = [None] * C
    poses[0] = np.eye(4)
    placed, tree = {0}, []
    index = {c.name: i for i, c in enumerate(cams)}
    while len(placed) < C:
        best = None
        for (na, nb), rel in edges.items():
            a, b = index[na], index[nb]
            if (a in placed) == (b in placed):
                continue
            if best is None or rel.inliers > best[2].inliers:
                best = (a, b, rel)
        if best is None:
            missing = [cams[i].name for i in range(C) if i not in placed]
            raise DegenerateGeometryError(
                f"camera(s) {', '.join(missing)} share too few joints (fewer than "
                f"{MIN_CORRESPONDENCES} consistent ones) with camera {cams[0].name} and the "
                "cameras linked to it: they cannot be placed (is the person visible in them at "
                "the same frames? are the frame offsets right?)")
        a, b, rel = best
        T_ab = rel.pose_b_in_a                       # b's pose in a's frame
        if a in placed:
            poses[b] = poses[a] @ T_ab
            placed.add(b)
            tree.append((cams[a].name, cams[b].name))
        else:
            poses[a] = poses[b] @ np.linalg.inv(T_ab)
            placed.add(a)
            tree.append((cams[b].name, cams[a].name))

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
    return InitialRig(poses=[np.asarray(p) for p in poses], planes=planes, edges=edges,
                      sightings=sightings, tree=tree, mirror_spread_deg=spread)
