"""BVH motion capture files: reader and forward kinematics.

:func:`read_bvh` / :func:`parse_bvh` -> :class:`BvhMotion`: the ``HIERARCHY``
(``ROOT``, ``JOINT``, ``End Site``, ``OFFSET``, ``CHANNELS`` in any order and any
subset of ``Xposition Yposition Zposition Xrotation Yrotation Zrotation``, several
roots allowed) and the ``MOTION`` section (``Frames:``, ``Frame Time:``, one line of
channel values per frame). Malformed input raises
:class:`mirrorgraph.errors.InputError` naming the file and the line.
:meth:`BvhMotion.forward_kinematics` computes the world positions and rotations of
every joint and end site, vectorised over frames; :meth:`BvhMotion.resample` changes
the frame rate. What a take means for a synthetic person (the CMU skeleton mapped to
the body model) is :mod:`mirrorgraph.synth.mocap`.

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
from scipy.spatial.transform import Rotation

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
            raise InputError(f"frame rate must be a positive number, got {fps}", field="fps")
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


def slerp_matrices(R0: np.ndarray, R1: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Rotations a fraction ``u`` of the way from ``R0`` to ``R1`` on the shortest arc.

    Args:
        R0, R1: ``(..., 3, 3)`` rotation matrices.
        u: fractions, broadcastable to ``R0.shape[:-2]`` (0 gives ``R0``, 1 ``R1``).

    Returns:
        ``(..., 3, 3)``: ``R0 Exp(u Log(R0^T R1))`` (spherical linear interpolation;
        Shoemake 1985), through :class:`scipy.spatial.transform.Rotation`.
    """
    R0 = np.asarray(R0, dtype=float)
    R1 = np.asarray(R1, dtype=float)
    shape = np.broadcast_shapes(R0.shape[:-2], R1.shape[:-2], np.shape(u))
    a = np.broadcast_to(R0, shape + (3, 3)).reshape(-1, 3, 3)
    b = np.broadcast_to(R1, shape + (3, 3)).reshape(-1, 3, 3)
    uu = np.broadcast_to(np.asarray(u, dtype=float), shape).reshape(-1)
    if a.shape[0] == 0:
        return np.empty(shape + (3, 3))
    w = Rotation.from_matrix(np.swapaxes(a, -1, -2) @ b).as_rotvec()
    step = Rotation.from_rotvec(w * uu[:, None]).as_matrix()
    return (a @ step).reshape(shape + (3, 3))


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
    joints = _read_hierarchy(text, lines, motion_line, source)
    if motion_line is None:
        raise InputError(f"line {len(lines)}: no MOTION section after the hierarchy",
                         source=source)
    F, dt, k = _read_motion_header(lines, motion_line, source)
    counts = np.array([len(c) for c in joints.channels], dtype=int)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int)
    values = _read_motion_values(lines, k, F, int(counts.sum()), source)
    return BvhMotion(source=source, names=tuple(joints.names),
                     parents=np.array(joints.parents, dtype=int),
                     offsets=np.array(joints.offsets, dtype=float),
                     channels=tuple(joints.channels), channel_start=starts,
                     end_site=np.array(joints.end_site, dtype=bool), frame_time=dt,
                     values=values)


class _Hierarchy:
    """The joints of a BVH hierarchy, in the order they are read (:func:`parse_bvh`)."""

    def __init__(self, toks: _Tokens) -> None:
        self.toks = toks
        self.names: list[str] = []
        self.parents: list[int] = []
        self.offsets: list[tuple[float, float, float]] = []
        self.channels: list[tuple[str, ...]] = []
        self.end_site: list[bool] = []
        self.seen: dict[str, int] = {}

    def node(self, name: str, line: int, parent: int, is_end: bool) -> None:
        """Read a joint (or End Site) from its ``{`` to its ``}``, its children with it."""
        toks = self.toks
        if name in self.seen:
            raise toks.fail(f"joint name {name!r} is used twice (first on line "
                            f"{self.seen[name]})", line)
        self.seen[name] = line
        idx = len(self.names)
        self.names.append(name)
        self.parents.append(parent)
        self.offsets.append((0.0, 0.0, 0.0))
        self.channels.append(())
        self.end_site.append(is_end)
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
                self.offsets[idx] = tuple(toks.number(f"OFFSET {a} of {name}") for a in "xyz")
                have_offset = True
            elif key == "CHANNELS":
                if is_end:
                    raise toks.fail(f"End Site of {self.names[parent]} cannot have CHANNELS",
                                    ln)
                if have_channels:
                    raise toks.fail(f"{name}: a second CHANNELS", ln)
                self.channels[idx] = _read_channels(toks, name)
                have_channels = True
            elif key == "JOINT":
                if is_end:
                    raise toks.fail("an End Site cannot have children", ln)
                child, cl = toks.next("a joint name")
                if child in ("{", "}"):
                    raise toks.fail("JOINT without a name", cl)
                self.node(child, cl, idx, False)
            elif key == "END":
                if is_end:
                    raise toks.fail("an End Site cannot have children", ln)
                site, sl = toks.next("'Site'")
                if site.upper() != "SITE":
                    raise toks.fail(f"expected 'End Site', got 'End {site}'", sl)
                self.node(name + END_SITE_SUFFIX, sl, idx, True)
            elif key in ("ROOT", "MOTION", "HIERARCHY"):
                raise toks.fail(f"{tok!r} inside {name}: missing '}}'", ln)
            else:
                raise toks.fail(f"unexpected {tok!r} in {name} (expected OFFSET, CHANNELS, "
                                "JOINT, End Site or '}')", ln)
        if not have_offset:
            raise toks.fail(f"{name} has no OFFSET", line)


def _read_channels(toks: _Tokens, name: str) -> tuple[str, ...]:
    """The channels of joint ``name`` after its ``CHANNELS`` keyword: the count, then the
    names (capitalised as ``Xrotation``)."""
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
    return tuple(got)


def _read_hierarchy(text: str, lines: list[str], motion_line: int | None, source: str
                    ) -> _Hierarchy:
    """The HIERARCHY section: the lines before ``motion_line`` (every line without one)."""
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
    joints = _Hierarchy(toks)
    roots = 0
    while toks.peek() is not None:
        tok, line = toks.next("'ROOT'")
        if tok.upper() != "ROOT":
            if tok == "}":
                raise toks.fail("unbalanced '}'", line)
            raise toks.fail(f"expected 'ROOT' or 'MOTION', got {tok!r}", line)
        name, nl = toks.next("the root's name")
        joints.node(name, nl, -1, False)
        roots += 1
    if roots == 0:
        raise toks.fail("the hierarchy has no ROOT", toks.items[-1][1])
    return joints


def _read_motion_header(lines: list[str], motion_line: int, source: str
                        ) -> tuple[int, float, int]:
    """The ``Frames:`` and ``Frame Time:`` lines after ``MOTION``: ``(F, dt, k)``, ``k`` the
    index of the line after them."""
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
    return F, dt, k


def _read_motion_values(lines: list[str], k: int, F: int, C: int, source: str) -> np.ndarray:
    """``(F, C)`` the frame lines from line index ``k`` on, ``C`` values each."""
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
    return values
