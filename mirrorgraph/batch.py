"""Calibrate many recordings in parallel with Dask: the library of ``mirrorgraph batch``.

A *manifest* lists the recordings (see :func:`read_manifest`):

* a CSV file with the header ``keypoints,intrinsics,out,subject_height`` (only
  ``keypoints`` is required; paths are relative to the CSV's folder; empty lines and
  lines starting with ``#`` are skipped)::

      keypoints,intrinsics,out,subject_height
      gym/keypoints_mmpose.json,gym/camera.json,results/gym.json,1.75
      studio/openpose,studio/camera.yml,,
      tutorial.npz,,,

  A missing ``out`` is ``<keypoints stem>.calibration.json`` in the output folder (the
  CSV's folder unless ``out_dir`` is given);
* a folder: each subfolder (hidden ones skipped) is a recording holding a keypoint input
  (``keypoints_mmpose.json``, ``openpose/``, ``easymocap/`` or a ``*.npz``, tried in this
  order) and optionally ``camera.json`` (or ``camera.yml`` / ``camera.yaml``); its
  calibration goes to ``calibration.json`` in the subfolder (in
  ``<out_dir>/<subfolder>.calibration.json`` when ``out_dir`` is given).

A recording may be a rig as well (a single mirror is the rig of one camera and one
mirror, and both go through the same options): a ``rig.toml`` as a CSV row's
``keypoints`` (its ``intrinsics`` left empty: the rig file lists every camera's), or a
subfolder holding ``rig.toml``. Its rig JSON goes to ``out`` and Pose2Sim's camera file
beside it (``out`` with ``.toml``), as ``mirrorgraph calibrate-rig`` writes them.

:func:`run_batch` calibrates every recording on a Dask cluster: a local one by default
(one single-threaded worker *process* per core: GTSAM holds the GIL, so threads would not
run in parallel), or an existing cluster given by its scheduler address. Each task runs
the whole pipeline and writes its calibration JSON atomically, with the run its report
draws from beside it (``<out>.report.npz``, :mod:`mirrorgraph.report.store`, so that
``mirrorgraph report`` shows that very run); a recording that fails
is reported with its one-line error and does not stop the others. Workers of an existing
cluster need mirrorgraph installed and the paths of the manifest readable.

Its command line, ``mirrorgraph batch MANIFEST``, is :mod:`mirrorgraph.cli.batch`.
"""

from __future__ import annotations

import csv
import logging
import math
import os
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Callable, Sequence

from .anthropometry import height_problem
from .errors import InputError, MirrorgraphError, require_extra
from .graph import RefineOptions
from .intrinsics import load_intrinsics
from .pipelines.mirror import CalibrateOptions, calibrate
from .rigs.config import RIG_FILE
from .report.store import write_calibration_and_run

#: Columns a CSV manifest may have; ``keypoints`` is required.
COLUMNS = ("keypoints", "intrinsics", "out", "subject_height")

#: Keypoint inputs looked for in a recording's subfolder, in this order (then ``*.npz``).
FOLDER_INPUTS = ("keypoints_mmpose.json", "openpose", "easymocap")

#: Intrinsics files looked for in a recording's subfolder, in this order.
FOLDER_CAMERAS = ("camera.json", "camera.yml", "camera.yaml")

#: Name of the calibration written into a recording's subfolder.
FOLDER_OUT = "calibration.json"

OK, FAILED = "ok", "failed"


@dataclass(frozen=True)
class Recording:
    """One recording to calibrate.

    Attributes:
        name: label in the summary (the keypoints path as the manifest gives it, or the
            subfolder's name).
        keypoints: keypoint input (file or folder) or a rig file (``.toml``), or ``None``
            when a subfolder holds none (the recording then fails with that message).
        intrinsics: intrinsics file, or ``None`` (the pipeline then guesses K).
        out: calibration JSON to write.
        subject_height: metres, or ``None``.
        where: where the manifest lists it, e.g. ``"runs.csv line 4"``.
    """

    name: str
    keypoints: Path | None
    intrinsics: Path | None
    out: Path
    subject_height: float | None = None
    where: str = ""


