"""3D motion out as BVH (Biovision hierarchy), for animation tools and game engines.

:func:`write_bvh` turns 3D joints over time into a skeleton with one constant length per
bone and one rotation per joint and frame.

Hierarchy, from the canonical joint names of any layout of :mod:`mirrorgraph.skeletons`:
the root is the mid-hip (``CHip`` / ``Hip`` as Pose2Sim names it, else ``Hips``, the
midpoint of the hips); under it the legs and the spine to the neck, under the neck the
arms, the nose and the head top. Joints carry Pose2Sim's marker names
(:func:`mirrorgraph.io.motion.trc_marker_names`); a joint with several children has one
zero-length joint per child, ``<joint>To<child>``; leaves end in an ``End Site``; a
joint never estimated is left out with what hangs from it.

Motion:

* axes: the ``.trc``'s, Y up, ``(X, Y, Z) = (z, -y, x)`` of the real camera frame
  (:data:`mirrorgraph.io.motion.TRC_FROM_CAMERA`); lengths in metres;
* channels: root ``Xposition Yposition Zposition Zrotation Xrotation Yrotation``, other
  joints ``Zrotation Xrotation Yrotation``, ``R = Rz Rx Ry`` in degrees;
* rest pose: a T-pose facing -X, bone offsets the median lengths over the frames;
* rotations: shortest arc for a joint with one child, Kabsch for several; joint
  positions differ from the data by the bones' length changes only;
* frames evenly spaced (:func:`mirrorgraph.io.motion.regular_frames`), gaps interpolated
  linearly; ``Frame Time`` is ``step / fps``.

Reference: Meredith and Maddock, "Motion capture file formats explained" (2001); the
conventions of :mod:`mirrorgraph.io.bvh`; in full: ``docs/internals.md``.
"""

from __future__ import annotations

import io
import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import InputError
from .atomic import atomic_write_text

__all__ = ["BvhSkeleton", "bvh_skeleton", "write_bvh"]

#: Rest-pose axes (``.trc`` axes): up, the subject's left, forward (facing -X).
_UP, _LEFT, _FWD = np.eye(3)[1], np.eye(3)[2], -np.eye(3)[0]

#: Parent of each canonical joint, by the joint's name without ``left_`` / ``right_``;
#: ``"<root>"`` and ``"<neck>"`` are the root and the neck, present or midpoints.
_PARENT = {
    "hip": "<root>", "knee": "hip", "ankle": "knee", "heel": "ankle", "big_toe": "ankle",
    "small_toe": "ankle",
    "neck": "<root>", "shoulder": "<neck>", "elbow": "shoulder", "wrist": "elbow",
    "pinky": "wrist", "index": "wrist", "thumb": "wrist",
    "nose": "<neck>", "head_top": "<neck>",
    "eye": "nose", "eye_inner": "nose", "eye_outer": "nose", "ear": "nose", "mouth": "nose",
}

#: Parents on the same side as their children (the others are on the midline).
_SIDED = {"hip", "knee", "ankle", "shoulder", "elbow", "wrist"}

#: Rest direction of the bone ending at a joint: coefficients of (up, side * left, forward).
_REST = {
    "hip": (0, 1, 0), "knee": (-1, 0, 0), "ankle": (-1, 0, 0), "heel": (-1, 0, -1),
    "big_toe": (-0.3, 0, 1), "small_toe": (-0.3, 0.3, 1),
    "neck": (1, 0, 0), "shoulder": (0, 1, 0), "elbow": (0, 1, 0), "wrist": (0, 1, 0),
    "pinky": (0, 1, 0), "index": (0, 1, 0), "thumb": (0, 1, 0.3),
    "nose": (1, 0, 1), "head_top": (1, 0, 0),
    "eye": (0.5, 0.5, 0), "eye_inner": (0.5, 0.3, 0), "eye_outer": (0.5, 0.7, 0),
    "ear": (0, 1, -0.5), "mouth": (-0.5, 0.3, 0),
}


def _split(name: str) -> tuple[int, str]:
    """``left_knee -> (+1, "knee")``, ``right_knee -> (-1, "knee")``, ``nose -> (0, "nose")``."""
    for prefix, side in (("left_", 1), ("right_", -1)):
        if name.startswith(prefix):
            return side, name[len(prefix):]
    return 0, name


