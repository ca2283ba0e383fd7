"""The run of ``mirrorgraph live``: a source through the calibrator into JSON lines.

Each frame appends one line to the JSON-lines file (written and flushed as the frame is
done, so another program can follow it): :meth:`mirrorgraph.live.LiveFrame.to_dict`,

    {"frame": 0, "frame_id": 0, "time": 0.0, "status": "initialising",
     "mirror": {"status": ..., "normal": [nx, ny, nz] | null, "distance": d | null,
                "rotation_std_deg": s | null, "distance_std": ...,
                "scale_rel_std": ..., "focal_px": ...,
                "focal_std_px": ..., "windows": ..., "windows_rejected": ...,
                "windows_failed": ..., "resets": ..., "scale": "subject_height"},
     "joints3d": [[x, y, z] | null, ...], "joints_std": [s | null, ...],
     "joints_std_shape": [s | null, ...],
     "paired": true, "skipped": null, "lag_frames": 9}

With a lag (``LiveOptions.lag_frames``, ``--lag``) each line is written that many frames
after its frame came, its joints smoothed with the frames after it
(:attr:`~mirrorgraph.live.LiveFrame.settled`); ``lag_frames`` says how late.

A joint not estimated, and any figure not known yet, is JSON ``null`` (JSON has no
NaN; Python's ``json`` reads ``null`` as ``None``). Lengths are metres with a subject
height, else mirror distances (``mirror.scale``); the real camera's frame.

``--view`` streams the same to Rerun (:class:`LiveView`): the 3D joints, the mirror's
normal and the status over the ``frame`` timeline, to the live viewer or to an ``.rrd``.
"""

from __future__ import annotations

import json
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from .calibrator import LiveCalibrator, LiveFrame, LiveMirror, LiveOptions
from .sources import Source

__all__ = ["LiveView", "LiveSummary", "run_live", "check_view"]


def check_view(view: str | None) -> None:
    """Fail before the stream: the Rerun SDK missing, a bad file name, or no display for
    the live viewer (one line each)."""
    if view is None:
        return
    from ..viewer.recording import require_rerun

    require_rerun()
    if view:
        if Path(view).suffix.lower() != ".rrd":
            raise InputError("must end in .rrd (a Rerun recording)", source=view, field="--view")
    elif sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                   or os.environ.get("WAYLAND_DISPLAY")):
        raise InputError("Rerun's live viewer needs a display (neither DISPLAY nor "
                         "WAYLAND_DISPLAY is set): give --view OUT.rrd to record the stream "
                         "instead", field="--view")


class LiveView:
    """The live run in Rerun: ``save`` an ``.rrd`` path, or ``None`` for the live viewer."""

    def __init__(self, skeleton, save: str | None = None):
        from ..viewer.recording import require_rerun

        rr = self.rr = require_rerun()
        self.rec = rr.RecordingStream("mirrorgraph-live")
        try:
            if save:
                self.rec.save(str(save))
            else:
                self.rec.spawn()
        except Exception as exc:  # noqa: BLE001 - Rerun raises RuntimeError and others
            raise InputError(f"Rerun could not {'write' if save else 'start its viewer'}: "
                             f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}",
                             source=save, field="--view") from None
        self.skeleton = skeleton
        names = skeleton.joints
        idx = {n: i for i, n in enumerate(names)}
        self.bones = np.array([(idx[a], idx[b]) for a, b in skeleton.bones.values()
                               if a in idx and b in idx], dtype=int).reshape(-1, 2)
        self.rec.log("world", rr.ViewCoordinates.RDF, static=True)

    def log(self, frame: LiveFrame) -> None:
        rr, rec = self.rr, self.rec
        rec.set_time("frame", sequence=int(frame.frame_id))
        rec.set_time("time", duration=float(frame.time))
        X = frame.joints3d
        ok = np.isfinite(X).all(1)
        rec.log("world/joints", rr.Points3D(X[ok], radii=0.02))
        both = ok[self.bones].all(1) if len(self.bones) else np.zeros(0, bool)
        rec.log("world/bones", rr.LineStrips3D([X[b] for b in self.bones[both]]))
        m = frame.mirror
        if m.normal is not None and m.distance:
            rec.log("world/mirror_normal", rr.Arrows3D(origins=[m.normal * m.distance],
                                                      vectors=[m.normal * 0.5 * m.distance]))
            rec.log("mirror/rotation_std_deg", rr.Scalars(m.rotation_std_deg))
        rec.log("status", rr.TextLog(m.status))

    def close(self) -> None:
        self.rec.flush()
        self.rec.disconnect()


