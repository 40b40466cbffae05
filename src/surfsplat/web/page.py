"""What an exported page draws: the splats the view plan gives for the page (:func:`exported_splats`), in
the desktop renderer's order (:func:`web_order`), quantized, with everything the viewer needs to draw them
as ``surfsplat render`` does (:func:`page_data`: the default view's fit, near/far, uniforms, material)."""

from __future__ import annotations

import base64

import numpy as np

from .. import defaults, progress
from ..camera import Camera
from ..cloud import SplatCloud
from ..errors import InputError
from ..geometry.preprocess import NONPLANAR
from ..hierarchy import Hierarchy, Selection
from ..lighting import Lights
from ..pipeline import View, hybrid_applies
from ..pipeline.framing import auto_fit_inputs
from ..pipeline.models import as_model
from ..rendering.edl import neighbour_offsets
from ..rendering.gpu_splats import radius_classes
from ..rendering.options import EdlOptions, RenderOptions
from ..rendering.passes import fill_depth, fill_gap
from ..rendering.techniques import get_technique
from ..version import __version__
from . import format as web_format
from .colors import attribute_streams, cut_attributes
from .framing import fit_frame
from .shaders import MAX_PAGE_SUPERSAMPLE, WEB_TECHNIQUES, fill_program

#: A hierarchy is cut to at most this many splats at the default camera unless a budget is given.
DEFAULT_POINT_BUDGET = 5_000_000


def _b64(array: np.ndarray) -> str:
    """The bytes of an array as base64 text."""
    return base64.b64encode(np.ascontiguousarray(array).tobytes()).decode("ascii")


def exported_splats(plan: View, camera: Camera, point_budget: int | None) -> SplatCloud:
    """The splats a page draws: the view plan's model as splats for ``camera`` (a mesh sampled for it);
    a hierarchy's cut at ``camera`` within ``point_budget`` (default :data:`DEFAULT_POINT_BUDGET`; its
    finest level where that holds it all), and so a cloud's beyond the budget (its hierarchy built)."""
    drawn = plan.sample(camera)
    budget = point_budget or DEFAULT_POINT_BUDGET
    if not drawn.is_tree:
        points = drawn.points()
        if len(points) <= budget:
            return points
        progress.message(f"{len(points):,} splats are more than the point budget of {budget:,}: exporting the "
                         f"cut of their hierarchy at the default view")
    tree = plan.tree(camera)
    cloud, selection = tree.cut(camera, 0.0, shading=plan.lod.shading, point_budget=budget)
    if isinstance(tree.data, Hierarchy) and isinstance(selection, Selection) and cloud.attributes is None:
        # the cut's splats with their attributes, for colour by attribute on the page
        cloud = cloud.replace(attributes=cut_attributes(tree.data, selection.node_indices(),
                                                        selection.point_indices()))
    return cloud


