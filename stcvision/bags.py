"""Frames from a robot's recordings: ROS 1 bags (``.bag``), ROS 2 bags (a folder with
``metadata.yaml`` and ``.db3`` or ``.mcap`` files, or one such file) and MCAP files, read with
`rosbags <https://pypi.org/project/rosbags/>`_, a pure-Python reader: no ROS installation.

A topic of ``sensor_msgs/Image`` (mono8, mono16, rgb8, bgr8, rgba8, bgra8, rgb16, bgr16 and the
Bayer patterns at 8 and 16 bits) or ``sensor_msgs/CompressedImage`` (PNG, JPEG) becomes BGR
frames as the pipeline reads them from PNG files: 8-bit, or 16-bit ADC counts never divided by
256. Each frame carries its message's header stamp.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from stcvision.errors import BadInputError
from stcvision.video import Frame

__all__ = [
    "IMAGE_TYPES",
    "BagSource",
    "colour_warning",
    "image_from_message",
    "open_bag",
    "parse_stamp",
    "read_frame",
    "stamp_text",
]

_RAW = "sensor_msgs/msg/Image"
_COMPRESSED = "sensor_msgs/msg/CompressedImage"
#: the message types read as frames (rosbags names ROS 1 types the ROS 2 way, with ``/msg/``)
IMAGE_TYPES = frozenset({_RAW, _COMPRESSED})

_NS_PER_S = 1_000_000_000

# encoding -> (channels, bytes per channel, OpenCV conversion to BGR or None); the Bayer names
# are the ROS ones (the colour of the first two pixels of the first two rows), which OpenCV's
# COLOR_Bayer<pattern>2BGR codes name the same way
_ENCODINGS = {
    "mono8": (1, 1, "COLOR_GRAY2BGR"),
    "mono16": (1, 2, "COLOR_GRAY2BGR"),
    "8UC1": (1, 1, "COLOR_GRAY2BGR"),
    "16UC1": (1, 2, "COLOR_GRAY2BGR"),
    "bgr8": (3, 1, None),
    "bgr16": (3, 2, None),
    "8UC3": (3, 1, None),
    "16UC3": (3, 2, None),
    "rgb8": (3, 1, "COLOR_RGB2BGR"),
    "rgb16": (3, 2, "COLOR_RGB2BGR"),
    "bgra8": (4, 1, "COLOR_BGRA2BGR"),
    "rgba8": (4, 1, "COLOR_RGBA2BGR"),
    **{
        f"bayer_{p}{bits}": (1, bits // 8, f"COLOR_Bayer{p.upper()}2BGR")
        for p in ("rggb", "bggr", "gbrg", "grbg")
        for bits in (8, 16)
    },
}
_MONO = frozenset(e for e, (c, _, conv) in _ENCODINGS.items() if c == 1 and conv == "COLOR_GRAY2BGR")


def colour_warning(encoding: str) -> str | None:
    """A warning for images that cannot show what the pipeline separates by colour.

    Parameters
    ----------
    encoding : str
        A ``sensor_msgs/Image`` encoding, or ``"jpeg"`` for a compressed image.

    Returns
    -------
    str or None
        The warning (a monochrome camera's frames, a lossy codec's), or None.
    """
    if encoding in _MONO:
        return (
            f"{encoding} images have no colour: they are read as grey in all three channels, so the red lights "
            "cannot be told from the green marks (a monochrome camera sees the marks only)"
        )
    if encoding in ("jpeg", "jpg"):
        return (
            "JPEG-compressed images: a lossy codec blurs faint phosphor dots into its block noise and smears hot "
            "pixels (the dark frame no longer matches them); record raw or PNG-compressed images for measurements"
        )
    return None


def image_from_message(msg, msgtype: str) -> np.ndarray:
    """Turn an image message into a BGR frame.

    Parameters
    ----------
    msg : object
        A deserialised ``sensor_msgs/Image`` or ``sensor_msgs/CompressedImage``.
    msgtype : str
        Its type, as rosbags names it (``sensor_msgs/msg/Image``).

    Returns
    -------
    numpy.ndarray
        (H, W, 3) BGR, uint8 or uint16 (16-bit encodings keep their counts).

    Raises
    ------
    BadInputError
        For an encoding it does not read, or data shorter than the header says.
    """
    import cv2

    from stcvision.fileio import quiet_opencv

    if msgtype == _COMPRESSED:
        with quiet_opencv():
            img = cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise BadInputError(f"a compressed image ({msg.format!r}) cannot be decoded; expected PNG or JPEG")
        if img.dtype not in (np.uint8, np.uint16):
            raise BadInputError(f"a compressed image holds {img.dtype} pixels; expected 8- or 16-bit")
        if img.ndim == 2:
            return cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
        return img[:, :, :3] if img.shape[2] == 4 else img
    enc = msg.encoding
    if enc not in _ENCODINGS:
        raise BadInputError(f"image encoding {enc!r} is not read; expected one of {', '.join(sorted(_ENCODINGS))}")
    channels, nbytes, conv = _ENCODINGS[enc]
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    row = w * channels * nbytes
    data = np.asarray(msg.data, dtype=np.uint8).reshape(-1)
    if h < 1 or w < 1 or step < row or data.size < step * h:
        raise BadInputError(
            f"a {enc} image of {w}x{h} (step {step}) holds {data.size:,} bytes; expected at least {row * h:,}"
        )
    rows = data[: step * h].reshape(h, step)[:, :row]
    if nbytes == 2:
        rows = np.ascontiguousarray(rows).view(">u2" if msg.is_bigendian else "<u2").astype(np.uint16)
    img = np.ascontiguousarray(rows).reshape(h, w, channels) if channels > 1 else np.ascontiguousarray(rows)
    return img if conv is None else cv2.cvtColor(img, getattr(cv2, conv))


def _encoding(msg, msgtype: str) -> str:
    """The encoding a warning is about: a raw image's, or ``jpeg`` for a JPEG-compressed one."""
    if msgtype == _COMPRESSED:
        fmt = msg.format.lower()
        return "jpeg" if "jpeg" in fmt or "jpg" in fmt else fmt
    return msg.encoding


