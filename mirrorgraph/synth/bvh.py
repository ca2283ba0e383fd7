"""Motion capture (BVH) as motion for synthetic scenes.

Two layers:

1. A BVH reader, :func:`read_bvh` / :func:`parse_bvh` -> :class:`BvhMotion`:
   the ``HIERARCHY`` (``ROOT``, ``JOINT``, ``End Site``, ``OFFSET``,
   ``CHANNELS`` in any order and any subset of ``Xposition Yposition Zposition
   Xrotation Yrotation Zrotation``, several roots allowed) and the ``MOTION``
   section (``Frames:``, ``Frame Time:``, one line of channel values per frame).
   Malformed input raises :class:`mirrorgraph.errors.InputError` naming the file
   and the line. :meth:`BvhMotion.forward_kinematics` computes the world
   positions and rotations of every joint and end site, vectorised over frames;
   :meth:`BvhMotion.resample` changes the frame rate.

2. The bridge to :mod:`mirrorgraph.synth`: :func:`body_joints` maps a CMU
   skeleton to the 25 joints of the synthetic body model
   (:data:`~mirrorgraph.synth.body.FULL_JOINTS`; the mapping is in its
   docstring); :func:`skeleton_height` measures the skeleton's standing
   height; :func:`load_motion` drops a leading reference pose, resamples,
   maps, scales to metres (CMU: ``units x 0.0254 / 0.45``) and puts the floor
   at ``y = 0`` (:class:`MocapMotion`); :meth:`MocapMotion.clip` cuts a number
   of frames (back and forth when the take is shorter) and moves them into the
   body frame of :func:`~mirrorgraph.synth.motion.generate_motion` (``x``
   left, ``y`` up, ``z`` forward, the person over the origin and facing ``+z``
   in the first frame); :func:`motion_for_scene` returns that in units of
   height for :func:`~mirrorgraph.synth.make_scene` (``motion=...``).

   The CMU skeleton's rest pose already stands in that frame (Y up, the left
   hip at ``+x``, the toes towards ``+z``), so only a turn about ``y`` and a
   shift are needed; a skeleton whose head is not above its hips in the rest
   pose is refused.

BVH conventions (as Biovision defines them)
-------------------------------------------

* ``OFFSET`` is the joint's position in its parent's frame when every rotation
  is zero (the rest pose); the rest pose of every joint frame is aligned with
  the world frame.
* A joint's local transform is ``T(offset + p) R`` where ``p`` holds the
  position channels (zero when absent; for the root ``offset + p`` is the world
  position of the root, the offset being usually zero) and
  ``R = R_a1(v1) R_a2(v2) R_a3(v3)`` is the product of the elementary rotations
  in the order the rotation channels are *listed* (``Zrotation Xrotation
  Yrotation`` gives ``Rz Rx Ry``): intrinsic Euler angles, in degrees.
  ``R_x, R_y, R_z`` are the right-handed rotations about the axes.
* World transforms compose from the root: ``G_j = G_parent(j) L_j``; a joint's
  own rotation moves its children, not itself.
* An ``End Site`` has an offset and no channels; here it becomes a node named
  ``"<parent>_EndSite"``.

Resampling (:meth:`BvhMotion.resample`): the new frames are at times
``k / fps`` from the first frame, up to the last one. Each sample interpolates
between the two nearest source frames: the local rotations of every joint on
the shortest arc (spherical linear interpolation of rotation matrices), the
translations linearly; the positions follow by forward kinematics, so bones
stay exactly rigid. A sample that falls on a source frame (e.g. 120 -> 30 fps:
every 4th frame) is that frame exactly. There is no low-pass averaging. The
frame rate is ``1 / Frame Time`` snapped to an integer within 0.01 % (files write
``.0083333`` for 120 fps).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError

_AXES = {"x": 0, "y": 1, "z": 2}
_CHANNEL_NAMES = {f"{a}{kind}": (kind, _AXES[a]) for a in "xyz"
                  for kind in ("position", "rotation")}
END_SITE_SUFFIX = "_EndSite"


# --------------------------------------------------------------------------- data
@dataclass(frozen=True)
class BvhMotion:
    """A parsed BVH file.

    Nodes (joints and end sites) are listed parents first, in file order.

    Attributes:
        source: the file read (or the name given to :func:`parse_bvh`).
        names: ``(N,)`` node names; an end site is ``"<parent>_EndSite"``.
        parents: ``(N,)`` int index of each node's parent, ``-1`` for a root.
        offsets: ``(N, 3)`` rest-pose offsets from the parent, file units.
        channels: per node, its channel names in file order, normalised to
            ``"Xposition"`` ... ``"Zrotation"`` (empty for end sites).
        channel_start: ``(N,)`` column of each node's first channel in ``values``.
        end_site: ``(N,)`` bool, the node is an end site.
        frame_time: seconds per frame.
        values: ``(F, C)`` channel values per frame (degrees for rotations).
    """

    source: str
    names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    channel_start: np.ndarray
    end_site: np.ndarray
    frame_time: float
    values: np.ndarray
    _index: dict[str, int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_index", {n: i for i, n in enumerate(self.names)})

    def __repr__(self) -> str:
        joints = int((~self.end_site).sum())
        return (f"BvhMotion({self.source!r}, {joints} joints, {self.frames} frames at "
                f"{self.fps:g} fps)")

    @property
    def frames(self) -> int:
        """Number of frames ``F``."""
        return int(self.values.shape[0])

    @property
    def fps(self) -> float:
        """Frame rate: ``1 / frame_time``, snapped to the nearest integer when within 0.01 %.

        Files write the frame time with few digits (``.0083333`` for 120 fps); the
        snap keeps resampling to 30 fps an exact pick of every 4th frame.
        """
        f = 1.0 / self.frame_time
        r = round(f)
        return float(r) if r > 0 and abs(f - r) <= 1e-4 * r else f

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the joints (end sites left out)."""
        return tuple(n for n, e in zip(self.names, self.end_site) if not e)

    def index(self, name: str) -> int:
        """Index of a node by name (``KeyError`` if absent)."""
        return self._index[name]

    def has(self, name: str) -> bool:
        """Whether the file has a node of this name."""
        return name in self._index

    def children(self, name: str) -> list[str]:
        """Names of the direct children of a node."""
        i = self._index[name]
        return [self.names[k] for k in np.flatnonzero(self.parents == i)]

    # ----------------------------------------------------------------- kinematics
    def local_transforms(self, values: np.ndarray | None = None
                         ) -> tuple[np.ndarray, np.ndarray]:
        """Local rotations ``(F, N, 3, 3)`` and translations ``(F, N, 3)`` of every node.

        ``values`` defaults to :attr:`values` (``(F, C)`` channel values).
        """
        v = self.values if values is None else np.asarray(values, dtype=float)
        F, N = v.shape[0], len(self.names)
        R = np.broadcast_to(np.eye(3), (F, N, 3, 3)).copy()
        t = np.broadcast_to(self.offsets, (F, N, 3)).copy()
        for j, chans in enumerate(self.channels):
            c0 = int(self.channel_start[j])
            for k, ch in enumerate(chans):
                kind, axis = _CHANNEL_NAMES[ch.lower()]
                col = v[:, c0 + k]
                if kind == "position":
                    t[:, j, axis] += col
                else:
                    R[:, j] = R[:, j] @ axis_rotation(axis, np.radians(col))
        return R, t

    def forward_kinematics(self, values: np.ndarray | None = None
                           ) -> tuple[np.ndarray, np.ndarray]:
        """World positions ``(F, N, 3)`` (file units) and rotations ``(F, N, 3, 3)``."""
        return self._fk(*self.local_transforms(values))

    def positions(self, values: np.ndarray | None = None) -> np.ndarray:
        """World positions ``(F, N, 3)`` of every node, in file units."""
        return self.forward_kinematics(values)[0]

    def _fk(self, R: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        G = np.empty_like(R)
        P = np.empty_like(t)
        for j, p in enumerate(self.parents):
            if p < 0:
                G[:, j] = R[:, j]
                P[:, j] = t[:, j]
            else:
                G[:, j] = G[:, p] @ R[:, j]
                P[:, j] = P[:, p] + np.einsum("fij,fj->fi", G[:, p], t[:, j])
        return P, G

    def rest_positions(self) -> np.ndarray:
        """``(N, 3)`` positions in the rest pose (all channels zero), file units."""
        return self.positions(np.zeros((1, self.values.shape[1])))[0]

    # ----------------------------------------------------------------- editing
    def select(self, frames: Any) -> "BvhMotion":
        """A copy with only the given frames (a slice or index array)."""
        v = self.values[frames]
        if v.ndim != 2 or len(v) == 0:
            raise ValueError("the selection must keep at least one frame")
        return replace(self, values=np.ascontiguousarray(v))

    def resample(self, fps: float) -> tuple[np.ndarray, np.ndarray]:
        """World positions and rotations at ``fps`` (see the module docstring).

        Returns:
            ``(positions (F', N, 3), rotations (F', N, 3, 3))`` with
            ``F' = floor((F - 1) * fps / self.fps) + 1`` frames at times ``k / fps``.
        """
        if not fps > 0:
            raise ValueError(f"fps must be positive, got {fps}")
        R, t = self.local_transforms()
        s = resample_times(self.frames, self.fps, fps)
        i0 = np.floor(s).astype(int)
        i0 = np.minimum(i0, self.frames - 1)
        u = s - i0
        i1 = np.minimum(i0 + 1, self.frames - 1)
        exact = u < 1e-9
        Ri = R[i0].copy()
        ti = t[i0].copy()
        m = ~exact
        if m.any():
            uu = u[m]
            ti[m] = t[i0[m]] * (1.0 - uu)[:, None, None] + t[i1[m]] * uu[:, None, None]
            Ri[m] = slerp_matrices(R[i0[m]], R[i1[m]], uu[:, None])
        return self._fk(Ri, ti)


def resample_times(frames: int, fps_in: float, fps_out: float) -> np.ndarray:
    """Source-frame coordinates ``(F',)`` of the samples at ``fps_out``.

    Sample ``k`` is at time ``k / fps_out``, i.e. at source frame ``k fps_in / fps_out``;
    samples run up to the last source frame (rounding within ``1e-9`` frames).
    """
    ratio = float(fps_in) / float(fps_out)
    n = int(np.floor((frames - 1) / ratio + 1e-9)) + 1
    s = np.arange(n) * ratio
    return np.minimum(s, frames - 1)


# --------------------------------------------------------------------------- rotations
def axis_rotation(axis: int, angle: np.ndarray) -> np.ndarray:
    """Right-handed rotations ``(..., 3, 3)`` by ``angle`` (radians) about axis 0/1/2."""
    a = np.asarray(angle, dtype=float)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R[..., axis, axis] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., i, j] = -s
    R[..., j, i] = s
    return R