@dataclass
class BatchResult:
    """What became of one recording (small: it travels back from a worker).

    Attributes:
        name: the recording's name.
        status: ``"ok"`` or ``"failed"``.
        message: the error for a failed recording, else ``""``.
        out: path of the calibration written (``None`` if it failed).
        normal: mirror normal ``(3,)`` (real camera frame), or ``None``.
        distance: camera-to-mirror distance in metres, or ``None`` (unknown scale or failure).
        inlier_ratio: share of joint/reflection pairs kept.
        rotation_std_deg: the virtual camera's rotation std (refinement only), or ``None``.
        seconds: wall time of the task on its worker.
        warnings: the calibration's warnings.
        keypoints: the keypoint input, as a string.
        cameras: the cameras of a rig recording (0: a single mirror; its ``normal`` and
            ``distance`` are then ``None``, ``rotation_std_deg`` the largest of its
            estimated cameras and mirrors).
    """

    name: str
    status: str
    message: str = ""
    out: str | None = None
    normal: tuple[float, float, float] | None = None
    distance: float | None = None
    inlier_ratio: float | None = None
    rotation_std_deg: float | None = None
    seconds: float = 0.0
    warnings: tuple[str, ...] = field(default_factory=tuple)
    keypoints: str | None = None
    cameras: int = 0

    @property
    def ok(self) -> bool:
        return self.status == OK


# --------------------------------------------------------------------------- manifest
def read_manifest(path: str | os.PathLike, *,
                  out_dir: str | os.PathLike | None = None) -> list[Recording]:
    """The recordings listed by a CSV manifest or held by a folder (module docstring).

    Args:
        path: the CSV file or the folder.
        out_dir: folder for the default output names (created when writing).

    Raises:
        InputError: naming the manifest, line and field at fault: no such manifest, no
            ``keypoints`` column, an unknown column, an empty ``keypoints``, a
            ``subject_height`` that is not a positive number, two recordings writing
            the same output, no recording at all.
    """
    path = Path(path)
    if path.is_dir():
        recordings = _read_folder(path, None if out_dir is None else Path(out_dir))
    elif path.is_file():
        recordings = _read_csv(path, None if out_dir is None else Path(out_dir))
    else:
        raise InputError("no such manifest file or folder", source=path)
    if not recordings:
        raise InputError("lists no recording", source=path)
    seen: dict[Path, Recording] = {}
    for rec in recordings:
        key = Path(os.path.abspath(rec.out))
        if key in seen:
            raise InputError(f"output {rec.out} is also the output of {seen[key].where}: "
                             "give each recording its own 'out'",
                             source=rec.where or path, field="out")
        seen[key] = rec
    return recordings


def _read_csv(path: Path, out_dir: Path | None) -> list[Recording]:
    base = path.parent
    out_dir = base if out_dir is None else out_dir
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            rows = list(enumerate(csv.reader(fh), start=1))
    except UnicodeDecodeError as e:
        raise InputError(f"not UTF-8 text ({e.reason} at byte {e.start})", source=path) from None
    except csv.Error as e:
        raise InputError(f"malformed CSV ({e})", source=path) from None
    except OSError as e:
        raise InputError(f"cannot read ({e.strerror})", source=path) from None
    rows = [(n, row) for n, row in rows
            if any(c.strip() for c in row) and not row[0].lstrip().startswith("#")]
    if not rows:
        raise InputError("is empty: expected the header "
                         f"{','.join(COLUMNS)} and one line per recording", source=path)
    n0, header = rows[0]
    columns = [c.strip().lower() for c in header]
    where0 = f"{path} line {n0}"
    for c in columns:
        if c not in COLUMNS:
            raise InputError(f"unknown column {c!r}; the columns are {', '.join(COLUMNS)} "
                             "(a header line is required)", source=where0, field=c or "header")
    if "keypoints" not in columns:
        raise InputError(f"no 'keypoints' column; the header is {','.join(COLUMNS)} (only "
                         "keypoints is required)", source=where0, field="keypoints")
    if len(set(columns)) != len(columns):
        dup = next(c for c in columns if columns.count(c) > 1)
        raise InputError("column given twice", source=where0, field=dup)
    recordings = []
    for n, row in rows[1:]:
        where = f"{path} line {n}"
        if len(row) > len(columns):
            raise InputError(f"{len(row)} fields, but the header has {len(columns)}",
                             source=where)
        values = {c: (row[i].strip() if i < len(row) else "") for i, c in enumerate(columns)}
        kp = values.get("keypoints", "")
        if not kp:
            raise InputError("empty: the keypoint input of the recording", source=where,
                             field="keypoints")
        keypoints = base / kp
        intr = values.get("intrinsics") or None
        out = values.get("out") or None
        out_path = base / out if out else out_dir / f"{Path(kp).stem}.calibration.json"
        recordings.append(Recording(
            name=kp, keypoints=keypoints, intrinsics=None if intr is None else base / intr,
            out=out_path, subject_height=_height(values.get("subject_height", ""), where),
            where=where))
    return recordings


