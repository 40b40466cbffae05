"""The browser viewer: ``surfsplat export`` writes a static page that draws a model in WebGL2 with the
package's own shaders (``docs/guides/web.md``).

- :mod:`~surfsplat.web.format`: the web format (19 bytes a splat, 22 with 24-bit positions) and its
  decoding, in NumPy;
- :mod:`~surfsplat.web.shaders`: the ``rendering/glsl`` files composed for GLSL ES 3.00;
- :mod:`~surfsplat.web.framing`: the page's default view, as ``surfsplat render`` frames the model;
- :mod:`~surfsplat.web.page`: what a page draws (the view plan's splats, in the desktop's order, quantized);
- :mod:`~surfsplat.web.tree`: level of detail in the browser (a hierarchy the page cuts per view);
- :mod:`~surfsplat.web.export`: :func:`export`, the page and its scripts;
- :mod:`~surfsplat.web.widget`: :func:`widget`, the same viewer in a Jupyter cell (anywidget);
- :mod:`~surfsplat.web.browser`: a small headless-Chromium driver (DevTools protocol over a pipe) that
  the tests and the benchmark open pages with.
"""

from .export import ExportResult, export
from .widget import widget

__all__ = ["ExportResult", "export", "widget"]