def _log_so3(R: np.ndarray) -> np.ndarray:
    """Rotation vectors ``(..., 3)`` of rotations ``(..., 3, 3)`` (angle in [0, pi])."""
    tr = np.clip((np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    ang = np.arccos(tr)
    w = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                  R[..., 1, 0] - R[..., 0, 1]], -1)
    s = np.sin(ang)
    small = s < 1e-6
    scale = np.where(small, 0.5, ang / (2.0 * np.where(small, 1.0, s)))
    out = w * scale[..., None]
    # near pi the antisymmetric part vanishes: take the axis from R + I
    big = small & (ang > 1.0)
    if np.any(big):
        B = R[big] + np.eye(3)
        col = np.argmax(np.linalg.norm(B, axis=-2), -1)
        axis = B[np.arange(len(B)), :, col]
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        out[big] = axis * ang[big][..., None]
    return out


def _exp_so3(w: np.ndarray) -> np.ndarray:
    """Rotations ``(..., 3, 3)`` of rotation vectors ``(..., 3)`` (Rodrigues)."""
    ang = np.linalg.norm(w, axis=-1)
    safe = np.where(ang < 1e-12, 1.0, ang)
    k = w / safe[..., None]
    Kx = np.zeros(w.shape[:-1] + (3, 3))
    Kx[..., 0, 1], Kx[..., 0, 2] = -k[..., 2], k[..., 1]
    Kx[..., 1, 0], Kx[..., 1, 2] = k[..., 2], -k[..., 0]
    Kx[..., 2, 0], Kx[..., 2, 1] = -k[..., 1], k[..., 0]
    s = np.sin(ang)[..., None, None]
    c = np.cos(ang)[..., None, None]
    return np.eye(3) + s * Kx + (1.0 - c) * (Kx @ Kx)


