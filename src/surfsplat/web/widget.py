"""The browser viewer in Jupyter: an `anywidget <https://anywidget.dev>`_ widget (``pip install
"surfsplat[notebook]"``) that draws a model in the notebook's output with the exported page's own viewer
(``static/viewer.js``, its programs and its data, sent to the browser as the widget's state).

The widget's ``camera`` follows the view in the browser (eye, target, up, fov, world units, set after each
move) and moves it when set from Python.
"""

from __future__ import annotations

from functools import cache

from .. import defaults
from ..errors import InputError
from ..pipeline import CameraSpec, LodOptions, SourceOptions
from .export import _static, page_payload
from .shaders import shader_bundle

#: The widget's front end: the viewer, and anywidget's entry point calling it on the output element.
WIDGET_ENTRY = """
export default {
  render({ model, el }) {
    el.style.height = model.get('height') + 'px';
    el.style.width = '100%';
    var state = surfsplatViewer(el, model.get('shaders'), model.get('data'), {
      params: model.get('params') || {},
      onCamera: function (camera) { model.set('camera', camera); model.save_changes(); }
    });
    el.surfsplat = state;   // the viewer's state, as window.surfsplat on the exported page
    model.on('change:camera', function () {
      var c = model.get('camera');
      if (c && c.eye && state.setCamera && JSON.stringify(c) !== JSON.stringify(state.camera)) state.setCamera(c);
    });
  }
};
"""


def widget_esm() -> str:
    """The widget's JavaScript module: ``viewer.js`` and :data:`WIDGET_ENTRY`."""
    return _static("viewer.js") + WIDGET_ENTRY


@cache
def _widget_class():
    try:
        import anywidget
        import traitlets
    except ImportError:
        raise InputError('the notebook viewer needs anywidget: pip install "surfsplat[notebook]"') from None

    class SplatViewer(anywidget.AnyWidget):
        """The browser viewer in a notebook cell (:func:`widget`)."""

        _esm = widget_esm()
        data = traitlets.Dict().tag(sync=True)
        shaders = traitlets.Dict().tag(sync=True)
        params = traitlets.Dict().tag(sync=True)
        height = traitlets.Int(480).tag(sync=True)
        camera = traitlets.Dict().tag(sync=True)

    return SplatViewer


def widget(source, *, height: int = 480, technique: str = "ewa", background=defaults.BACKGROUND,
           source_options: SourceOptions | None = None, lod: LodOptions | None = None,
           camera: CameraSpec | None = None, point_budget: int | None = None, supersample: int = 1,
           position_bits: int = 16,
           ui: bool = True):
    """A Jupyter widget drawing ``source`` with the browser viewer (WebGL2, in the notebook's browser).

    Args:
        source, technique, background, source_options, lod, camera, point_budget: as
            :func:`surfsplat.export` takes them (the model is prepared and quantized the same way).
        supersample: K, the viewer's first supersampling (1 to 4, as :func:`surfsplat.export` takes it): every
            pass drawn on K x K sub-pixels a pixel and reduced, as ``surfsplat render --supersample K`` draws.
        position_bits: 16 or 24, the splat centres' precision (as :func:`surfsplat.export` takes it).
        height: the widget's height, CSS pixels (its width is the cell's).
        ui: show the controls and the HUD.

    Returns:
        an ``anywidget.AnyWidget`` whose ``camera`` trait (eye, target, up, fov) follows the view.
    """
    if not (isinstance(height, int) and 16 <= height <= defaults.MAX_WINDOW_SIDE):
        raise InputError(f"height must be whole CSS pixels in 16..{defaults.MAX_WINDOW_SIDE}, got {height!r}")
    header, streams = page_payload(source, technique=technique, background=background, source_options=source_options,
                                   lod=lod, camera=camera, point_budget=point_budget, supersample=supersample,
                                   position_bits=position_bits)
    return _widget_class()(data={"header": header, "streams": streams}, shaders=shader_bundle(), height=height,
                           params={} if ui else {"ui": "0"})