def _height(text: str, where: str) -> float | None:
    if not text:
        return None
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"not a number: {text!r}", source=where,
                         field="subject_height") from None
    if not math.isfinite(value) or value <= 0:
        raise InputError(f"must be a positive number of metres, got {text!r}", source=where,
                         field="subject_height")
    problem = height_problem(value)
    if problem is not None:
        raise InputError(problem, source=where, field="subject_height")
    return value


def _read_folder(path: Path, out_dir: Path | None) -> list[Recording]:
    try:
        subs = sorted(p for p in path.iterdir() if p.is_dir() and not p.name.startswith("."))
    except OSError as e:
        raise InputError(f"cannot list folder ({e.strerror})", source=path) from None
    if not subs:
        raise InputError("holds no recording subfolders (each with keypoints_mmpose.json, "
                         "openpose/, easymocap/ or a .npz, and optionally camera.json)",
                         source=path)
    recordings = []
    for sub in subs:
        found = _folder_input(sub)
        camera = None if found is not None and found.name == RIG_FILE else next(
            (sub / c for c in FOLDER_CAMERAS if (sub / c).is_file()), None)
        out = sub / FOLDER_OUT if out_dir is None else out_dir / f"{sub.name}.calibration.json"
        recordings.append(Recording(name=sub.name, keypoints=found,
                                    intrinsics=camera, out=out, where=str(sub)))
    return recordings


def _folder_input(sub: Path) -> Path | None:
    if (sub / RIG_FILE).is_file():
        return sub / RIG_FILE
    for name in FOLDER_INPUTS:
        if (sub / name).exists():
            return sub / name
    npz = sorted(p for p in sub.glob("*.npz")
                 if p.is_file() and not p.name.startswith("ground_truth"))
    if "keypoints.npz" in [p.name for p in npz]:
        return sub / "keypoints.npz"
    return npz[0] if len(npz) == 1 else None


# --------------------------------------------------------------------------- one task
def calibrate_recording(recording: Recording, options: CalibrateOptions) -> BatchResult:
    """Calibrate one recording and write its calibration atomically; never raises.

    This is the task each Dask worker runs. Every error becomes a failed
    :class:`BatchResult` carrying the one-line message the CLI would print.
    """
    t0 = time.perf_counter()
    rec = recording
    result = BatchResult(name=rec.name, status=FAILED,
                         keypoints=None if rec.keypoints is None else str(rec.keypoints))
    try:
        if rec.keypoints is None:
            raise InputError("no keypoint input: expected keypoints_mmpose.json, openpose/, "
                             "easymocap/ or one .npz", source=rec.where)
        if rec.out.is_dir():
            raise InputError("is a folder; give a file name for the calibration JSON",
                             source=rec.out, field="out")
        opts = options if rec.subject_height is None else \
            replace(options, subject_height=rec.subject_height)
        if Path(rec.keypoints).suffix.lower() == ".toml":
            result = _calibrate_rig(rec, opts, result)
            result.seconds = time.perf_counter() - t0
            return result
        intr = None if rec.intrinsics is None else load_intrinsics(rec.intrinsics)
        run = calibrate(rec.keypoints, intr, opts)
        cal = run.calibration
        cal.input.setdefault("subject_height", opts.subject_height)     # for a recomputation
        cal.input.setdefault("scale_from", getattr(opts.refine_options, "scale_from", "stature"))
        rec.out.parent.mkdir(parents=True, exist_ok=True)
        write_calibration_and_run(rec.out, run)     # with the run its report draws from
        std = cal.uncertainty.get("rotation_std_deg") if cal.uncertainty else None
        result = replace(result, status=OK, out=str(rec.out),
                         normal=tuple(float(v) for v in cal.normal),
                         distance=None if cal.distance is None else float(cal.distance),
                         inlier_ratio=float(cal.inlier_ratio),
                         rotation_std_deg=None if std is None else float(std),
                         warnings=tuple(cal.warnings))
    except MirrorgraphError as e:
        result.message = _one_line(str(e))
    except OSError as e:  # e.g. the output folder cannot be created
        result.message = _one_line(f"{e.filename or rec.out}: {e.strerror or e}")
    except Exception as e:  # noqa: BLE001 - a task never raises: it reports
        result.message = _one_line(f"internal error: {type(e).__name__}: {e}")
    result.seconds = time.perf_counter() - t0
    return result