def slerp_matrices(R0: np.ndarray, R1: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Rotations a fraction ``u`` of the way from ``R0`` to ``R1`` on the shortest arc."""
    w = _log_so3(np.swapaxes(R0, -1, -2) @ R1)
    return R0 @ _exp_so3(w * np.asarray(u, dtype=float)[..., None])


# --------------------------------------------------------------------------- parser
class _Tokens:
    """Whitespace-separated tokens of the hierarchy with their 1-based line numbers."""

    def __init__(self, lines: list[str], source: str) -> None:
        self.source = source
        self.items: list[tuple[str, int]] = []
        self.pos = 0
        self.lines = lines

    def fail(self, message: str, line: int | None = None) -> InputError:
        if line is None:
            line = self.items[min(self.pos, len(self.items) - 1)][1] if self.items else 1
        return InputError(f"line {line}: {message}", source=self.source)

    def peek(self) -> tuple[str, int] | None:
        return self.items[self.pos] if self.pos < len(self.items) else None

    def next(self, what: str) -> tuple[str, int]:
        if self.pos >= len(self.items):
            last = self.items[-1][1] if self.items else len(self.lines)
            raise self.fail(f"unexpected end of the hierarchy, expected {what}", last)
        tok = self.items[self.pos]
        self.pos += 1
        return tok

    def expect(self, word: str) -> int:
        tok, line = self.next(repr(word))
        if tok != word:
            raise self.fail(f"expected {word!r}, got {tok!r}", line)
        return line

    def number(self, what: str) -> float:
        tok, line = self.next(what)
        try:
            x = float(tok)
        except ValueError:
            raise self.fail(f"expected a number ({what}), got {tok!r}", line) from None
        if not np.isfinite(x):
            raise self.fail(f"{what} is not finite: {tok!r}", line)
        return x


def read_bvh(path: str | os.PathLike) -> BvhMotion:
    """Read a BVH file (see :func:`parse_bvh`).

    Raises:
        InputError: the file cannot be read or is malformed (the message names
            the file and the line).
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8", errors="replace")
    except FileNotFoundError:
        raise InputError("no such BVH file", source=str(p)) from None
    except IsADirectoryError:
        raise InputError("is a folder, not a BVH file", source=str(p)) from None
    except OSError as e:
        raise InputError(f"cannot read: {e.strerror or e}", source=str(p)) from None
    return parse_bvh(text, source=str(p))


def parse_bvh(text: str, source: str = "<string>") -> BvhMotion:
    """Parse the text of a BVH file.

    Args:
        text: the whole file.
        source: name used in error messages and kept in :attr:`BvhMotion.source`.

    Raises:
        InputError: malformed hierarchy or motion (names ``source`` and the line).
    """
    lines = text.splitlines()
    # the hierarchy ends at the line that starts with MOTION
    motion_line = None
    for k, ln in enumerate(lines):
        head = ln.strip()
        if head.upper() == "MOTION" or head.upper().startswith("MOTION "):
            motion_line = k
            break
    toks = _Tokens(lines, source)
    stop = len(lines) if motion_line is None else motion_line
    for k in range(stop):
        for tok in lines[k].replace("{", " { ").replace("}", " } ").split():
            toks.items.append((tok, k + 1))
    if not toks.items:
        if motion_line is None and not text.strip():
            raise InputError("line 1: empty file, not a BVH file", source=source)
        raise toks.fail("no HIERARCHY section", 1)

    tok, line = toks.next("'HIERARCHY'")
    if tok.upper() != "HIERARCHY":
        raise toks.fail(f"a BVH file starts with 'HIERARCHY', got {tok!r}", line)

    names: list[str] = []
    parents: list[int] = []
    offsets: list[tuple[float, float, float]] = []
    channels: list[tuple[str, ...]] = []
    end_site: list[bool] = []
    seen: dict[str, int] = {}

    def node(name: str, line: int, parent: int, is_end: bool) -> None:
        if name in seen:
            raise toks.fail(f"joint name {name!r} is used twice (first on line {seen[name]})",
                            line)
        seen[name] = line
        idx = len(names)
        names.append(name)
        parents.append(parent)
        offsets.append((0.0, 0.0, 0.0))
        channels.append(())
        end_site.append(is_end)
        toks.expect("{")
        have_offset = have_channels = False
        while True:
            tok, ln = toks.next("'}'")
            key = tok.upper()
            if tok == "}":
                break
            if key == "OFFSET":
                if have_offset:
                    raise toks.fail(f"{name}: a second OFFSET", ln)
                offsets[idx] = tuple(toks.number(f"OFFSET {a} of {name}") for a in "xyz")
                have_offset = True
            elif key == "CHANNELS":
                if is_end:
                    raise toks.fail(f"End Site of {names[parent]} cannot have CHANNELS", ln)
                if have_channels:
                    raise toks.fail(f"{name}: a second CHANNELS", ln)
                ntok, nl = toks.next("the number of channels")
                try:
                    n = int(ntok)
                except ValueError:
                    raise toks.fail(f"expected the number of channels of {name}, got {ntok!r}",
                                    nl) from None
                if not 0 <= n <= 6:
                    raise toks.fail(f"{name} has {n} channels; a joint has 0 to 6", nl)
                got = []
                for _ in range(n):
                    ch, cl = toks.next(f"a channel name of {name}")
                    norm = ch.lower()
                    if norm not in _CHANNEL_NAMES:
                        raise toks.fail(
                            f"unknown channel {ch!r} of {name} (the CHANNELS line declares "
                            f"{n}; known: Xposition Yposition Zposition Xrotation Yrotation "
                            "Zrotation)", cl)
                    pretty = norm[0].upper() + norm[1:]
                    if pretty in got:
                        raise toks.fail(f"channel {ch} of {name} listed twice", cl)
                    got.append(pretty)
                channels[idx] = tuple(got)
                have_channels = True
            elif key == "JOINT":
                if is_end:
                    raise toks.fail("an End Site cannot have children", ln)
                child, cl = toks.next("a joint name")
                if child in ("{", "}"):
                    raise toks.fail("JOINT without a name", cl)
                node(child, cl, idx, False)
            elif key == "END":
                if is_end:
                    raise toks.fail("an End Site cannot have children", ln)
                site, sl = toks.next("'Site'")
                if site.upper() != "SITE":
                    raise toks.fail(f"expected 'End Site', got 'End {site}'", sl)
                node(name + END_SITE_SUFFIX, sl, idx, True)
            elif key in ("ROOT", "MOTION", "HIERARCHY"):
                raise toks.fail(f"{tok!r} inside {name}: missing '}}'", ln)
            else:
                raise toks.fail(f"unexpected {tok!r} in {name} (expected OFFSET, CHANNELS, "
                                "JOINT, End Site or '}')", ln)
        if not have_offset:
            raise toks.fail(f"{name} has no OFFSET", line)

    roots = 0
    while toks.peek() is not None:
        tok, line = toks.next("'ROOT'")
        if tok.upper() != "ROOT":
            if tok == "}":
                raise toks.fail("unbalanced '}'", line)
            raise toks.fail(f"expected 'ROOT' or 'MOTION', got {tok!r}", line)
        name, nl = toks.next("the root's name")
        node(name, nl, -1, False)
        roots += 1
    if roots == 0:
        raise toks.fail("the hierarchy has no ROOT", toks.items[-1][1])
    if motion_line is None:
        raise InputError(f"line {len(lines)}: no MOTION section after the hierarchy",
                         source=source)

    # ------------------------------------------------------------------ MOTION
    k = motion_line + 1
    header: dict[str, tuple[str, int]] = {}
    for key in ("frames", "frame time"):
        while k < len(lines) and not lines[k].strip():
            k += 1
        if k >= len(lines):
            raise InputError(f"line {len(lines)}: the MOTION section has no "
                             f"{'Frames:' if key == 'frames' else 'Frame Time:'} line",
                             source=source)
        label, _, val = lines[k].partition(":")
        if " ".join(label.split()).lower() != key or not val.strip():
            want = "Frames: N" if key == "frames" else "Frame Time: seconds"
            raise InputError(f"line {k + 1}: expected '{want}', got {lines[k].strip()!r}",
                             source=source)
        header[key] = (val.strip(), k + 1)
        k += 1
    val, ln = header["frames"]
    try:
        F = int(val)
    except ValueError:
        raise InputError(f"line {ln}: Frames must be an integer, got {val!r}",
                         source=source) from None
    if F < 1:
        raise InputError(f"line {ln}: the motion has no frames (Frames: {F})", source=source)
    val, ln = header["frame time"]
    try:
        dt = float(val)
    except ValueError:
        raise InputError(f"line {ln}: Frame Time must be a number, got {val!r}",
                         source=source) from None
    if not (np.isfinite(dt) and dt > 0):
        raise InputError(f"line {ln}: Frame Time must be positive, got {val!r}", source=source)

    counts = np.array([len(c) for c in channels], dtype=int)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int)
    C = int(counts.sum())
    data_lines = [(i + 1, lines[i]) for i in range(k, len(lines)) if lines[i].strip()]
    if len(data_lines) < F:
        last = data_lines[-1][0] if data_lines else k
        raise InputError(f"line {last}: Frames: {F} but only {len(data_lines)} frame lines "
                         f"follow", source=source)
    if len(data_lines) > F:
        raise InputError(f"line {data_lines[F][0]}: more frame lines than Frames: {F}",
                         source=source)
    rows = [ln.split() for _, ln in data_lines]
    for f, parts in enumerate(rows):
        if len(parts) != C:
            raise InputError(f"line {data_lines[f][0]}: frame {f} has {len(parts)} values, "
                             f"the hierarchy declares {C} channels", source=source)
    try:
        values = np.array(rows, dtype=float).reshape(F, C)
    except ValueError:
        values = None
    if values is None or not np.all(np.isfinite(values)):
        # find the first bad value for the message
        for f, ((num, _), parts) in enumerate(zip(data_lines, rows)):
            for p in parts:
                try:
                    x = float(p)
                except ValueError:
                    raise InputError(f"line {num}: frame {f}: {p!r} is not a number",
                                     source=source) from None
                if not np.isfinite(x):
                    raise InputError(f"line {num}: frame {f}: {p!r} is not finite",
                                     source=source)
        raise InputError("cannot read the motion values", source=source)  # pragma: no cover
    return BvhMotion(source=source, names=tuple(names), parents=np.array(parents, dtype=int),
                     offsets=np.array(offsets, dtype=float), channels=tuple(channels),
                     channel_start=starts, end_site=np.array(end_site, dtype=bool),
                     frame_time=dt, values=values)


