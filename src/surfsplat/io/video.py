"""Animations: frames written as GIF (Pillow) or MP4/WebM (imageio-ffmpeg and its ffmpeg binary, the
optional ``video`` extra: ``pip install "surfsplat[video]"``), atomically (see :mod:`surfsplat.io.atomic`)."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path
from typing import Iterable

import numpy as np
from PIL import Image

from ..errors import InputError, file_reader
from .atomic import atomic_path

#: Suffixes :func:`write_video` writes, and the encoder of each.
VIDEO_SUFFIXES = {".gif": "pillow", ".mp4": "ffmpeg", ".webm": "ffmpeg"}


@file_reader
def check_video_path(path: str | os.PathLike) -> Path:
    """``path`` as a Path; InputError for a suffix :func:`write_video` does not write, or a missing
    ffmpeg for MP4/WebM (checked before any rendering)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in VIDEO_SUFFIXES:
        raise InputError(f"{path}: unsupported animation format {suffix!r}; use .gif, .mp4 or .webm")
    if VIDEO_SUFFIXES[suffix] == "ffmpeg":
        if importlib.util.find_spec("imageio_ffmpeg") is None:   # the optional `video` extra
            raise InputError(f"{path}: writing {suffix} needs imageio-ffmpeg: "
                             "pip install \"surfsplat[video]\" (or write a .gif)")
    return path


def _write_gif(frames: Iterable[np.ndarray], temp: Path, path: Path, fps: float) -> None:
    images = [Image.fromarray(frame) for frame in frames]
    if not images:
        raise InputError(f"{path}: no frames to write")
    images[0].save(temp, format="GIF", save_all=True, append_images=images[1:],
                   duration=max(1, round(1000.0 / fps)), loop=0)


def _write_ffmpeg(frames: Iterable[np.ndarray], temp: Path, path: Path, fps: float) -> None:
    import imageio_ffmpeg   # optional: the `video` extra (checked by check_video_path)

    codec, fmt = ("libx264", "mp4") if path.suffix.lower() == ".mp4" else ("libvpx-vp9", "webm")
    writer = None
    try:
        for frame in frames:
            h, w = frame.shape[:2]
            frame = np.ascontiguousarray(frame[: h - h % 2, : w - w % 2])   # even sizes for yuv420p
            if writer is None:
                writer = imageio_ffmpeg.write_frames(str(temp), (frame.shape[1], frame.shape[0]), fps=fps,
                                                     codec=codec, pix_fmt_out="yuv420p",
                                                     output_params=["-f", fmt], macro_block_size=1,
                                                     ffmpeg_log_level="error")
                writer.send(None)
            writer.send(frame)
    finally:
        if writer is not None:
            writer.close()
    if writer is None:
        raise InputError(f"{path}: no frames to write")


def write_video(frames: Iterable[np.ndarray], path: str | os.PathLike, *, fps: float,
                overwrite: bool = True) -> Path:
    """Write (H, W, 3) uint8 frames as an animation at ``fps`` frames per second: a looping GIF, or
    H.264 MP4 / VP9 WebM through ffmpeg (frame sizes rounded down to even for the codecs). MP4/WebM
    frames are streamed one at a time; a GIF keeps them until written. Returns the path."""
    out = check_video_path(path)
    if not (np.isfinite(fps) and fps > 0):
        raise InputError(f"frames per second must be positive, got {fps}")
    with atomic_path(out, overwrite=overwrite) as temp:
        if out.suffix.lower() == ".gif":
            _write_gif(frames, temp, out, fps)
        else:
            _write_ffmpeg(frames, temp, out, fps)
    return out
