"""Frames from a video file or a live camera, through OpenCV's video reader (``cv2.VideoCapture``:
FFmpeg here, so any container and codec it opens).

A lossy codec destroys what the pipeline measures: faint phosphor dots sink into its block
noise and hot pixels are smeared into neighbours (so the dark frame no longer matches them);
:func:`codec_warning` names it. Lossless codecs -- FFV1, PNG in MKV/AVI, HuffYUV, raw BGR -- give
the frames exactly (tested against the same frames as PNG files).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from stcvision.errors import BadInputError

__all__ = ["LOSSLESS_FOURCCS", "Frame", "VideoSource", "codec_warning", "open_device", "open_video"]

#: codecs that keep every pixel of a BGR frame (OpenCV's FFmpeg reader reports these FourCCs)
LOSSLESS_FOURCCS = frozenset(
    {"FFV1", "MPNG", "PNG ", "HFYU", "FFVH", "LAGS", "RGBA", "RGB ", "DIB ", "BGR ", "\0\0\0\0"}
)


class Frame(NamedTuple):
    """A frame and its time: ``index`` in its source, ``image`` (BGR), ``t_s`` in seconds, and
    ``stamp_ns``, the exact stamp in integer nanoseconds where the source has one (a recording's
    header stamp), else None."""

    index: int
    image: np.ndarray
    t_s: float
    stamp_ns: int | None = None


@dataclass
class VideoSource:
    """An open capture: ``name`` for messages, ``fourcc`` of its codec, ``frame_count`` (None for
    a live camera or when the container does not say)."""

    cap: object
    name: str
    fourcc: str
    frame_count: int | None
    live: bool

    def frames(self, *, start: int = 0, count: int | None = None, every: int = 1) -> Iterator[Frame]:
        """Yield :class:`Frame`: frames ``start``, ``start + every``, ... (at most ``count``).

        A video file's frame time is its container's timestamp (OpenCV's ``CAP_PROP_POS_MSEC``,
        the frame just decoded); a live camera's is this computer's clock (Unix time)
        when the frame arrived, so that it lines up with other recordings made on it.
        """
        import time

        import cv2

        if start:
            if self.live:
                raise BadInputError("--start: a live camera has no earlier frames to skip to")
            if self.frame_count is not None and start >= self.frame_count:
                raise BadInputError(f"--start {start}: {self.name} has {self.frame_count} frames")
            # seeking is exact for intra-only codecs (FFV1, PNG, MJPEG); otherwise read up to it
            if not self.cap.set(cv2.CAP_PROP_POS_FRAMES, start):
                for _ in range(start):
                    if not self.cap.grab():
                        return
        index, taken = start, 0
        while count is None or taken < count:
            ok, frame = self.cap.read()
            if not ok:
                return
            # to the microsecond: the container counts in its own time base, not in binary fractions
            t_s = time.time() if self.live else round(self.cap.get(cv2.CAP_PROP_POS_MSEC) / 1000.0, 6)
            yield Frame(index, frame, t_s)
            taken += 1
            for _ in range(every - 1):  # skip without decoding into numpy
                index += 1
                if not self.cap.grab():
                    return
            index += 1

    def close(self) -> None:
        self.cap.release()


def _capture(source, *args):
    """cv2.VideoCapture without OpenCV's and FFmpeg's own log lines on stderr (a file it cannot
    open is our one-line error, not theirs as well)."""
    import os

    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET, read when FFmpeg loads
    import cv2

    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    try:
        return cv2.VideoCapture(source, *args)
    finally:
        cv2.utils.logging.setLogLevel(level)


def _fourcc(cap) -> str:
    import cv2

    code = int(cap.get(cv2.CAP_PROP_FOURCC)) & 0xFFFFFFFF
    return code.to_bytes(4, "little").decode("latin-1")


def open_video(path) -> VideoSource:
    """Open a video file; one line naming it when OpenCV cannot."""
    import os

    import cv2

    path = str(path)
    if not os.path.exists(path):
        raise BadInputError(f"video {path} does not exist")
    if os.path.isdir(path):
        raise BadInputError(f"video {path} is a directory; expected a video file")
    cap = _capture(path, cv2.CAP_FFMPEG)
    if not cap.isOpened():
        cap.release()
        raise BadInputError(
            f"video {path} cannot be opened by OpenCV's video reader (not a video, or its codec is missing)"
        )
    n = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    return VideoSource(cap, f"video {path}", _fourcc(cap), n if n > 0 else None, live=False)


def open_device(index: int) -> VideoSource:

    cap = _capture(int(index))
    if not cap.isOpened():
        cap.release()
        raise BadInputError(f"camera device {index} cannot be opened (no such camera, or it is busy)")
    return VideoSource(cap, f"camera device {index}", _fourcc(cap), None, live=True)


def codec_warning(src: VideoSource) -> str | None:
    """A warning naming what a lossy codec destroys; None for a lossless one."""
    if src.fourcc.upper() in {f.upper() for f in LOSSLESS_FOURCCS}:
        return None
    name = src.fourcc.strip("\0 ") or "unknown"
    return (
        f"{src.name} is coded with {name!r}, a lossy codec: it blurs faint phosphor dots into its block noise and "
        "smears hot pixels (the dark frame no longer matches them); record losslessly (FFV1, or PNG in MKV/AVI) "
        "for measurements"
    )