# --------------------------------------------------------------------------- CMU -> body
#: Metres per CMU unit (the CMU ASF scale: inches / 0.45).
CMU_UNIT_M = 0.0254 / 0.45

#: File name of the CMU take shipped as package data (``mirrorgraph/data``).
CMU_EXAMPLE = "cmu_01_01.bvh"


def cmu_example_path() -> Path:
    """Path of the CMU motion-capture take shipped with mirrorgraph.

    ``mirrorgraph/data/cmu_01_01.bvh``: CMU Graphics Lab Motion Capture Database,
    subject 01, trial 01, 2,752 frames at 120 fps, CMU skeleton (the BVH conversion
    of facebookresearch/fairmotion's test data; source and licence in
    ``mirrorgraph/data/README.md``). The default take of the tests and benchmarks,
    for :func:`load_motion` and ``make_scene(motion=...)``.
    """
    from importlib.resources import files

    return Path(str(files("mirrorgraph") / "data" / CMU_EXAMPLE))


#: Roles used by :func:`body_joints` -> joint names of the CMU skeleton (as in the
#: CMU BVH conversions, e.g. ``cmu_01_01.bvh``). The toe and head roles need an
#: End Site (or a first child) under them.
CMU_JOINT_NAMES: dict[str, str] = {
    "left_hip": "LeftUpLeg", "right_hip": "RightUpLeg",
    "left_knee": "LeftLeg", "right_knee": "RightLeg",
    "left_ankle": "LeftFoot", "right_ankle": "RightFoot",
    "left_toe": "LeftToeBase", "right_toe": "RightToeBase",
    "left_shoulder": "LeftArm", "right_shoulder": "RightArm",
    "left_elbow": "LeftForeArm", "right_elbow": "RightForeArm",
    "left_wrist": "LeftHand", "right_wrist": "RightHand",
    "head": "Head",
}

