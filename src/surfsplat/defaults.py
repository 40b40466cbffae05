"""Every default of a view, in one place: the Python API, the command line, the viewer and the
notebook widget read them from here. Where two doors differ, the reason is written beside the
values (``docs/architecture.md``, "Where each decision is made")."""

from __future__ import annotations

#: Image size (pixels) of :func:`surfsplat.render` without a camera. The Python call returns arrays
#: that are often made in loops (notebooks, training views, tests), so it is kept small ...
API_IMAGE_SIZE = 512
#: ... while ``surfsplat render`` and ``demo`` write one picture to look at (pixels).
CLI_IMAGE_SIZE = 1024
#: Window size of ``surfsplat view`` (screen coordinates; the framebuffer is larger on HiDPI screens).
WINDOW_SIZE = (1280, 720)
#: Image size of the notebook widget: every slider move renders a frame, small keeps it interactive.
NOTEBOOK_SIZE = (384, 288)

#: Largest image side (pixels): any size is drawn in tiles; the frame's arrays take about 24 bytes a
#: pixel in memory (a 32768 x 32768 frame: 26 GB).
MAX_IMAGE_SIDE = 32768
#: Largest window side (screen coordinates): the largest framebuffer common drivers allocate.
MAX_WINDOW_SIDE = 16384
#: Largest supersampling factor K (K x K samples a pixel) of splats and of the mesh ground truth.
MAX_SUPERSAMPLE = 16

#: Background colour (RGB in [0, 1]).
BACKGROUND = (1.0, 1.0, 1.0)
#: Vertical field of view of automatic cameras, degrees.
FOV = 40.0
#: Neighbours used to preprocess raw points.
K = 8

#: LOD screen tolerance (pixels) of a hierarchy rendered without one, and of the viewer.
LOD_TOLERANCE = 1.0
#: Normal field of coarse LOD splats (:func:`surfsplat.hierarchy.select`).
LOD_SHADING = "fit"
#: Where a hierarchy's cut is chosen by default: "auto" (:func:`surfsplat.pipeline.lod.lod_strategy`):
#: on the GPU for the views of an interactive door (the viewer: uploaded once, every frame cut by the
#: vertex shader), on the CPU for one picture (uploading the whole layout for one frame costs more
#: than gathering its cut).
LOD_MODE = "auto"