@dataclass
class LiveSummary:
    """What a live run did: the final mirror, counts, timings.

    ``lines``: the JSON lines written, one a frame, each complete; ``interrupted``: the run
    stopped on Ctrl-C (``KeyboardInterrupt``) after those; ``no_mirror``: why no mirror
    was found (``None`` where one was), in words; ``lag_frames``: how many frames after its
    frame each line was written (``fps``: the stream's rate, for that in seconds).
    """

    mirror: LiveMirror
    counts: dict
    frames: int
    seconds: float
    first_calibrated_frame: int | None
    first_calibrated_time: float | None
    latency_ms: dict = field(default_factory=dict)
    source_stats: dict = field(default_factory=dict)
    lines: int = 0
    interrupted: bool = False
    no_mirror: str | None = None
    lag_frames: int = 0
    fps: float | None = None

    def describe(self) -> str:
        m = self.mirror
        lines = [f"{self.frames} frames in {self.seconds:.1f} s "
                 f"({self.frames / max(self.seconds, 1e-9):.0f} frames/s); "
                 f"status {m.status}"]
        if self.first_calibrated_time is not None:
            lines.append(f"calibrated at frame {self.first_calibrated_frame} "
                         f"({self.first_calibrated_time:.1f} s into the stream)")
        if m.normal is not None:
            unit = "m" if m.scale == "subject_height" else "(mirror distances)"
            lines.append(f"mirror normal [{m.normal[0]:.4f}, {m.normal[1]:.4f}, "
                         f"{m.normal[2]:.4f}], rotation std {m.rotation_std_deg:.3f} deg, "
                         f"distance {m.distance:.3f} {unit}")
        if m.doubt:
            lines.append(f"warning: {m.doubt}")
        c = self.counts
        lines.append(f"windows: {c['windows']} fused, {c['windows_rejected']} rejected, "
                     f"{c['windows_failed']} failed, {c['resets']} restarts; frames skipped "
                     f"(bad input) {c['skipped']}, without a pair {c['unpaired']}")
        if self.lag_frames:
            late = f" ({self.lag_frames / self.fps:.2f} s)" if self.fps else ""
            lines.append(f"each line written {self.lag_frames} frames{late} after its frame, "
                         "its joints solved again with them (--lag)")
        if self.latency_ms:
            lat = self.latency_ms
            lines.append(f"per-frame latency median {lat['median']:.2f} ms, p95 "
                         f"{lat['p95']:.2f} ms, p99 {lat['p99']:.2f} ms")
        if self.source_stats.get("dropped"):
            lines.append(f"{self.source_stats['dropped']} video frames dropped (the detector "
                         "was slower than the frame rate)")
        return "\n".join(lines)


#: Latencies kept for the summary's quantiles (the most recent ones; memory stays flat).
LATENCY_KEEP = 10000


def _no_mirror(live: LiveCalibrator, people: dict[int, int]) -> str | None:
    """Why the stream gave no mirror, in words (``None`` where it gave one); ``people``:
    how many frames had 0, 1 and 2 or more people."""
    if live.mirror.normal is not None:
        return None
    c = live.counts
    if c["frames"] == 0:
        return "the source gave no frame"
    if c["skipped"] >= c["frames"]:
        by = ", ".join(f"{n} {r}" for r, n in sorted(c["skipped_by_reason"].items()))
        return f"every frame of {c['frames']} was skipped as bad input ({by})"
    if people.get(2, 0) == 0:
        return (f"no frame of {c['frames']} holds two people, the person and their "
                f"reflection ({people.get(0, 0)} with nobody, {people.get(1, 0)} with one "
                "person)")
    failed = [w for w in live.window_log if w["result"] != "fused" and w["reason"]]
    if failed:
        return (f"every window's solve failed ({c['windows_failed']} failed, "
                f"{c['windows_rejected']} rejected); the last: {failed[-1]['reason']}")
    return (f"{c['frames']} frames gave no mirror ({c['windows_failed']} windows failed, "
            f"{c['windows_rejected']} rejected, {c['buffered']} frames buffered)")