def _calibrate_rig(rec: Recording, opts: CalibrateOptions, result: BatchResult) -> BatchResult:
    """A rig recording: :func:`mirrorgraph.calibrate_rig` with the batch's options, the rig
    JSON to ``rec.out`` and Pose2Sim's camera file beside it (the errors are the caller's
    to report)."""
    import numpy as np

    from .export import write_rig_toml
    from .result.rig import write_rig_json
    from .pipelines.rig import calibrate_rig

    if rec.intrinsics is not None:
        raise InputError("a rig file lists its cameras' intrinsics itself: leave "
                         "'intrinsics' empty", source=rec.where, field="intrinsics")
    cal = calibrate_rig(rec.keypoints, opts)
    rec.out.parent.mkdir(parents=True, exist_ok=True)
    write_rig_json(cal, rec.out)
    write_rig_toml(cal, rec.out.with_suffix(".toml"))
    stds = [c.rotation_std_deg for c in cal.cameras[1:]] + [m.rotation_std_deg for m in cal.mirrors]
    stds = [v for v in stds if np.isfinite(v)]
    return replace(result, status=OK, out=str(rec.out), cameras=len(cal.cameras),
                   rotation_std_deg=max(stds) if stds else None, warnings=tuple(cal.warnings))


def _one_line(text: str) -> str:
    return " ".join(text.split())


# --------------------------------------------------------------------------- the batch
#: ``progress(result, done, total)``: called in the client as each recording finishes.
BatchProgress = Callable[[BatchResult, int, int], None]


def default_workers(n_recordings: int) -> int:
    """Local workers: one per core this process may use, no more than there are recordings."""
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    return max(1, min(cores, n_recordings))


