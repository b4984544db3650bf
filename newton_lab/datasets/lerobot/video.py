"""Camera streams as LeRobot v3.0 video features: each image term becomes mp4 files under
``videos/observation.images.<term>/chunk-XXX/file-XXX.mp4``, episodes appended one after another in a file, a new
file once one passes ``video_files_size_in_mb``. Encoded with PyAV (its wheel bundles FFmpeg).

Codec as LeRobot encodes by default: AV1 (``libsvtav1``), ``yuv420p``, a key frame every 2 frames (``g=2``), CRF 30;
where the bundled FFmpeg lacks SVT-AV1, H.264 (``libx264``, CRF 23). yuv420p needs even sizes: an odd width or
height is padded by one edge-replicated column / row, and the feature declares the padded shape.
"""

from __future__ import annotations

import os
from fractions import Fraction
from pathlib import Path
from typing import Any

import av
import numpy as np

from .tables import CHUNKS_SIZE, VIDEO_PATH

PIX_FMT = "yuv420p"
VIDEO_COLUMNS = ("chunk_index", "file_index", "from_timestamp", "to_timestamp")
"""Per-episode columns ``videos/<key>/<column>`` of meta/episodes: where the episode's frames are."""
CODECS: tuple[tuple[str, dict[str, str]], ...] = (
    ("libsvtav1", {"g": "2", "crf": "30", "preset": "8"}),
    ("libx264", {"g": "2", "crf": "23", "preset": "veryfast"}),
)
"""Codecs in order of preference, with their encoder options (LeRobot's defaults: AV1, g=2, CRF 30)."""


def video_codec() -> tuple[str, dict[str, str]]:
    """The first codec of ``CODECS`` that PyAV's FFmpeg can encode, with its options."""
    for name, options in CODECS:
        if name in av.codecs_available:
            return name, dict(options)
    raise RuntimeError(f"PyAV's FFmpeg has none of the encoders {[c for c, _ in CODECS]}; reinstall av==18.1.0")


def even_shape(shape: tuple[int, int, int]) -> tuple[int, int, int]:
    """(H, W, 3) of the encoded frames: odd sizes padded to even (yuv420p subsamples chroma by 2)."""
    h, w, c = shape
    return h + h % 2, w + w % 2, c


def video_info(shape: tuple[int, int, int], fps: int) -> dict[str, Any]:
    """The ``info`` block of a video feature in ``info.json``."""
    h, w, c = even_shape(shape)
    return {
        "video.height": h,
        "video.width": w,
        "video.codec": video_codec()[0].removeprefix("lib"),
        "video.pix_fmt": PIX_FMT,
        "video.is_depth_map": False,
        "video.fps": fps,
        "video.channels": c,
        "has_audio": False,
    }


def _padded(frames: np.ndarray) -> np.ndarray:
    h, w = frames.shape[1:3]
    if h % 2 == 0 and w % 2 == 0:
        return frames
    return np.pad(frames, ((0, 0), (0, h % 2), (0, w % 2), (0, 0)), mode="edge")


class VideoFiles:
    """One video feature's mp4 files: ``write`` appends an episode's frames and returns where they are."""

    def __init__(self, root: Path, video_key: str, fps: int, limit_bytes: int) -> None:
        self.root, self.key, self.fps, self.limit = root, video_key, fps, limit_bytes
        self.codec, self.options = video_codec()
        self.chunk = self.file = 0
        self.frames_in_file = self.bytes_in_file = 0
        self.container: Any = None
        self.stream: Any = None
        self.path: Path | None = None
        self.paths: list[str] = []

    def write(self, frames: np.ndarray) -> dict[str, Any]:
        """Encode (T, H, W, 3) uint8 ``frames``; returns the episode's ``videos/<key>/...`` columns."""
        if self.container is not None and self.bytes_in_file > self.limit:
            self._close_file()
            self.file += 1
            if self.file == CHUNKS_SIZE:
                self.chunk, self.file = self.chunk + 1, 0
        frames = _padded(frames)
        if self.container is None:
            self._open(frames.shape[2], frames.shape[1])
        start = self.frames_in_file
        for image in frames:
            frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(image), format="rgb24")
            frame.pts = self.frames_in_file
            self.frames_in_file += 1
            self._mux(self.stream.encode(frame))
        where = (self.chunk, self.file, start / self.fps, self.frames_in_file / self.fps)
        return {f"videos/{self.key}/{column}": value for column, value in zip(VIDEO_COLUMNS, where)}

    def _open(self, width: int, height: int) -> None:
        os.environ.setdefault("SVT_LOG", "1")  # SVT-AV1 prints its banner and config to stderr: errors only
        rel = VIDEO_PATH.format(video_key=self.key, chunk_index=self.chunk, file_index=self.file)
        self.path = self.root / rel
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.container = av.open(str(self.path), mode="w")
        self.stream = self.container.add_stream(self.codec, rate=self.fps, options=self.options)
        self.stream.width, self.stream.height, self.stream.pix_fmt = width, height, PIX_FMT
        self.stream.time_base = Fraction(1, self.fps)
        self.paths.append(rel)
        self.frames_in_file = self.bytes_in_file = 0

    def _mux(self, packets: list[Any]) -> None:
        for packet in packets:
            self.bytes_in_file += packet.size
            self.container.mux(packet)

    def _close_file(self) -> None:
        self._mux(self.stream.encode())  # flush the encoder's delayed frames
        self.container.close()
        self.container = self.stream = None

    def close(self) -> None:
        if self.container is not None:
            self._close_file()


def decode_frames(path: Path) -> tuple[np.ndarray, dict[str, Any]]:
    """All frames of an mp4 as (N, H, W, 3) uint8, and its stream's width, height, fps and decoder."""
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(stream)]
        meta = _stream_meta(stream)
    return (np.stack(frames) if frames else np.zeros((0, meta["height"], meta["width"], 3), np.uint8)), meta


def probe(path: Path) -> dict[str, Any]:
    """Width, height, fps, decoder and decoded frame count of an mp4 (every frame is decoded: a damaged or
    truncated file raises ``ValueError``)."""
    try:
        with av.open(str(path)) as container:
            stream = container.streams.video[0]
            frames = sum(1 for _ in container.decode(stream))
            return {**_stream_meta(stream), "frames": frames}
    except (av.FFmpegError, IndexError, OSError) as exc:
        raise ValueError(f"cannot be decoded ({type(exc).__name__}: {exc})") from None


def _stream_meta(stream: Any) -> dict[str, Any]:
    return {
        "width": stream.codec_context.width,
        "height": stream.codec_context.height,
        "fps": float(stream.average_rate or stream.base_rate or 0),
        "codec": stream.codec_context.name,
    }