def web_order(cloud: SplatCloud) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The order a page stores splats in, as the desktop renderer uploads them
    (:func:`~surfsplat.rendering.gpu_splats.radius_classes`: by radius class, largest first, each class in
    Morton order), with the first index and the largest radius of each class: a frame draws the classes
    too large for a point, a prefix, as quads, and an opaque technique keeps the same splat of two at
    one depth as the desktop."""
    return radius_classes(cloud.radii, cloud.positions)


def encoded(cloud: SplatCloud, order: np.ndarray, fine_positions: bool = False) -> tuple[dict[str, np.ndarray], dict]:
    """The web format's streams and header of the splats ``cloud[order]``: :func:`~surfsplat.io.splat_codec.encode`
    (with ``fine_positions`` 24-bit positions, ``position_fine``: at 16 bits a coordinate the opaque techniques'
    silhouettes differ from the desktop's by 5-17 dB more on the bunny at 1024 x 768),
    and for Phong splats (a cloud with a linear normal field, whose shading normals may lean off the plane
    of ``u`` and ``v``) the plane's normal coded in ``normal`` and the ``shading`` normal (octahedral) and
    ``normal_field`` (float16, flipped with the decoded axes) streams beside it."""
    if cloud.u is None or cloud.v is None or cloud.normals is None:
        raise InputError("a page draws splats: this SplatCloud has no splat axes or normals")
    colors = cloud.colors if cloud.colors is not None else np.full((len(cloud), 3), 0.8, np.float32)
    normals, u, v = cloud.normals[order], cloud.u[order], cloud.v[order]
    field = cloud.normal_field
    plane = web_format.plane_normals(normals, u, v) if field is not None else normals
    streams, header = web_format.encode(cloud.positions[order], plane, colors[order], u, v,
                                        fine_positions=fine_positions)
    if field is not None:
        su, sv = web_format.axis_signs(streams, header, u, v)
        streams["shading"] = web_format.octahedral_encode(normals)
        streams["normal_field"] = web_format.encode_normal_fields(field[order], su, sv).astype("<f2")
    return streams, header


def as_drawn(cloud: SplatCloud, fine_positions: bool = False) -> SplatCloud:
    """The splats a page draws for ``cloud``: in :func:`web_order`, through the web format and back
    (float32, the same origin and up): what the desktop renderer draws to show what the page shows
    (``fine_positions``: a page exported with 24-bit positions)."""
    if cloud.u is None or cloud.v is None or cloud.normals is None:
        raise InputError("a page draws splats: this SplatCloud has no splat axes or normals")
    order = web_order(cloud)[0]
    streams, header = encoded(cloud, order, fine_positions)
    d = web_format.decode(streams, header)
    clips = clip_streams(cloud, order, streams, header)
    lines = None if clips is None else web_format.decode_clip_lines(clips["clip_rows"], clips["clip"], len(cloud))
    normals = d["normals"] if "shading" not in streams else web_format.octahedral_decode(streams["shading"])
    field = streams["normal_field"].astype("f4") if "normal_field" in streams else None
    return SplatCloud(d["positions"].astype("f4"), normals.astype("f4"), d["colors"].astype("f4"),
                      d["u"].astype("f4"), d["v"].astype("f4"), normal_field=field, clip_lines=lines,
                      origin=cloud.origin, up=cloud.up)


def clip_streams(cloud: SplatCloud, order: np.ndarray, streams: dict[str, np.ndarray],
                 header: dict) -> dict[str, np.ndarray] | None:
    """The page's ``clip_rows`` and ``clip`` streams (:func:`~surfsplat.io.splat_codec.encode_clip_lines`):
    the clip lines of the splats of ``cloud[order]`` that cut, in the frame of their decoded axes
    (``streams``, ``header``: the splats' codes); None where the model has no clip lines."""
    if cloud.clip_lines is None or cloud.u is None or cloud.v is None:
        return None
    su, sv = web_format.axis_signs(streams, header, cloud.u[order], cloud.v[order])
    rows, codes = web_format.encode_clip_lines(cloud.clip_lines[order], su, sv)
    return {"clip_rows": rows.astype("<u4"), "clip": codes.astype("<f2")} if len(rows) else None


def hybrid_stream(plan: View, cloud: SplatCloud, order: np.ndarray) -> np.ndarray | None:
    """The page's ``nonplanar`` stream: one bit a splat of ``cloud[order]`` (``np.packbits``, little bit
    order), set where the desktop draws the splat as a round point facing the eye
    (:func:`surfsplat.pipeline.hybrid_splats`); None where the view plan does not draw the model hybrid
    (:attr:`View.hybrid <surfsplat.pipeline.View>`, :func:`~surfsplat.pipeline.hybrid_applies`) or its
    splats carry no flag. A node splat's flag is the majority of its points' (``node_attributes``), as
    :func:`~surfsplat.hierarchy.lod.selection_flags` gives it on the desktop."""
    flags = (cloud.attributes or {}).get(NONPLANAR)
    if not plan.hybrid or flags is None or not hybrid_applies(as_model(plan.model)):
        return None
    return np.packbits(np.asarray(flags, dtype=bool)[order], bitorder="little")


def page_data(plan: View, camera: Camera, cloud: SplatCloud, technique: str, background, name: str,
              ordered: bool = True, fine_positions: bool = False) -> tuple[dict, dict]:
    """The header (everything but the streams) and the streams of a page drawing ``cloud`` (in
    :func:`web_order` where ``ordered``, else as it is: the entries of a browser LOD tree) from ``camera``
    (the exported view): each technique's back-face culling is the view plan's for it
    (:meth:`View.culls <surfsplat.pipeline.View.culls>`), which holds while the eye stays outside the
    model's bounds (the page draws two-sided where it enters them)."""
    if len(cloud) == 0:
        raise InputError(f"{name}: no splats to export")
    if cloud.u is None or cloud.v is None or cloud.normals is None:
        raise InputError(f"{name}: the prepared model has no splat axes or normals to export")
    if ordered:
        order, class_start, class_radius = web_order(cloud)
    else:
        order, class_start, class_radius = np.arange(len(cloud)), np.zeros(1, np.int64), np.full(1, np.inf)
    streams, header = encoded(cloud, order, fine_positions)
    header["normal_fields"] = "normal_field" in streams
    model = as_model(plan.model).points()
    points, direction, up, margin = auto_fit_inputs(model, plan.up)
    options, lights = RenderOptions(), Lights()
    radius = float(cloud.radii.max())
    header.update({
        "name": name, "version": __version__, "origin": np.asarray(cloud.origin, np.float64).tolist(),
        "bounds": [b.tolist() for b in cloud.bounds()], "max_radius": radius,
        "class_start": class_start.tolist(), "class_radius": [min(float(r), 3e38) for r in class_radius],
        "fit": fit_frame(points, direction, up, margin), "fov": defaults.FOV,
        "technique": technique, "techniques": list(WEB_TECHNIQUES), "background": list(background),
        "uniforms": {t: {k: list(np.atleast_1d(v).astype(float)) for k, v in get_technique(t).uniforms(options).items()}
                     for t in WEB_TECHNIQUES},
        "frame": {"u_depth_epsilon": options.visibility.depth_epsilon,
                  "u_separate_sides": options.visibility.separate_sides,
                  "u_clip_fringe": options.visibility.clip_fringe, "u_deferred": options.deferred,
                  "u_supersample": 1.0},
        "culls": {t: plan.culls(camera, options, technique=t) for t in WEB_TECHNIQUES},
        "material": [lights.ambient, lights.diffuse, lights.specular, lights.shininess],
        "footprints": {t: {"footprint": get_technique(t).point_footprint, "min_point_px": get_technique(t).min_point_px}
                       for t in WEB_TECHNIQUES},
        "blended": [t for t in WEB_TECHNIQUES if get_technique(t).blended],
        "edge_fringe": [t for t in WEB_TECHNIQUES if get_technique(t).edge_fringe],
        # the fill pass of every technique, as the desktop draws by default (passes.FillPass), per supersampling
        "fill": {str(k): {"gap": fill_gap(options, k), "depth": fill_depth(fill_gap(options, k)),
                          "program": fill_program(k)} for k in range(1, MAX_PAGE_SUPERSAMPLE + 1)}
        if options.fill_holes else None,
        "supersample": 1, "max_supersample": MAX_PAGE_SUPERSAMPLE,
        "edl": {"strength": EdlOptions().strength, "offsets": neighbour_offsets(EdlOptions().radius_px)},
    })
    clips = clip_streams(cloud, order, streams, header)
    header["clip_lines"] = 0 if clips is None else int(len(clips["clip_rows"]))
    if clips is not None:
        streams.update(clips)
    flags = hybrid_stream(plan, cloud, order)
    header["hybrid"] = flags is not None
    if flags is not None:
        streams["nonplanar"] = flags
    colorings, attributes = attribute_streams(cloud, order, plan.sample().points(), plan.up)
    colorings["tables"] = {k: _b64(v) for k, v in colorings["tables"].items()}
    header["color"] = colorings
    streams.update(attributes)
    return header, {key: _b64(value) for key, value in streams.items()}
