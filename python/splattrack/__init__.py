"""splattrack: 6-DoF tracking of a rigid object in video from a point model.

The native module (``splattrack._splattrack``) is the Rust library the
``splattrack`` command runs; this package adds the frame readers
(:func:`iter_frames`, :func:`track_frames`). See docs/python.md.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from typing import Iterator, Tuple, Union

from ._splattrack import (
    Camera,
    Error,
    GpuError,
    InputError,
    Model,
    ModelError,
    MultiTracker,
    Tracker,
    TrackError,
    TrackResult,
    __version__,
    device,
    list_images,
    read_image,
)

__all__ = [
    "Camera",
    "Error",
    "GpuError",
    "InputError",
    "Model",
    "ModelError",
    "MultiTracker",
    "Tracker",
    "TrackError",
    "TrackResult",
    "__version__",
    "device",
    "iter_frames",
    "list_images",
    "read_image",
    "track_frames",
]

PathLike = Union[str, "os.PathLike[str]"]


def iter_frames(source: PathLike) -> Iterator["numpy.ndarray"]:  # noqa: F821
    """Yields the frames of ``source`` as HxWx3 uint8 RGB arrays, in order.

    ``source`` is a frames folder (PNG, JPEG; in the natural order of their
    names, as the command line reads them), a sequence folder (its
    ``frames/``), or a video file: read with OpenCV when it is installed,
    else through the ``ffmpeg`` program. Raises :class:`InputError` when
    the source cannot be read.
    """
    path = os.fspath(source)
    if os.path.isdir(path):
        frames = os.path.join(path, "frames")
        folder = frames if os.path.isdir(frames) else path
        for image in list_images(folder):
            yield read_image(image)
        return
    if not os.path.isfile(path):
        raise InputError(f"{path}: no such file or folder")
    try:
        import cv2  # type: ignore
    except ImportError:
        cv2 = None
    if cv2 is not None:
        yield from _frames_cv2(cv2, path)
    else:
        yield from _frames_ffmpeg(path)


def _frames_cv2(cv2, path: str):
    cap = cv2.VideoCapture(path)
    if not cap.isOpened():
        raise InputError(f"{path}: OpenCV cannot open this video")
    try:
        while True:
            ok, bgr = cap.read()
            if not ok:
                return
            yield cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
    finally:
        cap.release()


def _frames_ffmpeg(path: str):
    import numpy as np

    if shutil.which("ffprobe") is None or shutil.which("ffmpeg") is None:
        raise InputError(
            f"{path}: reading a video needs OpenCV (pip install opencv-python-headless) "
            "or the ffmpeg program"
        )
    probe = subprocess.run(
        ["ffprobe", "-v", "error", "-select_streams", "v:0", "-show_entries",
         "stream=width,height", "-of", "csv=p=0:s=x", path],
        capture_output=True, text=True,
    )
    try:
        w, h = (int(v) for v in probe.stdout.strip().splitlines()[0].split("x")[:2])
    except (ValueError, IndexError):
        raise InputError(f"{path}: ffprobe finds no video stream") from None
    proc = subprocess.Popen(
        ["ffmpeg", "-v", "error", "-i", path, "-f", "rawvideo", "-pix_fmt", "rgb24", "-"],
        stdout=subprocess.PIPE,
    )
    size = w * h * 3
    try:
        while True:
            data = proc.stdout.read(size)
            if len(data) < size:
                return
            yield np.frombuffer(data, dtype=np.uint8).reshape(h, w, 3)
    finally:
        proc.kill()
        proc.wait()


def track_frames(tracker: Tracker, source: PathLike) -> Iterator[Tuple[int, TrackResult]]:
    """Tracks every frame of ``source`` (see :func:`iter_frames`) in order,
    yielding ``(index, result)`` as each is tracked."""
    for i, frame in enumerate(iter_frames(source)):
        yield i, tracker.track(frame)
