"""The table of rendering techniques, by name: the one place that lists them.

Each technique module defines its :class:`~surfsplat.rendering.technique.Technique`
constant and nothing registers itself; a new technique is added here (and to
``options.TechniqueName``).
"""

from __future__ import annotations

from ..errors import InputError
from .blend import BLEND
from .ewa import EWA
from .flat import FLAT
from .perspective import PERSPECTIVE
from .phong import PHONG
from .points import POINTS
from .technique import Technique

#: Technique name -> Technique; the keys are exactly ``options.TechniqueName``.
TECHNIQUES: dict[str, Technique] = {
    "ewa": EWA,
    "perspective": PERSPECTIVE,
    "phong": PHONG,
    "blend": BLEND,
    "flat": FLAT,
    "points": POINTS,
}


def get_technique(name: str) -> Technique:
    """The technique called ``name``; InputError listing the known ones otherwise."""
    try:
        return TECHNIQUES[name]
    except (KeyError, TypeError):
        raise InputError(f"unknown technique {name!r}; choose one of {', '.join(sorted(TECHNIQUES))}") from None
