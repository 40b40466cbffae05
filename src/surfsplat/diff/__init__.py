"""Differentiable EWA surface splatting in PyTorch (the optional extra ``diff``: ``pip install surfsplat[diff]``).

:func:`render` draws :class:`Splats` seen by a :class:`DiffCamera` as the OpenGL ``ewa`` technique
does, differentiably with respect to the splats (positions, tangent axes, colours, opacity, normals)
and the camera (pose, focal length); :func:`fit` fits splats to photographs with known cameras.
"""

from .render import DiffFrame, DiffOptions, render, render_frame
from .scene import DiffCamera, Splats, rotation_from_vector, tangent_axes

__all__ = ["DiffCamera", "DiffFrame", "DiffOptions", "Splats", "render", "render_frame", "rotation_from_vector",
           "tangent_axes"]
