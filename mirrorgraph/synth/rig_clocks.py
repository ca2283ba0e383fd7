"""Synthetic rigs whose cameras were not started together: known time offsets.

:func:`unsynchronised_rig` makes a rig (:func:`mirrorgraph.synth.rig.make_rig`) at
``upsample`` times the frame rate and keeps for each camera every ``upsample``-th frame,
starting where its offset puts it: camera ``c``'s frame ``f`` shows the rig's (camera
0's) frame ``f - offsets[c]``, the rig file's ``frame_offset`` convention, so an offset of
``2.5`` puts the camera's frames half-way between the rig's. The motion is defined in
seconds (:func:`mirrorgraph.synth.motion.generate_motion`), so the upsampled rig is the
same kind of scene; the detector's noise is drawn per upsampled frame, independent
between the frames kept. The ground truth (``joints3d``, ``frame_ids``) is on the rig's
clock; :attr:`SyntheticRig.placement` holds ``time_offsets``. A camera may film at
another rate (``rates``: a 30 fps camera beside 60 fps ones, 25 fps beside 30) and its
clock run at another rate (``drifts``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..keypoints import RawDetections
from .rig import make_rig
from .rig_types import SyntheticRig

__all__ = ["unsynchronised_rig"]


def unsynchronised_rig(kind: str, offsets, *, frames: int = 150, upsample: int = 10,
                       fps: float = 30.0, rates=None, drifts=None, **options) -> SyntheticRig:
    """A rig whose cameras have the given time offsets (see the module docstring).

    Args:
        kind: as :func:`~mirrorgraph.synth.rig.make_rig`.
        offsets: per camera its offset, frames of the rig's clock (the first camera's
            must be 0); each a multiple of ``1 / upsample``.
        frames: frames ``T`` of the rig's clock (every camera keeps those of its frames
            that fall within them).
        upsample: the factor of the rig made underneath.
        fps: the rig's frame rate (the first camera's).
        rates: per camera the rig's frames per own frame (default all 1): a camera with
            ``d`` films at ``fps / d``, its own frame ``g`` the rig's frame ``d g -
            offset`` (its files number its own frames, and say its rate); a ``d`` that
            is no whole number puts some frames between the upsampled rig's, at the
            nearest (within ``1 / (2 upsample)`` frame).
        drifts: per camera its clock's rate against the rig's (default all 1): its own
            frame ``g`` the rig's frame ``(d g - offset) / drift``, to the nearest
            ``1 / upsample`` frame.
        options: the other keywords of :func:`~mirrorgraph.synth.rig.make_rig`.

    Raises:
        ValueError: an offset that is no multiple of ``1 / upsample``, a first camera's
            offset other than 0, or a count of offsets other than the rig's cameras.
    """
    k = int(upsample)
    hi = make_rig(kind, frames=int(frames) * k, fps=float(fps) * k, **options)
    offsets = [float(o) for o in offsets]
    if len(offsets) != len(hi.camera_names):
        raise ValueError(f"{len(offsets)} offsets for {len(hi.camera_names)} cameras")
    rates = [1.0] * len(offsets) if rates is None else [float(r) for r in rates]
    if len(rates) != len(offsets) or min(rates) <= 0:
        raise ValueError(f"rates must be one positive number per camera, got {rates}")
    drifts = [1.0] * len(offsets) if drifts is None else [float(r) for r in drifts]
    if len(drifts) != len(offsets) or min(drifts) <= 0:
        raise ValueError(f"drifts must be one positive number per camera, got {drifts}")
    if offsets[0] != 0:
        raise ValueError("the first camera defines the rig's clock: its offset must be 0")
    steps = [o * k for o in offsets]
    if any(abs(s - round(s)) > 1e-9 for s in steps):
        raise ValueError(f"offsets must be multiples of 1/{k} frame, got {offsets}")
    T_hi = len(hi)
    detections, views, det_views = {}, {}, {}
    for name, o, rate, drift in zip(hi.camera_names, offsets, rates, drifts):
        # own frame g shows rig frame (rate g - o) / drift: upsampled index k times that
        # (its frames numbered from 0, as a camera's files are: frames before the rig's
        # first are not made, so a camera ahead of the rig starts at its offset)
        f = np.arange(max(int(np.ceil(o / rate)), 0),
                      int(np.floor(((T_hi - 1) / k * drift + o) / rate)) + 1)
        idx = np.round(k * (rate * f - o) / drift).astype(np.int64)
        keep = (idx >= 0) & (idx < T_hi)
        f, idx = f[keep], idx[keep]
        d = hi.detections[name]
        detections[name] = RawDetections(skeleton=d.skeleton, frame_ids=f.astype(np.int64),
                                         people=[d.people[i] for i in idx], source=d.source,
                                         format=d.format, image_size=d.image_size,
                                         fps=float(fps) / rate)
        views[name] = {v: replace(rv, clean=rv.clean[idx], visible=rv.visible[idx],
                                  detected=rv.detected[idx], observed=rv.observed[idx],
                                  outliers=rv.outliers[idx], lr_swapped=rv.lr_swapped[idx])
                       for v, rv in hi.views[name].items()}
        det_views[name] = [hi.detection_views[name][i] for i in idx]
    rows = np.arange(0, T_hi, k)
    options = dict(hi.options, frames=int(frames), fps=float(fps), upsample=k,
                   time_offsets=offsets, rates=rates, drifts=drifts)
    return replace(hi, frame_ids=np.arange(len(rows), dtype=np.int64),
                   joints3d=hi.joints3d[rows], detections=detections, views=views,
                   detection_views=det_views, fps=float(fps), options=options,
                   placement=dict(hi.placement, time_offsets=offsets),
                   bystanders=[replace(b, joints3d=b.joints3d[rows]) for b in hi.bystanders])
