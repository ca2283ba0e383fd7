"""A synthetic room's straight edges drawn with a known camera: ground truth for the
focal length from vanishing points (:mod:`mirrorgraph.initial.vanishing`).

A box room (y down, the camera near the origin looking into it) with floor tiles, the
edges where walls meet the ceiling, door and window frames on the walls and a rail along
each side wall: three orthogonal families of lines. :func:`render_room` draws them
anti-aliased, dark on a light background, optionally with Gaussian image noise.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["room_edges", "render_room", "rotation_ypr"]


def rotation_ypr(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """``(3, 3)`` world-to-camera rotation: yaw about y, pitch about x, roll about z,
    degrees (positive pitch looks down at the floor)."""
    a, b, c = np.radians([yaw, pitch, roll])
    Ry = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    Rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    Rz = np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])
    return Rz @ Rx @ Ry


def room_edges(width: float = 8.0, depth: float = 10.0, height: float = 3.0,
               tile: float = 1.0) -> list[tuple[np.ndarray, np.ndarray]]:
    """3D segments (metres, world frame, y down, the floor 1.5 m below the origin) of a box
    room ``width`` wide and ``depth`` deep: floor tiles of ``tile``, the wall-ceiling
    edges, frames on the walls, a rail along each side wall."""
    x0, x1, z0, z1, yf, yc = -width / 2, width / 2, -2.0, depth, 1.5, 1.5 - height
    out = []
    for x in np.arange(x0, x1 + 1e-9, tile):
        out.append(((x, yf, z0), (x, yf, z1)))
    for z in np.arange(z0, z1 + 1e-9, tile):
        out.append(((x0, yf, z), (x1, yf, z)))
    for x in (x0, x1):
        out.append(((x, yc, z0), (x, yc, z1)))
    out.append(((x0, yc, z1), (x1, yc, z1)))
    for x in np.linspace(x0 + 1, x1 - 1, 5):
        out.append(((x, yf, z1), (x, yc + 0.5, z1)))
    for z in np.linspace(1.0, depth - 1, 6):
        for x in (x0, x1):
            out.append(((x, yf, z), (x, yc + 0.7, z)))
    for y in (yc + 0.7, 0.2):
        for x in (x0, x1):
            out.append(((x, y, 0.5), (x, y, depth - 0.5)))
    return [(np.array(a, float), np.array(b, float)) for a, b in out]


def render_room(K: np.ndarray, R: np.ndarray, size: tuple[int, int], C=(0.0, 0.0, 0.0), *,
                thickness: int = 2, noise: float = 0.0, seed: int = 0,
                edges: list | None = None) -> np.ndarray:
    """``(H, W)`` uint8: the room's segments (:func:`room_edges`, or ``edges``) drawn with
    camera ``K``, world-to-camera rotation ``R`` and centre ``C``, clipped at 0.2 m in
    front of the camera; ``noise``: Gaussian image noise, grey levels."""
    W, H = size
    img = np.full((H, W), 200, np.uint8)
    C = np.asarray(C, float)
    near = 0.2
    for a, b in (room_edges() if edges is None else edges):
        pa, pb = R @ (a - C), R @ (b - C)
        if pa[2] < near and pb[2] < near:
            continue
        if pa[2] < near or pb[2] < near:
            s = (near - pa[2]) / (pb[2] - pa[2])
            p = pa + s * (pb - pa)
            pa, pb = (p, pb) if pa[2] < near else (pa, p)
        ua, ub = K @ pa, K @ pb
        ua, ub = ua[:2] / ua[2], ub[:2] / ub[2]
        big = 1e6                                          # cv2's integer coordinates
        ua, ub = np.clip(ua, -big, big), np.clip(ub, -big, big)
        ok, p1, p2 = cv2.clipLine((0, 0, W, H), tuple(int(round(v)) for v in ua),
                                  tuple(int(round(v)) for v in ub))
        if ok:
            cv2.line(img, p1, p2, 40, thickness, cv2.LINE_AA)
    if noise > 0:
        rng = np.random.default_rng(seed)
        img = np.clip(img + rng.normal(0.0, noise, img.shape), 0, 255).astype(np.uint8)
    return img
