"""Jupyter: an interactive orbit view rendered headless (ipywidgets, optional: the ``notebook`` extra).

``Orbit(source)`` prepares a view once (:class:`surfsplat.pipeline.View`: a file, ``demo:NAME``, a
SplatCloud, a hierarchy, any object :func:`surfsplat.render` takes), frames it like ``surfsplat render``
does, and shows an ``ipywidgets.Image`` with sliders for azimuth, elevation and zoom and a technique dropdown. Every
change renders one frame with the same renderer as :func:`surfsplat.render` (EGL, no display
needed) and streams its PNG into the image. The widget logic runs without a browser: set
``orbit.azimuth.value = 90`` and ``orbit.image.value`` holds the new view.

A single frame needs no widget: :class:`~surfsplat.rendering.frame.Frame` displays inline by itself
(``_repr_png_``).
"""

from __future__ import annotations

import io
from dataclasses import replace
from typing import get_args

import numpy as np
from PIL import Image

from . import defaults
from .pipeline import LodOptions, RenderResult, SourceOptions, View
from .camera import Camera, rotate
from .errors import InputError, SurfsplatError
from .lighting import Lights
from .rendering.options import RenderOptions, TechniqueName

#: Techniques the dropdown offers, in the order of :data:`surfsplat.rendering.options.TechniqueName`.
TECHNIQUE_CHOICES: tuple[str, ...] = get_args(TechniqueName)
#: Zoom range of the slider (a factor on the eye's distance to the target: 2 halves it).
ZOOM_RANGE = (0.25, 8.0)


def orbit_camera(base: Camera, azimuth: float, elevation: float, zoom: float = 1.0) -> Camera:
    """``base`` turned ``azimuth`` degrees about its up axis through its target (right-handed, as
    :func:`surfsplat.api.orbit_cameras`), the eye raised to ``elevation`` degrees above the plane
    normal to up, and its distance to the target divided by ``zoom``. Near and far are reset
    (set from the model's bounds when rendering)."""
    if not (np.isfinite(azimuth) and -89.0 <= elevation <= 89.0 and np.isfinite(zoom) and zoom > 0):
        raise InputError(f"orbit needs a finite azimuth, elevation within -89..89 degrees and zoom > 0, got "
                         f"azimuth {azimuth}, elevation {elevation}, zoom {zoom}")
    up = np.asarray(base.up, dtype=np.float64)
    up = up / np.linalg.norm(up)
    target = np.asarray(base.target, dtype=np.float64)
    offset = np.asarray(base.eye, dtype=np.float64) - target
    flat = offset - (offset @ up) * up
    if np.linalg.norm(flat) < 1e-9 * np.linalg.norm(offset):   # looking along up: any horizontal direction
        flat = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
    flat = rotate(flat / np.linalg.norm(flat), up, azimuth)
    angle = np.radians(elevation)
    eye = target + np.linalg.norm(offset) / zoom * (np.cos(angle) * flat + np.sin(angle) * up)
    return replace(base, eye=tuple(eye), near=None, far=None)


def elevation_of(camera: Camera) -> float:
    """Degrees of the eye above the plane through the target normal to ``camera.up``."""
    up = np.asarray(camera.up, dtype=np.float64)
    offset = np.asarray(camera.eye, dtype=np.float64) - np.asarray(camera.target, dtype=np.float64)
    return float(np.degrees(np.arcsin(np.clip(offset @ up / (np.linalg.norm(up) * np.linalg.norm(offset)),
                                              -1.0, 1.0))))