#: Joint speeds above this (m/s) between the first frames are a jump to a
#: reference pose, not motion (see :func:`load_motion`).
MAX_JOINT_SPEED = 25.0


def _tip_offset(motion: BvhMotion, name: str) -> np.ndarray:
    """Rest offset of the segment that ``name`` rotates: its End Site or first child."""
    kids = [motion.index(c) for c in motion.children(name)]
    if not kids:
        raise InputError(f"joint {name!r} has no End Site or child: cannot tell the length "
                         "and direction of its segment", source=motion.source)
    ends = [k for k in kids if motion.end_site[k]]
    return motion.offsets[(ends or kids)[0]].copy()


def _resolve(motion: BvhMotion, names: dict[str, str]) -> dict[str, int]:
    missing = [f"{role} ({n!r})" for role, n in names.items() if not motion.has(n)]
    need = [r for r in CMU_JOINT_NAMES if r not in names]
    if need:
        raise ValueError(f"the joint-name map lacks the role(s) {', '.join(need)}")
    if missing:
        raise InputError("no joint for " + ", ".join(missing) + "; the file's joints are "
                         + ", ".join(motion.joint_names), source=motion.source)
    return {role: motion.index(n) for role, n in names.items()}


def skeleton_height(motion: BvhMotion, names: dict[str, str] | None = None) -> float:
    """Standing height of the skeleton in file units (floor to top of the head).

    ``(thigh + shank + height of the top of the head above the hip joints in the
    rest pose) / (1 - 0.039)``: straight vertical legs (the mean of both sides),
    the trunk and head as the rest pose holds them, the top of the head at the
    head's End Site, and the ankle above the floor by the body model's 0.039 of
    the height (a BVH skeleton has no heel).

    Raises:
        InputError: a joint is missing, or the skeleton is not Y-up (the head's
            top not above the hips in the rest pose).
    """
    from .body import EXTRA_FRACTION

    J = _resolve(motion, CMU_JOINT_NAMES if names is None else names)
    rest = motion.rest_positions()
    leg = 0.0
    for s in ("left", "right"):
        leg += np.linalg.norm(rest[J[f"{s}_knee"]] - rest[J[f"{s}_hip"]])
        leg += np.linalg.norm(rest[J[f"{s}_ankle"]] - rest[J[f"{s}_knee"]])
    leg /= 2.0
    hip_y = (rest[J["left_hip"], 1] + rest[J["right_hip"], 1]) / 2.0
    top_y = rest[J["head"], 1] + _tip_offset(motion, motion.names[J["head"]])[1]
    if not top_y - hip_y > 0.5 * leg:
        raise InputError("the top of the head is not above the hips in the rest pose: "
                         "a Y-up skeleton standing upright is expected", source=motion.source)
    return float((leg + top_y - hip_y) / (1.0 - EXTRA_FRACTION["ankle_height"]))


