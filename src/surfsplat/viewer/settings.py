"""The viewer's settings and counters: timing constants, :class:`MotionOptions`, :class:`ViewStats`."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, get_args

from ..errors import InputError
from ..rendering.techniques import TECHNIQUES

#: Seconds the camera must be still before the full-quality frame replaces the preview.
SETTLE_S = 0.25
#: Seconds of the cross-fade from the preview to the full-quality frame.
FADE_S = 0.15
#: Default (about) number of splats and resolution scale of the motion preview: with ``flat``
#: at 1280x720 (drawn at 640x360) about 5-10 frames/s on llvmpipe with 2 cores. Only used
#: where full quality is slow (motion "auto"), so a GPU usually never shows the preview.
#: LOD screen tolerance range, pixels, and the factor of one +/- step.
TOLERANCE_RANGE = (0.125, 64.0)
TOLERANCE_STEP = math.sqrt(2.0)
#: Seconds between refreshes of the frame counter (and so of the HUD's text).
FPS_INTERVAL_S = 0.5

Motion = Literal["auto", "flat", "same", "off"]
#: The values of :data:`Motion`.
MOTION_MODES = get_args(Motion)
#: With motion "auto", the preview is used only where a full-quality frame takes longer than this
#: (seconds): on a GPU the full quality usually keeps up and is drawn while moving too.
PREVIEW_ABOVE_S = 0.05

@dataclass(frozen=True)
class MotionOptions:
    """What the viewer draws while the camera moves.

    Attributes:
        mode: "flat" (opaque one-pass disks) or "same" (the chosen technique), both on about
            ``budget`` splats at ``scale`` of the resolution; "off": full quality always;
            "auto": "flat" where a full-quality frame takes longer than ``PREVIEW_ABOVE_S``.
        budget: about this many splats at most in the preview (0: all). The default, with
            ``flat`` at 1280x720 drawn at 640x360, gives about 5-10 frames/s on llvmpipe with 2
            cores; only used where full quality is slow, so a GPU usually never shows it.
        scale: internal resolution of the preview, fraction of the window's, in (0, 1].
        fps: frames per second the preview keeps while moving: it is drawn from a ladder of
            level-uniform cuts (the finest of at most ``budget`` splats, each coarser one about
            a quarter of the next) and steps to a coarser one when a frame is too slow, to a finer
            one when there is time (:func:`~surfsplat.viewer.detail.next_preview_level`); 0: always
            the finest.
    """

    mode: Motion = "auto"
    budget: int = 100_000
    scale: float = 0.5
    fps: float = 25.0

    def __post_init__(self) -> None:
        if self.mode not in MOTION_MODES:
            raise InputError(f"motion must be one of {', '.join(map(repr, MOTION_MODES))}, got {self.mode!r}")
        if not (_is_real(self.scale) and 0.0 < self.scale <= 1.0):
            raise InputError(f"motion scale must be in (0, 1], got {self.scale!r}")
        if not (_is_real(self.budget) and int(self.budget) == self.budget and self.budget >= 0):
            raise InputError(f"motion budget must be a whole number >= 0 splats (0: all), got {self.budget!r}")
        if not (_is_real(self.fps) and 0.0 <= self.fps <= 1000.0):
            raise InputError(f"motion fps must be in [0, 1000] frames per second (0: no adapting), got {self.fps!r}")


def _is_real(value) -> bool:
    """Whether ``value`` is a finite real number (bool excluded)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool) and math.isfinite(value)


@dataclass
class ViewStats:
    """What a :func:`view` session did.

    Attributes:
        frames: frames presented (scripted mode: the N asked for, unless the window was closed).
        seconds: wall-clock time of those frames (rendering, presenting, HUD, swap), seconds.
        fps: frames / seconds.
        preview_frames, full_frames: how many renders were motion previews / full quality.
        splats: splats in the model; preview_splats: splats drawn in a preview.
        size: (width, height) of the framebuffer, pixels.
        screenshot: the image written by the scripted mode, if any.
    """

    frames: int
    seconds: float
    fps: float
    preview_frames: int
    full_frames: int
    splats: int
    preview_splats: int
    size: tuple[int, int]
    screenshot: Path | None = None


def technique_names() -> list[str]:
    """The techniques in the order T cycles through them and 1..9 select them."""
    return sorted(TECHNIQUES)