class Orbit:
    """An interactive orbit view of a model for Jupyter; display it as the last expression of a cell.

    Args:
        source: what :func:`surfsplat.render` takes (path, ``"demo:NAME"``, SplatCloud, hierarchy,
            mesh, array or other object); loaded once (a mesh's surface sampled once, for the first view).
        camera: the starting view (a Camera or CameraSpec; None: automatic framing). Azimuth 0 and
            zoom 1 are this view; the elevation slider starts at its elevation.
        technique: the starting technique (the dropdown offers :data:`TECHNIQUE_CHOICES`).
        width, height: image size in pixels (small sizes keep it interactive on a CPU renderer).
        lights, background, options, lod, source_options: as for :func:`surfsplat.render` (the widget
            draws what :func:`surfsplat.render` draws for each camera: a single picture's LOD rule).
        continuous_update: render while a slider is dragged (True) or when it is released (False).

    Attributes:
        azimuth, elevation, zoom: the sliders (degrees, degrees, distance factor);
        technique: the dropdown; image: the ``ipywidgets.Image`` (PNG bytes in ``image.value``);
        status: a label with what the last frame drew and its time, or the error;
        widget: the whole ``VBox``; result: the last :class:`~surfsplat.api.RenderResult`.

    Raises:
        InputError: ipywidgets is missing (the ``notebook`` extra), or a bad source or argument.
    """

    def __init__(self, source, camera=None, *, technique: TechniqueName = "ewa",
                 width: int = defaults.NOTEBOOK_SIZE[0], height: int = defaults.NOTEBOOK_SIZE[1],
                 lights: Lights | None = None, background=defaults.BACKGROUND, options: RenderOptions | None = None,
                 lod: LodOptions | None = None, source_options: SourceOptions | None = None,
                 continuous_update: bool = False) -> None:
        try:
            import ipywidgets as widgets
        except ImportError as exc:
            raise InputError("the notebook widget needs ipywidgets: `pip install ipywidgets` (or "
                             "`pip install \".[notebook]\"` in the surfsplat checkout)") from exc
        if technique not in TECHNIQUE_CHOICES:
            raise InputError(f"unknown technique {technique!r}; choose one of {', '.join(TECHNIQUE_CHOICES)}")
        self.view = View(source, source_options=source_options, lod=lod)
        self.base = self.view.camera(camera, width, height)
        self.view.sample(self.base)   # a mesh's surface sampled once, for the starting view
        self._render_args = dict(lights=lights, background=background, options=options)
        self.result: RenderResult | None = None
        sliders = dict(continuous_update=continuous_update, style={"description_width": "initial"})
        self.azimuth = widgets.FloatSlider(value=0.0, min=-180.0, max=180.0, step=5.0, description="azimuth",
                                           **sliders)
        self.elevation = widgets.FloatSlider(value=round(elevation_of(self.base), 1), min=-89.0, max=89.0,
                                             step=1.0, description="elevation", **sliders)
        self.zoom = widgets.FloatLogSlider(value=1.0, base=2.0, min=np.log2(ZOOM_RANGE[0]),
                                           max=np.log2(ZOOM_RANGE[1]), step=0.05, description="zoom", **sliders)
        self.technique = widgets.Dropdown(options=list(TECHNIQUE_CHOICES), value=technique,
                                          description="technique")
        self.image = widgets.Image(format="png", width=width, height=height)
        self.status = widgets.Label()
        self.widget = widgets.VBox([self.image, widgets.HBox([self.azimuth, self.elevation]),
                                    widgets.HBox([self.zoom, self.technique]), self.status])
        for control in (self.azimuth, self.elevation, self.zoom, self.technique):
            control.observe(self._changed, names="value")
        self.update()

    def camera(self) -> Camera:
        """The camera the controls describe now (:func:`orbit_camera` of the starting view)."""
        return orbit_camera(self.base, self.azimuth.value, self.elevation.value, self.zoom.value)

    def update(self) -> RenderResult | None:
        """Render the current view into ``image`` and ``result``; a SurfsplatError is shown in
        ``status`` (a callback's exception would be lost in the kernel's log) and returns None."""
        try:
            self.result = self.view.render(self.camera(), technique=self.technique.value, **self._render_args)
        except SurfsplatError as exc:
            self.status.value = f"error: {exc}"
            return None
        buffer = io.BytesIO()
        Image.fromarray(self.result.frame.image()).save(buffer, format="PNG")
        self.image.value = buffer.getvalue()
        self.status.value = (f"{self.technique.value}: {self.result.describe()} in "
                             f"{1000 * self.result.seconds:.0f} ms")
        return self.result

    def _changed(self, change) -> None:
        self.update()

    def _repr_mimebundle_(self, **kwargs):
        return self.widget._repr_mimebundle_(**kwargs)


def orbit(source, camera=None, **kwargs) -> Orbit:
    """An :class:`Orbit` view of ``source`` (same arguments); the last expression of a cell displays it."""
    return Orbit(source, camera, **kwargs)