def stamp_text(stamp_ns: int) -> str:
    """A stamp in integer nanoseconds as exact decimal seconds (``1700000000.000000123``).

    Parameters
    ----------
    stamp_ns : int
        Nanoseconds.

    Returns
    -------
    str
        The seconds with all nine decimals.
    """
    sec, ns = divmod(int(stamp_ns), _NS_PER_S)
    return f"{sec}.{ns:09d}"


def parse_stamp(text: str) -> int:
    """A header stamp given in decimal seconds (``1700000000.000000123``), as integer nanoseconds.

    Parameters
    ----------
    text : str
        Seconds, with up to nine decimals (read exactly, not through a float).

    Returns
    -------
    int
        Nanoseconds.

    Raises
    ------
    BadInputError
        If ``text`` is not a number of seconds >= 0 with at most nine decimals.
    """
    from decimal import Decimal, InvalidOperation

    try:
        sec = Decimal(text.strip())
    except InvalidOperation:
        raise BadInputError(f"stamp {text!r} is not a number of seconds (e.g. 1700000000.000000123)") from None
    if not sec.is_finite() or sec < 0 or (sec * _NS_PER_S) != (sec * _NS_PER_S).to_integral_value():
        raise BadInputError(f"stamp {text!r}: expected seconds >= 0 with at most nine decimals")
    return int(sec * _NS_PER_S)


def _stamp_ns(msg) -> int:
    stamp = msg.header.stamp
    return int(stamp.sec) * _NS_PER_S + int(stamp.nanosec)


@dataclass
class BagSource:
    """An open recording and one image topic of it.

    ``name`` names it in messages, ``frame_count`` is the topic's message count, ``encoding``
    the first frame's (known once it is read).
    """

    reader: object
    name: str
    topic: str
    connections: list
    msgtype: str
    frame_count: int
    live: bool = False
    encoding: str | None = field(default=None)

    def frames(
        self, *, start_s: float = 0.0, end_s: float | None = None, count: int | None = None, every: int = 1
    ) -> Iterator[Frame]:
        """Yield the topic's frames in recording order, each with its header stamp.

        Parameters
        ----------
        start_s, end_s : float
            Seconds from the recording's start on its own clock (the time each message was
            recorded, as ``rosbag play --start`` and ``ros2 bag play --start-offset`` count):
            the messages recorded in ``[start_s, end_s)``.
        count : int, optional
            At most this many frames.
        every : int
            One message in ``every``.

        Yields
        ------
        Frame
            ``index`` (the message's position in the topic), ``image``, ``t_s`` and
            ``stamp_ns`` (the header stamp).
        """
        t0 = self.reader.start_time
        start = t0 + round(start_s * _NS_PER_S)
        stop = None if end_s is None else t0 + round(end_s * _NS_PER_S)
        # the messages before --start still count in the index, so that an index names the same
        # message whatever the window
        skipped = 0
        if start_s > 0:
            skipped = sum(1 for _ in self._raw(stop=start))
        index, taken = skipped, 0
        for k, (conn, raw) in enumerate(self._raw(start=start, stop=stop)):
            if count is not None and taken >= count:
                return
            if k % every == 0:
                try:
                    msg = self.reader.deserialize(raw, conn.msgtype)
                except Exception as exc:  # a damaged message is the file's fault, in one line
                    raise BadInputError(f"{self.name}: message {index} of {self.topic} cannot be read: {exc}") from None
                if self.encoding is None:
                    self.encoding = _encoding(msg, conn.msgtype)
                try:
                    image = image_from_message(msg, conn.msgtype)
                except BadInputError as exc:
                    raise BadInputError(f"{self.name}: message {index} of {self.topic}: {exc}") from None
                ns = _stamp_ns(msg)
                yield Frame(index, image, ns / _NS_PER_S, ns)
                taken += 1
            index += 1

    def _raw(self, *, start: int | None = None, stop: int | None = None):
        """(connection, raw bytes) of the topic's messages, a damaged file's error in one line."""
        it = self.reader.messages(connections=self.connections, start=start, stop=stop)
        while True:
            try:
                conn, _, raw = next(it)
            except StopIteration:
                return
            except Exception as exc:
                raise BadInputError(f"{self.name} cannot be read past a damaged record: {exc}") from None
            yield conn, raw

    def close(self) -> None:
        """Close the recording."""
        try:
            self.reader.close()
        except Exception:  # closing a reader whose file failed to read is not a second error
            pass


