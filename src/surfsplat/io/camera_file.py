"""Camera files: a :class:`~surfsplat.camera.Camera` as JSON, written by ``--save-camera`` and read by
``--camera`` (``render``, ``demo``, ``view``), so a view can be reused exactly.

Format (``"format": "surfsplat-camera"``, version 1): ``eye``, ``target``, ``up`` (3 numbers each,
world/model units), ``fov`` (vertical, degrees), ``width``, ``height`` (pixels) and optionally
``near``, ``far`` (model units along the view axis; absent or null: from the model's bounds).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from ..camera import Camera
from ..errors import InputError
from .atomic import write_atomically

CAMERA_FORMAT = "surfsplat-camera"
CAMERA_FORMAT_VERSION = 1


def camera_to_dict(camera: Camera) -> dict:
    """The JSON-ready dict of a camera (see the module docstring)."""
    return {"format": CAMERA_FORMAT, "version": CAMERA_FORMAT_VERSION, "eye": list(camera.eye),
            "target": list(camera.target), "up": list(camera.up), "fov": float(camera.fov),
            "width": camera.width, "height": camera.height, "near": camera.near, "far": camera.far}


def save_camera(camera: Camera, path: str | os.PathLike, *, overwrite: bool = False) -> Path:
    """Write ``camera`` as JSON to ``path``; an existing file only with ``overwrite``. Returns the path."""
    path = Path(path)
    text = json.dumps(camera_to_dict(camera), indent=2) + "\n"
    write_atomically(path, text.encode("utf-8"), overwrite=overwrite)
    return path


def load_camera(path: str | os.PathLike) -> Camera:
    """Read a camera file (InputError naming the file and the problem when it is not one)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{path}: no such camera file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{path}: not a camera file (JSON): {exc}") from None
    if not isinstance(data, dict) or data.get("format") != CAMERA_FORMAT:
        raise InputError(f"{path}: not a surfsplat camera file (no \"format\": \"{CAMERA_FORMAT}\")")
    if data.get("version") != CAMERA_FORMAT_VERSION:
        raise InputError(f"{path}: camera file version {data.get('version')!r}; this surfsplat reads version "
                         f"{CAMERA_FORMAT_VERSION}")
    try:
        return Camera(eye=tuple(data["eye"]), target=tuple(data["target"]), up=tuple(data["up"]),
                      fov=float(data["fov"]), width=int(data["width"]), height=int(data["height"]),
                      near=data.get("near"), far=data.get("far"))
    except KeyError as exc:
        raise InputError(f"{path}: camera file lacks {exc.args[0]!r}") from None
    except (TypeError, ValueError) as exc:
        raise InputError(f"{path}: bad camera: {exc}") from None