def _rest_direction(name: str) -> np.ndarray:
    side, part = _split(name)
    up, left, fwd = _REST[part]
    v = up * _UP + side * left * _LEFT + fwd * _FWD
    return v / np.linalg.norm(v)


@dataclass
class BvhSkeleton:
    """A BVH hierarchy and the points that drive it.

    Attributes:
        names: ``(N,)`` node names, parents before children.
        parents: ``(N,)`` parent index, ``-1`` for the root.
        points: ``(N,)`` index into :attr:`point_names` of the point each node sits at
            (a zero-length joint sits at its parent's point).
        rest: ``(N, 3)`` unit rest direction of the bone from the parent to the node
            (zero for the root and zero-length joints).
        point_names: the canonical names of the points (``"<root>"``, ``"<neck>"`` where
            they are midpoints).
    """

    names: list[str] = field(default_factory=list)
    parents: list[int] = field(default_factory=list)
    points: list[int] = field(default_factory=list)
    rest: list[np.ndarray] = field(default_factory=list)
    point_names: list[str] = field(default_factory=list)

    def add(self, name: str, parent: int, point: int, rest: np.ndarray) -> int:
        self.names.append(name)
        self.parents.append(parent)
        self.points.append(point)
        self.rest.append(np.asarray(rest, float))
        return len(self.names) - 1

    def children(self, node: int) -> list[int]:
        return [i for i, p in enumerate(self.parents) if p == node]


def _points(X: np.ndarray, ok: np.ndarray, names: list[str]):
    """The hierarchy's points: the joints by name plus the root and neck (the mid-hip and
    neck, or midpoints). Returns ``{name: ((T, 3), (T,) valid)}``."""
    idx = {n: i for i, n in enumerate(names)}
    pts = {n: (X[:, i], ok[:, i]) for n, i in idx.items()}

    def mid(a: str, b: str):
        if a in idx and b in idx:
            return 0.5 * (X[:, idx[a]] + X[:, idx[b]]), ok[:, idx[a]] & ok[:, idx[b]]
        return None

    root = pts.get("mid_hip") or mid("left_hip", "right_hip")
    if root is None or not root[1].any():
        raise InputError("a BVH needs the hips (left_hip and right_hip, or mid_hip) in at "
                         "least one frame", field="joints3d")
    pts["<root>"] = root
    neck = pts.get("neck") or mid("left_shoulder", "right_shoulder")
    if neck is not None:
        pts["<neck>"] = neck
    return pts


def bvh_skeleton(joint_names: Sequence[str], present: set[str]) -> BvhSkeleton:
    """The hierarchy of a layout (see the module docstring).

    Args:
        joint_names: canonical joint names of the layout.
        present: the points with data (joint names, ``"<root>"``, ``"<neck>"``).
    """
    from .motion_base import trc_marker_names

    names = [str(n) for n in joint_names]
    marker = dict(zip(names, trc_marker_names(names)))
    marker["<root>"] = marker.get("mid_hip", "Hips")
    marker["<neck>"] = marker.get("neck", "Neck")
    kids: dict[str, list[str]] = {}
    for n in names:
        if n in ("mid_hip",) or n not in present:
            continue
        side, part = _split(n)
        if part not in _PARENT:
            continue                      # a point of no known place in the body
        parent = _PARENT[part]
        if part == "neck":
            n = "<neck>"
        elif parent in _SIDED:
            parent = ("left_" if side > 0 else "right_") + parent
        kids.setdefault(parent, []).append(n)
    if "<neck>" in present and "<neck>" not in kids.get("<root>", []):
        kids.setdefault("<root>", []).append("<neck>")
    sk = BvhSkeleton(point_names=sorted(present))
    pindex = {n: i for i, n in enumerate(sk.point_names)}

    def emit(point: str, parent: int, rest: np.ndarray) -> None:
        node = sk.add(marker[point], parent, pindex[point], rest)
        below = [k for k in kids.get(point, []) if k in present]
        if len(below) == 1:
            emit(below[0], node, _rest_direction(_canonical(below[0])))
        elif below:
            for k in below:
                branch = sk.add(f"{marker[point]}To{marker[k]}", node, pindex[point], np.zeros(3))
                emit(k, branch, _rest_direction(_canonical(k)))

    emit("<root>", -1, np.zeros(3))
    return sk


def _canonical(point: str) -> str:
    return "neck" if point == "<neck>" else point