def run_live(source: Source, intrinsics, options: LiveOptions, jsonl: str | os.PathLike,
             *, view: str | None = None, on_frame=None) -> LiveSummary:
    """Run a source through :class:`LiveCalibrator`, a JSON line per frame.

    The JSON-lines file is opened (an existing file replaced: the stream is written
    where it can be followed, not staged) when the first frame comes; ``"-"`` writes
    to standard output. Ctrl-C ends the run with :attr:`LiveSummary.interrupted` set:
    the file then holds every frame done, each a complete line.

    Args:
        source: :func:`~.sources.open_source`.
        intrinsics: :class:`~mirrorgraph.intrinsics.Intrinsics` or ``None``.
        options: :class:`LiveOptions` (its ``calibrate.image_size`` is filled from the
            source where missing).
        jsonl: the file to write (one line per frame, flushed as it goes), or ``"-"``.
        view: ``None`` (no viewer), ``""`` (Rerun's live viewer) or an ``.rrd`` path.
        on_frame: ``on_frame(LiveFrame)`` after each frame (progress).

    Returns:
        :class:`LiveSummary`.
    """
    from dataclasses import replace

    from ..pipelines.options import CalibrateOptions

    copts = options.calibrate or CalibrateOptions()
    if copts.image_size is None and source.image_size is not None:
        copts = replace(copts, image_size=tuple(source.image_size))
    if source.fps:
        options = replace(options, fps=float(source.fps))
    options = replace(options, calibrate=copts)
    live = LiveCalibrator(source.skeleton, intrinsics, options)
    latencies: list[float] = []
    first = (None, None)
    interrupted = False
    lines = 0
    people: dict[int, int] = {}
    viewer = None
    clock = time.perf_counter()
    to_stdout = os.fspath(jsonl) == "-"
    try:
        viewer = LiveView(source.skeleton, view or None) if view is not None else None
        fh = sys.stdout if to_stdout else open(Path(jsonl), "w", encoding="utf-8")
        def emit(out: LiveFrame) -> None:
            nonlocal lines
            fh.write(json.dumps(out.to_dict(), allow_nan=False) + "\n")
            fh.flush()
            lines += 1
            if viewer is not None:
                viewer.log(out)

        lagged = options.lag_frames > 0
        try:
            try:
                for sf in source.frames:
                    frame = live.update(sf.people, frame_id=sf.frame_id, time_s=sf.time)
                    try:
                        n = min(len(sf.people), 2)
                    except TypeError:
                        n = 0
                    people[n] = people.get(n, 0) + 1
                    if not lagged:
                        emit(frame)
                    elif frame.settled is not None:
                        emit(frame.settled)
                    latencies.append(frame.latency_s)
                    if len(latencies) > 2 * LATENCY_KEEP:
                        del latencies[:LATENCY_KEEP]
                    if first[0] is None and frame.status == "calibrated":
                        first = (frame.frame_id, frame.time)
                    if on_frame is not None:
                        on_frame(frame)
            except KeyboardInterrupt:
                interrupted = True
            mirror = live.mirror if interrupted else live.finish()
            for out in live.flush():                 # the frames still held for their lag
                emit(out)
        finally:
            if not to_stdout:
                fh.close()
    finally:
        live.close()
        if viewer is not None:
            viewer.close()
    lat = np.asarray(latencies) * 1e3
    q = (dict(zip(("median", "p95", "p99"), np.percentile(lat, [50, 95, 99]).tolist()))
         if lat.size else {})
    return LiveSummary(mirror=mirror, counts=live.counts, frames=live.frames,
                       seconds=time.perf_counter() - clock, first_calibrated_frame=first[0],
                       first_calibrated_time=first[1], latency_ms=q,
                       source_stats=dict(source.stats), lines=lines, interrupted=interrupted,
                       no_mirror=None if interrupted else _no_mirror(live, people),
                       lag_frames=int(options.lag_frames), fps=options.fps)
