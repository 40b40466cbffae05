"""``view --record FILE``: the frames the window shows, written as a GIF or an MP4/WebM video.

Frames go to :func:`surfsplat.io.video.write_video` running in a background thread, through a
bounded queue: MP4/WebM are encoded while the viewer runs (memory stays flat), a GIF is
assembled at the end. The window shows frames at an irregular rate (it waits for input while
nothing changes), so the video is on a fixed clock: each shown frame is repeated for the
:data:`RECORD_FPS` ticks that pass until the next one (a still view plays as long as it was
shown); the scripted mode (``--frames``) records one video frame per frame instead.
"""

from __future__ import annotations

import queue
import threading
import time
from pathlib import Path
from typing import Callable

import numpy as np

from ..io.video import check_video_path, write_video

#: Frames per second of a recording.
RECORD_FPS = 24.0
#: Frames waiting for the encoder at most (the viewer waits when it falls behind).
QUEUE_FRAMES = 8

_END = None


class Recorder:
    """Feeds shown frames to :func:`~surfsplat.io.video.write_video` in a background thread."""

    def __init__(self, path, fps: float = RECORD_FPS, *, realtime: bool = True, overwrite: bool = True):
        self.path = check_video_path(path)
        self.fps, self.realtime = float(fps), realtime
        self.frames = 0
        self._queue: queue.Queue = queue.Queue(maxsize=QUEUE_FRAMES)
        self._start: float | None = None
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._write, args=(overwrite,), daemon=True)
        self._thread.start()

    def _frames(self):
        while (frame := self._queue.get()) is not _END:
            yield frame

    def _write(self, overwrite: bool) -> None:
        try:
            write_video(self._frames(), self.path, fps=self.fps, overwrite=overwrite)
        except BaseException as exc:   # reported by close(), in the viewer's thread
            self._error = exc
            while self._queue.get() is not _END:   # drain: the viewer must not block on a dead writer
                pass

    def add(self, grab: Callable[[], np.ndarray]) -> None:
        """Record the frame ``grab()`` returns ((H, W, 3) uint8), repeated to the clock when ``realtime``."""
        now = time.perf_counter()
        if self._start is None:
            self._start = now
        due = int((now - self._start) * self.fps) + 1 if self.realtime else self.frames + 1
        if due <= self.frames:
            return
        frame = grab()
        for _ in range(due - self.frames):
            self._queue.put(frame)
        self.frames = due

    def close(self) -> Path | None:
        """Finish the file; returns its path (None when no frame was recorded). Raises the writer's error."""
        self._queue.put(_END)
        self._thread.join()
        if self._error is not None and self.frames:
            raise self._error
        return self.path if self.frames else None