def body_joints(motion: BvhMotion, positions: np.ndarray, rotations: np.ndarray,
                height: float, names: dict[str, str] | None = None) -> np.ndarray:
    """The 25 joints of :data:`~mirrorgraph.synth.body.FULL_JOINTS` from BVH poses.

    Args:
        motion: the skeleton (names, offsets).
        positions: ``(F, N, 3)`` world positions of its nodes (file units).
        rotations: ``(F, N, 3, 3)`` world rotations of its nodes.
        height: the subject's standing height in file units (scales the head and
            foot points), e.g. :func:`skeleton_height`.
        names: role -> joint name (default :data:`CMU_JOINT_NAMES`).

    Returns:
        ``(F, 25, 3)`` positions in the frame and units of ``positions``.

    The mapping (``H`` = height; offsets are the body model's,
    :data:`~mirrorgraph.synth.body.HEAD_OFFSETS` and ``FOOT_OFFSETS``, given for
    the left side, mirrored in ``x`` for the right):

    * shoulders, elbows, wrists = ``LeftArm``, ``LeftForeArm``, ``LeftHand`` (and
      right); hips, knees, ankles = ``LeftUpLeg``, ``LeftLeg``, ``LeftFoot``;
    * ``neck`` = midpoint of the shoulders and ``mid_hip`` = midpoint of the hips
      (the OpenPose definitions the body model uses; the CMU ``Hips`` root lies
      about 0.1 m above the hip joints and is not used);
    * heel = ankle + ``R_foot`` (heel offset) ``H``, ``R_foot`` the world
      rotation of ``LeftFoot`` (its rest frame is the body frame, the foot
      pointing forward);
    * big toe = the toe tip (``LeftToeBase``'s End Site) moved medially by
      0.010 ``H``; small toe = ``LeftToeBase`` + a quarter of the toe segment,
      moved laterally by 0.022 ``H``; both in the toe segment's frame (they bend
      with the toes) and lowered so that in the rest pose they lie 0.033 ``H``
      below the ankle, as in the body model;
    * eyes, ears, nose = head pivot + ``R_head`` (head offset) ``H``, where
      ``R_head`` is the world rotation of ``Head`` and the pivot lies 0.110 ``H``
      (the body model's pivot-to-vertex distance) below the head's End Site (the
      top of the head) along the head's axis: roughly the top of the neck.
      ``Neck1`` is not needed: the head segment's pose carries the face.
    """
    from .body import FOOT_OFFSETS, FULL_INDEX, FULL_JOINTS, HEAD_OFFSETS

    J = _resolve(motion, CMU_JOINT_NAMES if names is None else names)
    P = np.asarray(positions, dtype=float)
    G = np.asarray(rotations, dtype=float)
    out = np.empty(P.shape[:1] + (len(FULL_JOINTS), 3))
    I = FULL_INDEX
    for s in ("left", "right"):
        for role in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle"):
            out[:, I[f"{s}_{role}"]] = P[:, J[f"{s}_{role}"]]
    out[:, I["neck"]] = (P[:, J["left_shoulder"]] + P[:, J["right_shoulder"]]) / 2.0
    out[:, I["mid_hip"]] = (P[:, J["left_hip"]] + P[:, J["right_hip"]]) / 2.0

    def attach(node: int, offset: np.ndarray) -> np.ndarray:
        return P[:, node] + G[:, node] @ offset

    for s, sx in (("left", 1.0), ("right", -1.0)):
        mirror = np.array([sx, 1.0, 1.0])
        a, toe = J[f"{s}_ankle"], J[f"{s}_toe"]
        out[:, I[f"{s}_heel"]] = attach(a, np.array(FOOT_OFFSETS["heel"]) * mirror * height)
        toe_off = motion.offsets[toe]                  # ankle -> toe base, rest
        tip = _tip_offset(motion, motion.names[toe])   # toe base -> toe tip, rest
        for pt, along in (("big_toe", 1.0), ("small_toe", 0.25)):
            o = tip * along
            o = o + np.array([FOOT_OFFSETS[pt][0] * sx * height, 0.0, 0.0])
            o[1] += FOOT_OFFSETS[pt][1] * height - toe_off[1] - tip[1] * along
            out[:, I[f"{s}_{pt}"]] = attach(toe, o)

    h = J["head"]
    top = _tip_offset(motion, motion.names[h])
    pivot = np.array([0.0, top[1] - 0.110 * height, top[2]])
    for pt in ("eye", "ear"):
        for s, sx in (("left", 1.0), ("right", -1.0)):
            o = pivot + np.array(HEAD_OFFSETS[pt]) * np.array([sx, 1.0, 1.0]) * height
            out[:, I[f"{s}_{pt}"]] = attach(h, o)
    out[:, I["nose"]] = attach(h, pivot + np.array(HEAD_OFFSETS["nose"]) * height)
    return out


