"""Video files out: an OpenCV writer in the codec the build has that browsers play.

Browsers play H.264 (``avc1``) in MP4 and VP8 / VP9 in WebM; MPEG-4 part 2 (``mp4v``),
which every OpenCV build writes, they do not. The PyPI wheels of
``opencv-python-headless`` ship FFmpeg without an H.264 encoder (``avc1`` does not open)
but with libvpx (VP9 at about 80 ms CPU a 1080p frame against 10 ms for ``mp4v``), so
``.mp4`` falls back to ``mp4v`` with a note saying so, and ``.webm`` is VP9 (else VP8).
"""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path

from ..errors import InputError

__all__ = ["open_video_writer", "CODECS"]


@contextlib.contextmanager
def _quiet_stderr():
    """The process's stderr (file descriptor 2, where FFmpeg's C library and OpenCV
    write) sent to the null device for the block."""
    import cv2

    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):
        saved = None
    try:
        if saved is not None:
            with open(os.devnull, "wb") as null:
                os.dup2(null.fileno(), 2)
        yield
    finally:
        if saved is not None:
            os.dup2(saved, 2)
            os.close(saved)
        cv2.utils.logging.setLogLevel(level)

#: fourcc codes tried, in order, by file extension; the first is what browsers play.
CODECS = {".webm": ("VP90", "VP80"), ".mp4": ("avc1", "mp4v"), ".m4v": ("avc1", "mp4v"),
          ".mov": ("avc1", "mp4v"), ".avi": ("MJPG",)}


def open_video_writer(path: str | os.PathLike, fps: float, size: tuple[int, int]):
    """An open :class:`cv2.VideoWriter` for ``path`` in the first codec of
    :data:`CODECS` the OpenCV build can write.

    Args:
        path: the file (``.mp4``, ``.webm``, ``.mov``, ``.m4v`` or ``.avi``).
        fps: frames a second; size: ``(width, height)`` px of every frame.

    Returns:
        ``(writer, fourcc, note)``: ``note`` says what a browser will not play (the
        fallback to ``mp4v``), else ``None``.

    Raises:
        InputError: an extension of no known container, or no codec of it opens.
    """
    import cv2

    path = Path(path)
    codecs = CODECS.get(path.suffix.lower())
    if codecs is None:
        raise InputError(f"a video's name ends in {', '.join(sorted(CODECS))}",
                         source=str(path))
    for fourcc in codecs:
        with _quiet_stderr():       # FFmpeg's own lines about an encoder it lacks
            writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), float(fps),
                                     tuple(int(v) for v in size))
        if writer.isOpened():
            note = None
            if fourcc == "mp4v":
                note = (f"{path.name}: this OpenCV build has no H.264 encoder, so the video "
                        "is MPEG-4 part 2 (mp4v), which browsers do not play (players such "
                        "as VLC do); name it .webm for VP9, which they play")
            return writer, fourcc, note
        writer.release()
    raise InputError(f"cannot be written: this OpenCV build opens none of "
                     f"{', '.join(codecs)}", source=str(path))
