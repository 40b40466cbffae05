"""The interactive viewer (``surfsplat view``): a glfw window drawing with the same Renderer.

``surfsplat.viewer.view("bunny.ply")`` opens a window; see :func:`view` for the
options and the scripted mode (``frames``, ``orbit``, ``screenshot``) used by
tests and by people without a mouse. Needs the optional ``glfw`` package
(``pip install 'surfsplat[viewer]'``) and a display.
"""

from .app import MOTION_MODES, LevelOfDetail, MotionOptions, ViewStats, view

__all__ = ["MOTION_MODES", "LevelOfDetail", "MotionOptions", "ViewStats", "view"]