def _leading_rest_frames(positions: np.ndarray, fps: float, unit: float) -> int:
    """Number of leading frames followed by a jump faster than :data:`MAX_JOINT_SPEED`."""
    k = 0
    limit = MAX_JOINT_SPEED / fps / unit
    while k + 1 < len(positions):
        step = np.linalg.norm(positions[k + 1] - positions[k], axis=-1).max()
        if step <= limit:
            break
        k += 1
    return k


@dataclass(frozen=True)
class MocapMotion:
    """A motion-capture take mapped to the synthetic body's joints, in metres.

    Attributes:
        joints: ``(F, 25, 3)`` joints of :data:`~mirrorgraph.synth.body.FULL_JOINTS`,
            metres, the BVH world's axes (Y up) with the floor moved to ``y = 0``.
        fps: frame rate of ``joints``.
        height: the skeleton's standing height, metres (:func:`skeleton_height`).
        source: the BVH file.
        source_fps: the file's frame rate.
        source_frames: frames in the file.
        skipped: leading frames of the file left out (a reference pose).
        floor: height of the floor in the BVH world, metres (see :func:`load_motion`).
    """

    joints: np.ndarray
    fps: float
    height: float
    source: str
    source_fps: float
    source_frames: int
    skipped: int
    floor: float

    def __len__(self) -> int:
        return int(self.joints.shape[0])

    def clip(self, frames: int, start: int = 0) -> np.ndarray:
        """``frames`` frames from ``start`` in the body frame of the procedural motion.

        The body frame of :func:`~mirrorgraph.synth.motion.generate_motion`:
        ``x`` left, ``y`` up, ``z`` forward, floor at ``y = 0``, metres here. At the
        clip's first frame the person faces ``+z`` (the horizontal normal of the
        line from the right to the left hip and shoulder) and the mid-hip is
        straight above the origin.

        A take shorter than ``start + frames`` plays back and forth (ping-pong:
        ``0, 1, .., F-1, F-2, .., 0, 1, ..``): the motion stays continuous (no jump
        back to the start; the velocity reverses at the turns).
        """
        from .body import FULL_INDEX

        T = int(frames)
        if T < 1:
            raise ValueError(f"frames must be >= 1, got {frames}")
        X = self.joints[pingpong_indices(len(self), T, start)]
        I = FULL_INDEX
        first = X[0]
        left = (first[I["left_hip"]] - first[I["right_hip"]]
                + first[I["left_shoulder"]] - first[I["right_shoulder"]])
        fwd = np.array([-left[2], 0.0, left[0]])            # left x up
        yaw = np.arctan2(fwd[0], fwd[2])
        R = axis_rotation(1, -yaw)                          # turns fwd onto +z
        origin = np.array([first[I["mid_hip"], 0], 0.0, first[I["mid_hip"], 2]])
        return (X - origin) @ R.T