def open_bag(path, topic: str) -> BagSource:
    """Open a recording at ``path`` and its image topic ``topic``.

    Parameters
    ----------
    path : str or os.PathLike
        A ROS 1 bag (``.bag``), a ROS 2 bag folder, or a ``.mcap`` or ``.db3`` file.
    topic : str
        The image topic (``sensor_msgs/Image`` or ``sensor_msgs/CompressedImage``).

    Returns
    -------
    BagSource
        The open recording; close it with :meth:`BagSource.close`.

    Raises
    ------
    BadInputError
        In one line: a path that is missing or not a recording, a damaged file, or a topic that
        is missing or not an image (naming the image topics present).
    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    p = Path(path)
    name = f"bag {p}"
    if not p.exists():
        raise BadInputError(f"{name} does not exist")
    if p.is_file() and p.suffix not in (".bag", ".mcap", ".db3"):
        raise BadInputError(f"{name}: expected a ROS 1 bag (.bag), a ROS 2 bag folder, or a .mcap or .db3 file")
    if p.is_dir() and not (p / "metadata.yaml").is_file():
        raise BadInputError(f"{name} is a folder without metadata.yaml; expected a ROS 2 bag folder")
    try:
        reader = AnyReader([p], default_typestore=get_typestore(Stores.LATEST))
        reader.open()
    except Exception as exc:  # rosbags' own errors, and whatever a damaged file raises in its parsers
        detail = str(exc).strip() or type(exc).__name__
        raise BadInputError(f"{name} cannot be read as a ROS bag or MCAP file: {detail}") from None
    images = sorted(t for t, info in reader.topics.items() if info.msgtype in IMAGE_TYPES)
    conns = [c for c in reader.connections if c.topic == topic]
    if not conns or any(c.msgtype not in IMAGE_TYPES for c in conns):
        what = f"has no topic {topic}" if not conns else f"topic {topic} is {conns[0].msgtype}, not an image"
        present = ", ".join(images) if images else "none"
        reader.close()
        raise BadInputError(f"{name}: {what}; image topics present: {present}")
    count = sum(c.msgcount for c in conns)
    return BagSource(reader, name, topic, conns, conns[0].msgtype, count)


def read_frame(path, topic: str, *, stamp_ns: int | None = None) -> tuple[np.ndarray, str]:
    """One frame of a recording's image topic: the message whose header stamp is ``stamp_ns``,
    or the first.

    Only the chosen message's image is decoded; the search reads at most ``MAX_VIDEO_FRAMES``
    messages (``stcvision.limits``), the cap of one pipeline run.

    Parameters
    ----------
    path : str or os.PathLike
        The recording (:func:`open_bag`).
    topic : str
        Its image topic.
    stamp_ns : int, optional
        The header stamp to find (:func:`parse_stamp`); None: the topic's first message.

    Returns
    -------
    image : ndarray
        The frame as the pipeline reads it (BGR, 8 or 16 bits).
    name : str
        What names it in messages and a profile's provenance: the file, the topic, the stamp.

    Raises
    ------
    BadInputError
        In one line: what :func:`open_bag` refuses, an empty topic, or no message with that
        stamp (with the range of stamps the topic has).
    """
    from stcvision.limits import MAX_VIDEO_FRAMES

    src = open_bag(path, topic)
    try:
        first = last = None
        for index, (conn, raw) in enumerate(src._raw()):
            if index == MAX_VIDEO_FRAMES:
                break
            try:
                msg = src.reader.deserialize(raw, conn.msgtype)
            except Exception as exc:  # a damaged message is the file's fault, in one line
                raise BadInputError(f"{src.name}: message {index} of {topic} cannot be read: {exc}") from None
            ns = _stamp_ns(msg)
            first = ns if first is None else first
            last = ns
            if stamp_ns is None or ns == stamp_ns:
                try:
                    image = image_from_message(msg, conn.msgtype)
                except BadInputError as exc:
                    raise BadInputError(f"{src.name}: message {index} of {topic}: {exc}") from None
                return image, f"{src.name} {topic} at stamp {stamp_text(ns)} s"
    finally:
        src.close()
    if first is None:
        raise BadInputError(f"{src.name}: no message on {topic}")
    read = f"the first {MAX_VIDEO_FRAMES:,} messages' stamps" if index == MAX_VIDEO_FRAMES else "its stamps"
    raise BadInputError(
        f"{src.name}: no message on {topic} has header stamp {stamp_text(stamp_ns)} s; "
        f"{read} run from {stamp_text(first)} to {stamp_text(last)} s"
    )
