"""Camera motion for the viewer: orbit, pan, zoom (dolly) and fly, as pure functions on :class:`Camera`.

Nothing here needs a window or OpenGL, so the math is unit-tested on its own.
Every function returns a new camera (Camera is frozen) with ``near``/``far``
reset to None: the renderer sets them from the model's bounds for each view,
exactly as :func:`surfsplat.auto_camera` does for the first one.

Conventions: angles in degrees; pan offsets in framebuffer pixels, x right and
y *down* (window coordinates, as mouse events report them); distances in model
units. "up" is the world up axis the viewer keeps (``--up``, default +y): orbits
turn about it and the camera never rolls.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Callable, Literal

import numpy as np

from ..camera import rotate

from ..camera import Camera

#: Orbit and look never get closer than this to the up axis (degrees of elevation), so the
#: look-at basis stays well defined (the view direction must not be parallel to up).
MAX_ELEVATION_DEG = 89.0


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _split(direction: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, float]:
    """A unit direction as (unit horizontal part, elevation in degrees) relative to ``up``."""
    d = _unit(direction)
    sin_e = float(np.clip(d @ up, -1.0, 1.0))
    horizontal = d - sin_e * up
    norm = np.linalg.norm(horizontal)
    if norm < 1e-9:  # exactly along up: any horizontal direction will do
        helper = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
        horizontal = helper - (helper @ up) * up
        norm = np.linalg.norm(horizontal)
    return horizontal / norm, float(np.degrees(np.arcsin(sin_e)))


def _join(horizontal: np.ndarray, elevation_deg: float, up: np.ndarray) -> np.ndarray:
    e = np.radians(elevation_deg)
    return np.cos(e) * horizontal + np.sin(e) * up


def _world_up(camera: Camera, up) -> np.ndarray:
    return _unit(np.asarray(camera.up if up is None else up, dtype=np.float64))


def _moved(camera: Camera, eye: np.ndarray, target: np.ndarray, up: np.ndarray) -> Camera:
    return replace(camera, eye=tuple(eye), target=tuple(target), up=tuple(up), near=None, far=None)


def distance(camera: Camera) -> float:
    """Distance from the eye to the target, model units."""
    return float(np.linalg.norm(np.subtract(camera.eye, camera.target)))


def _turned(offset: np.ndarray, up: np.ndarray, yaw_deg: float, pitch_deg: float,
            max_elevation_deg: float) -> np.ndarray:
    """``offset`` turned by ``yaw_deg`` about ``up`` and raised by ``pitch_deg`` (elevation clamped)."""
    horizontal, elevation = _split(offset, up)
    horizontal = rotate(horizontal, up, yaw_deg)
    elevation = float(np.clip(elevation + pitch_deg, -max_elevation_deg, max_elevation_deg))
    return np.linalg.norm(offset) * _join(horizontal, elevation, up)


def orbit(camera: Camera, yaw_deg: float, pitch_deg: float = 0.0, up=None,
          max_elevation_deg: float = MAX_ELEVATION_DEG) -> Camera:
    """Turn the eye around the target, keeping its distance.

    ``yaw_deg``: rotation of the eye about the ``up`` axis through the target
    (right-handed: positive is counter-clockwise seen from above).
    ``pitch_deg``: added to the eye's elevation above the target's horizontal
    plane, clamped to +-``max_elevation_deg`` so the camera never flips over the pole.
    ``up`` defaults to the camera's up vector.
    """
    up = _world_up(camera, up)
    target = np.asarray(camera.target)
    eye = target + _turned(np.asarray(camera.eye) - target, up, yaw_deg, pitch_deg, max_elevation_deg)
    return _moved(camera, eye, target, up)


def pixel_size(camera: Camera) -> float:
    """Size of one pixel at the target's depth, model units (what a pan of one pixel moves)."""
    return distance(camera) * 2.0 * np.tan(np.radians(camera.fov) / 2.0) / camera.height


def pan(camera: Camera, dx_px: float, dy_px: float) -> Camera:
    """Slide eye and target together so the scene follows the cursor ("grab").

    ``dx_px``, ``dy_px``: cursor motion in framebuffer pixels, y down. Points at
    the target's depth move by exactly that many pixels on screen.
    """
    view = camera.view_matrix
    right, cam_up = view[0, :3], view[1, :3]
    shift = pixel_size(camera) * (-dx_px * right + dy_px * cam_up)
    return _moved(camera, np.asarray(camera.eye) + shift, np.asarray(camera.target) + shift,
                  np.asarray(camera.up))


def zoom(camera: Camera, steps: float, factor: float = 0.85, min_distance: float = 1e-6) -> Camera:
    """Dolly toward the target: the distance is multiplied by ``factor ** steps``.

    Positive ``steps`` (wheel forward) move closer; the distance stays at least
    ``min_distance`` (model units), so the eye never reaches the target.
    """
    target = np.asarray(camera.target)
    offset = np.asarray(camera.eye) - target
    d = max(float(np.linalg.norm(offset)) * factor ** steps, min_distance)
    return _moved(camera, target + _unit(offset) * d, target, np.asarray(camera.up))