def pingpong_indices(n: int, frames: int, start: int = 0) -> np.ndarray:
    """Frame indices ``(frames,)`` playing ``n`` frames back and forth from ``start``."""
    k = np.arange(int(frames)) + int(start)
    if n <= 1:
        return np.zeros_like(k)
    period = 2 * (n - 1)
    m = k % period
    return np.where(m < n, m, period - m)


def load_motion(path: str | os.PathLike | BvhMotion, fps: float = 30.0, *,
                unit: float = CMU_UNIT_M, names: dict[str, str] | None = None,
                skip_reference_pose: bool = True) -> MocapMotion:
    """Read a BVH take and map it to the synthetic body's 25 joints, in metres.

    Steps: parse; leave out leading frames that jump to the next one faster than
    :data:`MAX_JOINT_SPEED` (CMU conversions start with a reference T-pose: in
    ``cmu_01_01.bvh`` frame 0, 0.7 m from frame 1) when
    ``skip_reference_pose``; resample to ``fps`` (see the module docstring);
    map the joints (:func:`body_joints`); scale by ``unit`` (metres per file
    unit; CMU: 0.0254 / 0.45); move the floor to ``y = 0``.

    The floor is the level the feet stand on: the lowest heel or toe point of
    each frame, median over the take (at the file's rate; in most frames a foot
    stands on the floor). In ``cmu_01_01.bvh`` it lies 3 cm above the capture's
    ``y = 0``; the toes touch it when standing, a few landings dip up to 6 cm
    below, and the heels stand about 3 cm above it (the CMU ankle centre lies
    about 0.07 of the height above the floor, the body model's heel offset
    assumes 0.039).

    Args:
        path: BVH file (or an already parsed :class:`BvhMotion`).
        fps: frame rate wanted.
        unit: metres per file unit.
        names: role -> joint name (default :data:`CMU_JOINT_NAMES`).
        skip_reference_pose: leave out a leading reference pose.

    Raises:
        InputError: unreadable or malformed file, joints missing, not Y-up.
    """
    from .body import FULL_INDEX

    if not fps > 0:
        raise ValueError(f"fps must be positive, got {fps}")
    if not unit > 0:
        raise ValueError(f"unit must be positive, got {unit}")
    motion = path if isinstance(path, BvhMotion) else read_bvh(path)
    names = CMU_JOINT_NAMES if names is None else names
    height = skeleton_height(motion, names)
    P, G = motion.forward_kinematics()
    skipped = _leading_rest_frames(P, motion.fps, unit) if skip_reference_pose else 0
    if skipped:
        P, G = P[skipped:], G[skipped:]
        motion = motion.select(slice(skipped, None))
    full = body_joints(motion, P, G, height, names)
    feet = [FULL_INDEX[f"{s}_{p}"] for s in ("left", "right")
            for p in ("heel", "big_toe", "small_toe")]
    floor = float(np.median(full[:, feet, 1].min(1)))
    del P, G, full
    if motion.fps == fps:
        P, G = motion.forward_kinematics()
    else:
        P, G = motion.resample(fps)
    X = body_joints(motion, P, G, height, names)
    X[..., 1] -= floor
    X *= unit
    return MocapMotion(joints=X, fps=float(fps), height=height * unit, source=motion.source,
                       source_fps=motion.fps, source_frames=motion.frames + skipped,
                       skipped=skipped, floor=floor * unit)


def motion_for_scene(path: str | os.PathLike, frames: int, fps: float = 30.0,
                     **kwargs: Any) -> tuple[np.ndarray, MocapMotion]:
    """The first ``frames`` frames of a take for :func:`~mirrorgraph.synth.make_scene`.

    Returns:
        ``(local, take)``: ``local`` ``(frames, 25, 3)`` in units of the skeleton's
        height in the body frame (exactly what
        :func:`~mirrorgraph.synth.motion.generate_motion` returns; see
        :meth:`MocapMotion.clip`), and the take (:func:`load_motion`; its
        ``height`` in metres turns ``local`` back into metres).
    """
    take = load_motion(path, fps, **kwargs)
    return take.clip(frames) / take.height, take