def _fill(P: np.ndarray, ok: np.ndarray, t: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """``(T', 3)``: the valid samples of ``P`` at times ``t`` interpolated at ``rows``."""
    return np.stack([np.interp(rows, t[ok], P[ok, a]) for a in range(3)], axis=-1)


def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    good = n[..., 0] > 1e-12
    return np.where(good[..., None], v / np.where(good[..., None], n, 1.0), 0.0), good


def _swing(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(T, 3, 3)`` shortest-arc rotations turning the unit ``a`` ``(3,)`` onto the unit
    ``b`` ``(T, 3)`` (a half turn about an axis normal to ``a`` where they are opposite)."""
    axis = np.cross(a, b)
    s = np.linalg.norm(axis, axis=-1)
    c = b @ a
    angle = np.arctan2(s, c)
    perp = np.cross(a, np.eye(3)[np.argmin(np.abs(a))])
    perp /= np.linalg.norm(perp)
    unit_axis = np.where((s > 1e-12)[:, None], axis / np.maximum(s, 1e-300)[:, None], perp)
    return Rotation.from_rotvec(unit_axis * angle[:, None]).as_matrix()


def _kabsch(rest: np.ndarray, target: np.ndarray) -> np.ndarray:
    """``(T, 3, 3)`` rotations ``R`` minimising ``sum_k |R rest_k - target_tk|^2``;
    ``rest`` ``(K, 3)``, ``target`` ``(T, K, 3)``."""
    M = np.einsum("tki,kj->tij", target, rest)
    U, _, Vt = np.linalg.svd(M)
    d = np.sign(np.linalg.det(U @ Vt))
    d[d == 0] = 1.0
    U[:, :, 2] *= d[:, None]
    return U @ Vt


def solve_bvh(joints3d: np.ndarray, valid: np.ndarray, frame_ids: np.ndarray,
              joint_names: Sequence[str]):
    """The BVH of joints (in the ``.trc`` axes, metres): hierarchy, offsets, motion.

    Args:
        joints3d: ``(T, J, 3)`` joints, ``.trc`` axes, metres.
        valid: ``(T, J)`` bool.
        frame_ids: ``(T,)`` increasing frame numbers.
        joint_names: ``(J,)`` canonical names.

    Returns:
        ``(skeleton, offsets (N, 3), root (T', 3), local (T', N, 3, 3), rows, step)``:
        the rotations relative to the parent, on the evenly spaced frames ``rows``.
    """
    from .motion_base import regular_frames

    names = [str(n) for n in joint_names]
    ids = np.asarray(frame_ids, dtype=np.int64)
    rows, step = regular_frames(ids)
    raw = _points(joints3d, valid, names)
    present = {n for n, (_, ok) in raw.items() if ok.any()}
    sk = bvh_skeleton(names, present)
    P = np.stack([_fill(*raw[n], ids, rows) for n in sk.point_names], axis=1)  # (T', K, 3)
    N, T = len(sk.names), len(rows)
    offsets = np.zeros((N, 3))
    for i, (par, rest) in enumerate(zip(sk.parents, sk.rest)):
        if par < 0 or not rest.any():
            continue
        a, b = sk.point_names[sk.points[par]], sk.point_names[sk.points[i]]
        both = raw[a][1] & raw[b][1]
        lengths = np.linalg.norm(raw[b][0] - raw[a][0], axis=-1)
        offsets[i] = rest * float(np.median(lengths[both] if both.any() else
                                            np.linalg.norm(P[:, sk.points[i]]
                                                           - P[:, sk.points[par]], axis=-1)))
    G = np.zeros((N, T, 3, 3))
    local = np.zeros((T, N, 3, 3))
    # parents before children: one pass; a zero-length joint has one child, whose bone
    # it swings into place
    for i in range(N):
        Gp = G[sk.parents[i]] if sk.parents[i] >= 0 else np.broadcast_to(np.eye(3), (T, 3, 3))
        kids = sk.children(i)
        targets, rests = [], []
        for k in kids:
            # the bone of child k (or of the child below the zero-length joint k)
            leaf = k if sk.rest[k].any() else sk.children(k)[0]
            u, good = _unit(P[:, sk.points[leaf]] - P[:, sk.points[i]])
            v = np.einsum("tji,tj->ti", Gp, u)        # G_p^T u: in the parent's frame
            rest = sk.rest[leaf]
            v = np.where(good[:, None], v, rest)       # a zero-length bone: keep the rest
            targets.append(v)
            rests.append(rest)
        if len(kids) == 1:
            L = _swing(rests[0], targets[0])
        elif kids:
            L = _kabsch(np.array(rests), np.stack(targets, axis=1))
        else:
            L = np.broadcast_to(np.eye(3), (T, 3, 3))
        local[:, i] = L
        G[i] = Gp @ L
    root = P[:, sk.points[0]]
    return sk, offsets, root, local, rows, step


def write_bvh(path: str | os.PathLike, joints3d: np.ndarray, valid: np.ndarray | None,
              frame_ids: np.ndarray | None, joint_names: Sequence[str], fps: float | None,
              unit: str = "m") -> None:
    """Write 3D joints as BVH (metres, Y up; see the module docstring).

    Args:
        path: the ``.bvh`` file to write (atomically).
        joints3d: ``(T, J, 3)`` joints, real camera frame (or a rig's world frame).
        valid: ``(T, J)`` bool joints to use (``None``: every finite one).
        frame_ids: ``(T,)`` increasing frame numbers (``None``: ``0 .. T-1``).
        joint_names: ``(J,)`` canonical joint names.
        fps: frame rate of the frame numbers, Hz (required).
        unit: ``m``, ``cm`` or ``mm`` (anything else is refused).

    Raises:
        InputError: no frame rate, a non-metric unit, no hips in any frame.
    """
    from .motion_base import check_arrays, metres_factor, to_trc_axes

    X, ok, ids, names, fps = check_arrays(joints3d, valid, frame_ids, joint_names, fps)
    if fps is None:
        raise InputError("a .bvh file needs the frame rate", source=path, field="fps")
    if not len(ids):
        raise InputError("no frame to write", source=path, field="joints3d")
    factor = metres_factor(unit, path)
    Y = factor * to_trc_axes(np.where(ok[..., None], X, 0.0))
    try:
        sk, offsets, root, local, _, step = solve_bvh(Y, ok, ids, names)
    except InputError as exc:
        raise InputError(str(exc.args[0]) if exc.args else str(exc), source=path,
                         field="joints3d") from None
    atomic_write_text(path, _bvh_text(sk, offsets, root, local, step / fps))


def _bvh_text(sk: BvhSkeleton, offsets: np.ndarray, root: np.ndarray, local: np.ndarray,
              frame_time: float) -> str:
    lines = ["HIERARCHY"]

    def node(i: int, depth: int) -> None:
        pad = "  " * depth
        o = offsets[i]
        lines.append(f"{pad}{'ROOT' if depth == 0 else 'JOINT'} {sk.names[i]}")
        lines.append(pad + "{")
        lines.append(f"{pad}  OFFSET {o[0]:.6f} {o[1]:.6f} {o[2]:.6f}")
        lines.append(f"{pad}  CHANNELS " + ("6 Xposition Yposition Zposition " if depth == 0
                                            else "3 ") + "Zrotation Xrotation Yrotation")
        kids = sk.children(i)
        for k in kids:
            node(k, depth + 1)
        if not kids:
            lines.append(f"{pad}  End Site")
            lines.append(pad + "  {")
            lines.append(f"{pad}    OFFSET 0.000000 0.000000 0.000000")
            lines.append(pad + "  }")
        lines.append(pad + "}")

    node(0, 0)
    T, N = local.shape[:2]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # gimbal lock: the angles still compose to R
        euler = Rotation.from_matrix(local.reshape(-1, 3, 3)).as_euler("ZXY", degrees=True)
    order = [0] + [i for i in _depth_first(sk) if i != 0]
    values = np.concatenate([root, euler.reshape(T, N, 3)[:, order].reshape(T, -1)], axis=1)
    buf = io.StringIO()
    np.savetxt(buf, values, fmt="%.6f")
    lines += ["MOTION", f"Frames: {T}", f"Frame Time: {frame_time:.8f}"]
    return "\n".join(lines) + "\n" + buf.getvalue()


def _depth_first(sk: BvhSkeleton) -> list[int]:
    """Nodes in the order the hierarchy lists them (their channels' order)."""
    out: list[int] = []

    def walk(i: int) -> None:
        out.append(i)
        for k in sk.children(i):
            walk(k)
    walk(0)
    return out