def run_batch(recordings: Sequence[Recording], *, scheduler: str | None = None,
              workers: int | None = None, options: CalibrateOptions | None = None,
              progress: BatchProgress | None = None) -> list[BatchResult]:
    """Calibrate every recording on a Dask cluster; results in the recordings' order.

    Args:
        recordings: what :func:`read_manifest` returned.
        scheduler: address of an existing Dask scheduler (``tcp://host:8786``); ``None``
            starts a local cluster of ``workers`` single-threaded worker processes.
        workers: local worker processes (default: one per core, at most one per
            recording); ignored with ``scheduler``.
        options: pipeline options shared by every recording (a recording's
            ``subject_height`` overrides the one in ``options``).
        progress: ``progress(result, done, total)`` as each recording finishes.

    Returns:
        one :class:`BatchResult` per recording. A failed recording (bad input,
        degenerate data, a worker that died) is a result with status ``"failed"``; it
        never stops the others.

    Raises:
        MirrorgraphError: Dask is not installed (:class:`MissingExtraError`),
            ``workers`` is not positive, or the scheduler cannot be reached.
    """
    recordings = list(recordings)
    options = options or CalibrateOptions()
    # the recordings are the parallel work: a long one's chunks are solved in its worker
    options = replace(options, refine_options=replace(options.refine_options or RefineOptions(),
                                                      workers=1))
    if not recordings:
        return []
    if workers is not None and workers < 1:
        raise InputError(f"must be at least 1, got {workers}", field="workers")
    # the batch extra: Dask is optional, imported only to run a batch
    distributed = require_extra("dask.distributed", "batch", "mirrorgraph batch", what="Dask")
    Client, LocalCluster = distributed.Client, distributed.LocalCluster
    as_completed = distributed.as_completed

    cluster = None
    if scheduler:
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError, ValueError) as e:
            raise InputError(f"cannot connect to the Dask scheduler {scheduler!r} ({e})",
                             field="scheduler") from None
    else:
        try:
            cluster = LocalCluster(n_workers=workers or default_workers(len(recordings)),
                                   threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.ERROR)
            client = Client(cluster)
        except Exception as e:  # noqa: BLE001 - e.g. no process could be spawned
            if cluster is not None:
                cluster.close()
            raise MirrorgraphError(f"cannot start a local Dask cluster ({type(e).__name__}: "
                                   f"{e})") from None
    results: list[BatchResult | None] = [None] * len(recordings)
    try:
        futures = [client.submit(calibrate_recording, rec, options, pure=False,
                                 key=f"mirrorgraph-{i}-{os.getpid()}-{time.time_ns()}")
                   for i, rec in enumerate(recordings)]
        index = {f.key: i for i, f in enumerate(futures)}
        for done, fut in enumerate(as_completed(futures), start=1):
            i = index[fut.key]
            try:
                res = fut.result()
            except Exception as e:  # noqa: BLE001 - the worker died or lost the task
                rec = recordings[i]
                res = BatchResult(name=rec.name, status=FAILED,
                                  message=_one_line(f"worker failed: {type(e).__name__}: {e}"),
                                  keypoints=None if rec.keypoints is None
                                  else str(rec.keypoints))
            results[i] = res
            if progress is not None:
                progress(res, done, len(recordings))
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return [r for r in results if r is not None]


# --------------------------------------------------------------------------- summary
def format_summary(results: Sequence[BatchResult]) -> str:
    """A plain-text table of every result, then a count line.

    Columns: recording, status, mirror normal, distance, inlier ratio, rotation std,
    time, and the output written or the error.
    """
    head = ("recording", "status", "normal", "distance", "inliers", "rot. std", "time",
            "output / error")
    rows = []
    for r in results:
        if r.ok and r.cameras:
            std = "-" if r.rotation_std_deg is None else f"<= {r.rotation_std_deg:.3f} deg"
            last = r.out + (f"  ({len(r.warnings)} warning{'s' * (len(r.warnings) != 1)})"
                            if r.warnings else "")
            rows.append((r.name, OK, f"rig of {r.cameras} cameras", "-", "-", std,
                         f"{r.seconds:.1f} s", last))
        elif r.ok:
            normal = "[" + ", ".join(f"{v:+.4f}" for v in r.normal) + "]"
            dist = "unknown" if r.distance is None else f"{r.distance:.3f} m"
            inl = f"{100 * r.inlier_ratio:.1f}%"
            std = "-" if r.rotation_std_deg is None else f"{r.rotation_std_deg:.3f} deg"
            last = r.out + (f"  ({len(r.warnings)} warning{'s' * (len(r.warnings) != 1)})"
                            if r.warnings else "")
            rows.append((r.name, OK, normal, dist, inl, std, f"{r.seconds:.1f} s", last))
        else:
            rows.append((r.name, "FAILED", "-", "-", "-", "-", f"{r.seconds:.1f} s",
                         r.message))
    widths = [max(len(h), *(len(row[k]) for row in rows)) if rows else len(h)
              for k, h in enumerate(head)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(head, widths)).rstrip(),
             "  ".join("-" * w for w in widths)]
    lines += ["  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in rows]
    n_ok = sum(r.ok for r in results)
    lines.append(f"{len(results)} recording{'s' * (len(results) != 1)}: {n_ok} ok, "
                 f"{len(results) - n_ok} failed")
    return "\n".join(lines)


def results_to_json(results: Sequence[BatchResult]) -> list[dict]:
    """Plain-JSON form of the results (what ``--report`` writes)."""
    return [asdict(r) for r in results]