def fly(camera: Camera, forward: float = 0.0, right: float = 0.0, upward: float = 0.0, up=None) -> Camera:
    """Move eye and target together: ``forward`` along the view direction, ``right``
    along the camera's right axis, ``upward`` along the world ``up`` axis (model units)."""
    up = _world_up(camera, up)
    view = camera.view_matrix
    shift = forward * -view[2, :3] + right * view[0, :3] + upward * up
    return _moved(camera, np.asarray(camera.eye) + shift, np.asarray(camera.target) + shift, up)


def look(camera: Camera, yaw_deg: float, pitch_deg: float = 0.0, up=None,
         max_elevation_deg: float = MAX_ELEVATION_DEG) -> Camera:
    """Turn the view direction about the eye (the target swings around the eye).

    ``yaw_deg`` positive looks left (counter-clockwise about ``up``), ``pitch_deg``
    positive looks up; the elevation is clamped like :func:`orbit`'s.
    """
    up = _world_up(camera, up)
    eye = np.asarray(camera.eye)
    target = eye + _turned(np.asarray(camera.target) - eye, up, yaw_deg, pitch_deg, max_elevation_deg)
    return _moved(camera, eye, target, up)


Mode = Literal["orbit", "fly"]


@dataclass
class CameraController:
    """Mouse and keyboard input -> camera, for one window (no GL, no glfw here).

    Attributes:
        camera: the current camera (its width/height are the framebuffer's).
        home: ``(width, height) -> Camera``, the automatic framing that ``reset`` returns to.
        scale: size of the scene (its bounding sphere's radius, model units); sets fly speed
            and the closest zoom.
        mode: "orbit" (mouse turns around the target) or "fly" (keyboard moves the eye).
        orbit_speed: degrees of orbit per pixel of mouse drag.
        fly_speed: model units per second in fly mode, in units of ``scale``.
        look_speed: degrees per second for the arrow keys.
    """

    camera: Camera
    home: Callable[[int, int], Camera]
    scale: float = 1.0
    mode: Mode = "orbit"
    orbit_speed: float = 0.3
    fly_speed: float = 0.5
    look_speed: float = 60.0
    up: np.ndarray = field(default=None)  # type: ignore[arg-type]  # None given: set in __post_init__

    def __post_init__(self) -> None:
        self.up = _world_up(self.camera, self.up)

    def reset(self) -> None:
        """Back to the automatic framing at the current size."""
        self.camera = self.home(self.camera.width, self.camera.height)

    def resize(self, width: int, height: int) -> None:
        """New framebuffer size in pixels (the view stays, the aspect ratio follows)."""
        self.camera = self.camera.resized(max(int(width), 1), max(int(height), 1))

    def toggle_mode(self) -> Mode:
        """Switch between orbit and fly mode; returns the new mode."""
        self.mode = "fly" if self.mode == "orbit" else "orbit"
        return self.mode

    def drag(self, button: Literal["left", "right", "middle"], dx_px: float, dy_px: float) -> None:
        """A mouse drag of (dx, dy) framebuffer pixels (y down).

        Left: orbit around the target ("grab": dragging right turns the model right,
        dragging down tilts its top toward the viewer); in fly mode left looks around.
        Right or middle: pan.
        """
        if button == "left":
            if self.mode == "orbit":
                self.camera = orbit(self.camera, -dx_px * self.orbit_speed, dy_px * self.orbit_speed, self.up)
            else:
                self.camera = look(self.camera, -dx_px * self.orbit_speed, -dy_px * self.orbit_speed, self.up)
        else:
            self.camera = pan(self.camera, dx_px, dy_px)

    def scroll(self, steps: float) -> None:
        """Mouse wheel: dolly toward the target (orbit) or move forward (fly); positive is forward."""
        if self.mode == "orbit":
            self.camera = zoom(self.camera, steps, min_distance=1e-4 * self.scale)
        else:
            self.camera = fly(self.camera, forward=0.1 * self.scale * steps, up=self.up)

    def keys(self, move: tuple[float, float, float], turn: tuple[float, float], dt: float,
             fast: bool = False) -> bool:
        """Keys held for ``dt`` seconds; returns whether the camera moved.

        ``move`` = (forward, right, up) moves the eye in fly mode (ignored in orbit mode);
        ``turn`` = (left, up) looks left/up in fly mode and moves the eye left/up around
        the target in orbit mode. Components are -1, 0 or 1; ``fast`` is 4x the speed.
        """
        if self.mode == "orbit":
            move = (0.0, 0.0, 0.0)
        if not any(move) and not any(turn):
            return False
        boost = 4.0 if fast else 1.0
        angle = self.look_speed * dt * boost
        camera = self.camera
        if any(turn):
            if self.mode == "fly":
                camera = look(camera, turn[0] * angle, turn[1] * angle, self.up)
            else:
                camera = orbit(camera, -turn[0] * angle, turn[1] * angle, self.up)
        if any(move):
            step = self.fly_speed * self.scale * dt * boost
            camera = fly(camera, move[0] * step, move[1] * step, move[2] * step, self.up)
        self.camera = camera
        return True
