"""Camera files: a :class:`~surfsplat.camera.Camera` as JSON, written by ``--save-camera`` and read by
``--camera`` (``render``, ``demo``, ``view``), so a view can be reused exactly.

Format (``"format": "surfsplat-camera"``, version 1): ``eye``, ``target``, ``up`` (3 numbers each,
world/model units), ``fov`` (vertical, degrees), ``width``, ``height`` (pixels) and optionally
``near``, ``far`` (model units along the view axis; absent or null: from the model's bounds).

A file may instead hold several cameras (key views of a camera path, ``turntable --path``; views for
``render --cameras``): ``"cameras"``, a list of objects with the fields above and an optional
``name``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from ..camera import Camera
from ..errors import InputError, file_reader
from .atomic import write_atomically

CAMERA_FORMAT = "surfsplat-camera"
CAMERA_FORMAT_VERSION = 1


def camera_to_dict(camera: Camera) -> dict:
    """The JSON-ready dict of a camera (see the module docstring)."""
    return {"format": CAMERA_FORMAT, "version": CAMERA_FORMAT_VERSION, "eye": list(camera.eye),
            "target": list(camera.target), "up": list(camera.up), "fov": float(camera.fov),
            "width": camera.width, "height": camera.height, "near": camera.near, "far": camera.far}


def _camera_fields(camera: Camera) -> dict:
    fields = camera_to_dict(camera)
    del fields["format"], fields["version"]
    return fields


def save_cameras(cameras, path: str | os.PathLike, *, overwrite: bool = True) -> Path:
    """Write several cameras (Cameras, or ``(name, Camera)`` pairs) as one camera file with a
    ``"cameras"`` list; an existing file is replaced unless ``overwrite=False``. Returns the path."""
    entries = []
    for i, item in enumerate(cameras):
        name, camera = item if isinstance(item, tuple) else (str(i), item)
        if not isinstance(camera, Camera):
            raise InputError(f"{path}: camera {i} is a {type(camera).__name__}, not a Camera")
        entries.append({"name": str(name), **_camera_fields(camera)})
    if not entries:
        raise InputError(f"{path}: no cameras to write")
    text = json.dumps({"format": CAMERA_FORMAT, "version": CAMERA_FORMAT_VERSION, "cameras": entries}, indent=2)
    write_atomically(Path(path), (text + "\n").encode("utf-8"), overwrite=overwrite)
    return Path(path)


def save_camera(camera: Camera, path: str | os.PathLike, *, overwrite: bool = True) -> Path:
    """Write ``camera`` as JSON to ``path``; an existing file is replaced unless ``overwrite=False``.
    Returns the path."""
    path = Path(path)
    text = json.dumps(camera_to_dict(camera), indent=2) + "\n"
    write_atomically(path, text.encode("utf-8"), overwrite=overwrite)
    return path


def _read(path: Path) -> dict:
    """The parsed JSON of a surfsplat camera file, its format and version checked."""
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
    return data


@file_reader
def load_camera(path: str | os.PathLike) -> Camera:
    """Read a camera file of one camera (InputError naming the file and the problem when it is not one)."""
    path = Path(path)
    data = _read(path)
    if "cameras" in data:
        raise InputError(f"{path}: holds a list of cameras; give it to render --cameras or turntable --path")
    return _camera_from(data, path)


@file_reader
def load_camera_list(path: str | os.PathLike) -> list[tuple[str, Camera]]:
    """The ``(name, Camera)`` pairs of a camera file: its ``"cameras"`` list (names: the ``name``
    field, else the index), or its one camera named by the file's stem."""
    path = Path(path)
    data = _read(path)
    if "cameras" not in data:
        return [(path.stem, _camera_from(data, path))]
    entries = data["cameras"]
    if not isinstance(entries, list) or not entries:
        raise InputError(f"{path}: \"cameras\" must be a non-empty list")
    views = []
    for i, entry in enumerate(entries):
        if not isinstance(entry, dict):
            raise InputError(f"{path}: camera {i} is not an object", element="cameras", row=i)
        views.append((str(entry.get("name", i)), _camera_from(entry, path, f" (camera {i})", i)))
    return views


def _camera_from(data: dict, path: Path, where: str = "", row: int | None = None) -> Camera:
    """The Camera of one entry; an InputError names the file, the field (``element``) and, in a
    list, the entry (``row``)."""
    try:
        return Camera(eye=tuple(data["eye"]), target=tuple(data["target"]), up=tuple(data["up"]),
                      fov=float(data["fov"]), width=int(data["width"]), height=int(data["height"]),
                      near=data.get("near"), far=data.get("far"))
    except KeyError as exc:
        raise InputError(f"{path}: camera file lacks {exc.args[0]!r}{where}", element=exc.args[0], row=row) from None
    except InputError as exc:   # the Camera's check names the field
        raise InputError(f"{path}: bad camera{where}: {exc}", element=exc.argument, row=row) from None
    except (TypeError, ValueError) as exc:
        raise InputError(f"{path}: bad camera{where}: {exc}", row=row) from None
