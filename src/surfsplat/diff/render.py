"""Differentiable screen-space EWA splatting (technique ``ewa``) in PyTorch.

The image of :func:`render` is the OpenGL ``ewa`` technique's (``rendering/glsl/ewa.vert``,
``ewa.frag``, ``splat_fragment.glsl``, ``normalize.frag``), with the per-splat and per-pixel formulas
taken from :mod:`surfsplat.reference` run on tensors:

- per splat (Guennebaud 2003, sec. 6): camera-space centre and axes, the Jacobian of the projection at
  the centre (eq. 8), the resampling variance ``J V_r J^T + H`` (eq. 6), its conic, peak weight and
  bounding box, and the Blinn-Phong colour lit at the centre (the vertex stage's lighting);
- per (pixel, splat) pair inside the cutoff ellipse: the EWA weight, the exact ray/plane hit (s, t) and
  its depth (footprint_depth: a fringe fragment gets the depth of the nearest disk point);
- visibility (Guennebaud 2003, sec. 5): the depth ``D`` of the nearest disk at the pixel, offset by
  ``epsilon`` splat radii along the ray, and a *soft* depth test: a pair blends with the factor
  ``sigmoid((D - z) / tau)`` (``tau`` a fraction ``depth_softness`` of the splat's epsilon band) in
  place of the hard ``z <= D``; a fringe fragment (beyond its own disk) also needs ``D <= z + 2 band``
  (``fringe_hidden``). ``depth_softness = 0`` is the hard test. With ``separate_sides`` (the default,
  as ``VisibilityOptions``) only the splats seen from the same side as the nearest disk blend.
- coverage: without edge coverage the OpenGL passes show the background where no disk covers the pixel's
  centre. Here the centre's coverage is ``A = 1 - prod_i (1 - o_i m_i)`` with ``m_i`` the disk's coverage
  of the centre smoothed over ``edge_softness`` pixels across its rim (0: the hard test) and ``o_i`` the
  splat's opacity, so the silhouette moves with the splats; the colour is the normalized blend
  ``sum w c / sum w`` (Guennebaud 2003, eq. 18), clamped to [0, 1] and composited over the background by
  alpha. With ``edge_coverage`` (the default, as ``VisibilityOptions``) a rim pixel's alpha is instead the
  fraction of its area the disks cover, by OpenGL's rule (``reference.edge_alpha``: normalize.frag): each
  pair brings the disk's pixel coverage ``c_i`` (times its opacity) and the signed distance ``d_i`` of the
  pixel's centre to its rim (``reference.disk_coverage``: splat_fragment.glsl), their soft maxima are
  summed per pixel weighted by the soft depth test, and the alpha of a covered pixel and that of an
  uncovered one (set by its 8 neighbours: whether the centre is covered is discrete) are mixed by ``A``;
  gradients flow through ``A``, ``c_i`` and ``d_i``.

Evaluation is vectorized and tiled: splats are binned to horizontal bands of rows by their boxes, and
each band evaluates its (pixel, splat) pairs in batched tensor operations with the per-pixel sums as
scatter reductions; the number of pairs a band holds is bounded (``max_pairs``), and with several bands
and gradients each band is checkpointed, so memory is bounded by the band, not the image. Any device
PyTorch runs on (CPU, CUDA, MPS) works: every tensor follows the splats' device.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import torch
from torch.utils.checkpoint import checkpoint

from .. import reference as ref
from ..errors import InputError
from ..lighting import Lights
from .scene import DiffCamera, Splats

#: Smallest depth of a drawn splat centre when the camera has no near plane (the Jacobian needs z > 0).
MIN_DEPTH = 1e-6


@dataclass(frozen=True)
class DiffOptions:
    """Options of the differentiable renderer; defaults match the OpenGL ``ewa`` technique's.

    Attributes:
        cutoff: c of ``FilterOptions`` (the kernel is cut at ``0.5 x^T V^-1 x = c``).
        prefilter: the one-pixel EWA prefilter ``H = I``.
        depth_epsilon: visibility offset along the rays in splat radii (``VisibilityOptions``).
        depth_softness: width of the soft depth test, as a fraction of each splat's epsilon band (0: hard).
        edge_softness: width in pixels over which a disk's coverage falls to 0 across its rim (0: hard).
        edge_coverage: rim pixels take the fraction of their area the disks cover as alpha, as the OpenGL
            passes do with ``VisibilityOptions.edge_coverage`` (the default); off: the papers' rims.
        separate_sides: a pixel blends only the splats seen from the side (front or back of their
            normals) of its nearest one (``VisibilityOptions.separate_sides``).
        min_visibility: with gradients, pairs whose soft depth test passes less than this are left out of
            the differentiable pass (hidden surfaces: their weight is below it; 0: every pair is kept).
        max_pairs: most (pixel, splat) pairs evaluated at once (a band of rows holds at most this many,
            unless one row alone holds more).
    """

    cutoff: float = 1.0
    prefilter: bool = True
    depth_epsilon: float = 1.0
    depth_softness: float = 0.1
    edge_softness: float = 0.02
    max_pairs: int = 4_000_000
    min_visibility: float = 1e-4
    separate_sides: bool = True
    edge_coverage: bool = True

    def __post_init__(self) -> None:
        for name in ("cutoff", "depth_epsilon", "depth_softness", "edge_softness", "min_visibility"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and value >= 0 and value == value and value != float("inf")):
                raise InputError(f"{name} must be a finite number >= 0, got {value!r}", argument=name)
        if self.cutoff <= 0:
            raise InputError(f"cutoff must be > 0, got {self.cutoff!r}", argument="cutoff")
        if int(self.max_pairs) < 1:
            raise InputError(f"max_pairs must be >= 1, got {self.max_pairs!r}", argument="max_pairs")


@dataclass
class DiffFrame:
    """The differentiable renderer's output, row 0 at the top of the image.

    Attributes:
        color: (H, W, 3) composited over the background.
        alpha: (H, W) coverage in [0, 1].
        depth: (H, W) weighted mean camera-space depth of the blended splats (0 where none).
        weight: (H, W) accumulated EWA weight.
    """

    color: torch.Tensor
    alpha: torch.Tensor
    depth: torch.Tensor
    weight: torch.Tensor


# Rows of the per-splat feature table (one (splats,) tensor per feature: a pair's gather is a 1-D gather per
# feature, whose backward is a 1-D scatter, twice as fast on CPU as gathering columns of a 2-D table and
# giving each feature's per-pair values as a contiguous row): the ray/splat coefficients
# (reference.ray_coefficients, 15), radius, seen from the back (the rows the visibility needs, first), the
# projected centre (2), the conic V^-1 (xx, xy, yy), the peak weight, the lit colour (3), opacity, rho,
# the rim Jacobian (d(s, t)/dx, d(s, t)/dy: reference.rim_jacobian, row-major).
Table = tuple[torch.Tensor, ...]
_RADIUS, _BACK = ref.RAY_COEFFICIENTS, ref.RAY_COEFFICIENTS + 1
_VISIBILITY = slice(0, _BACK + 1)
_CENTER_CONIC = slice(_BACK + 1, _BACK + 6)
_SCALE, _COLOR, _OPACITY, _RHO = _BACK + 6, slice(_BACK + 7, _BACK + 10), _BACK + 10, _BACK + 11
_RIM = slice(_BACK + 12, _BACK + 16)


def _splat_table(splats: Splats, camera: DiffCamera, lights: Lights, options: DiffOptions):
    """Per-splat stage (the vertex shader's work): the table of the drawn splats (a tuple of (splats,)
    feature rows) and their inclusive pixel boxes (x0, x1, y0, y1) in window pixels (y up)."""
    r, f = camera.rotation, camera.focal
    p = ref.transform_points(r, camera.translation, splats.positions)
    u = splats.u @ r.T
    v = splats.v @ r.T
    plane = ref.unit(ref.cross(u, v))
    shading = ref.unit(splats.normals @ r.T) if splats.normals is not None else plane
    plane = torch.where(ref.dot(plane, shading, keepdims=True) < 0, -plane, plane)
    # the side the eye sees: the plane's normal (and the shading normal) turned toward the eye
    back = ref.dot(plane, p, keepdims=True) > 0
    plane = torch.where(back, -plane, plane)
    shading = torch.where(back, -shading, shading)
    if camera.near is None:
        near = MIN_DEPTH
    else:
        near = max(float(camera.near), MIN_DEPTH)
    far = float("inf") if camera.far is None else float(camera.far)
    z = -p[:, 2]
    zext = torch.sqrt(u[:, 2] ** 2 + v[:, 2] ** 2)
    with torch.no_grad():
        keep = (z >= near) & (z - zext <= far) & (-ref.dot(plane, p) > ref.EDGE_ON_TOLERANCE * ref.norm(p))
    idx = torch.nonzero(keep).squeeze(1)
    p, u, v, plane, shading = p[idx], u[idx], v[idx], plane[idx], shading[idx]
    if lights.directions is None:   # the headlight: from the target toward the eye, +z in camera space
        light_dirs: Any = torch.tensor([[0.0, 0.0, 1.0]], dtype=p.dtype, device=p.device)
    else:
        light_dirs = torch.as_tensor(lights.directions, dtype=p.dtype, device=p.device) @ r.T
    color = ref.shade(splats.colors[idx], shading, ref.unit(-p), light_dirs, lights)
    jac = ref.jacobian(f, p, u, v)
    var = ref.ewa_variance(jac, options.cutoff, options.prefilter)
    conic = ref.inv2(var)
    scale = ref.ewa_scale(var, jac, options.cutoff)
    center = ref.project_points(p, f, camera.principal)
    half = ref.ewa_half_extent(var, options.cutoff)
    opacity = splats.opacity[idx] if splats.opacity is not None else torch.ones_like(scale)
    radius = torch.maximum(ref.norm(u), ref.norm(v))
    rho = torch.sqrt(torch.abs(ref.det2(jac)) + 1e-12)   # projected radius, pixels (geometric mean)
    if options.edge_coverage:
        rim = ref.rim_jacobian(f, p, plane, u, v).reshape(-1, 4)
    else:
        rim = torch.zeros((len(p), 4), dtype=p.dtype, device=p.device)
    xx, xy, _, yy = conic.reshape(-1, 4).unbind(1)
    table = tuple(t.contiguous() for t in (*ref.ray_coefficients(p, plane, u, v).unbind(0), radius,
                                           back[idx, 0].to(p.dtype), *center.unbind(1), xx, xy, yy, scale,
                                           *color.unbind(1), opacity, rho, *rim.unbind(1)))
    with torch.no_grad():
        c, h = center.detach(), half.detach()
        lo = torch.ceil(c - h - 0.5)
        hi = torch.floor(c + h - 0.5)
        limit = torch.tensor([camera.width - 1, camera.height - 1], dtype=c.dtype, device=c.device)
        lo = torch.maximum(lo, torch.zeros_like(lo))
        hi = torch.minimum(hi, limit)
        ok = torch.isfinite(lo).all(dim=1) & torch.isfinite(hi).all(dim=1) & (lo <= hi).all(dim=1)
        box = torch.where(ok[:, None], torch.cat([lo[:, :1], hi[:, :1], lo[:, 1:], hi[:, 1:]], dim=1),
                          torch.tensor([0.0, -1.0, 0.0, -1.0], dtype=c.dtype, device=c.device)).long()
    return table, box


def _band_pairs(box: torch.Tensor, row0: int, row1: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(splat, x, y) of every pixel of the splats' boxes in window rows [row0, row1), splat by splat and row
    by row: the (splat, row) segments first, then their pixels (repeats and sums, no division)."""
    y0 = torch.clamp(box[:, 2], min=row0)
    ny = (torch.clamp(box[:, 3], max=row1 - 1) - y0 + 1).clamp(min=0)
    nx = (box[:, 1] - box[:, 0] + 1).clamp(min=0)
    ny = torch.where(nx > 0, ny, torch.zeros_like(ny))
    arange = torch.arange(len(box), device=box.device)
    seg_splat = torch.repeat_interleave(arange, ny)
    first = torch.cumsum(ny, 0) - ny
    seg_y = torch.arange(len(seg_splat), device=box.device) + (y0 - first).index_select(0, seg_splat)
    seg_nx = nx.index_select(0, seg_splat)
    seg_x = box[:, 0].index_select(0, seg_splat) - (torch.cumsum(seg_nx, 0) - seg_nx)
    sid = torch.repeat_interleave(seg_splat, seg_nx)
    ix = torch.repeat_interleave(seg_x, seg_nx) + torch.arange(len(sid), device=box.device)
    return sid, ix, torch.repeat_interleave(seg_y, seg_nx)


def _visibility(hit: torch.Tensor, z: torch.Tensor, band: torch.Tensor, inside: torch.Tensor,
                from_back: torch.Tensor, pixel: torch.Tensor, npix: int,
                options: DiffOptions) -> tuple[torch.Tensor, torch.Tensor]:
    """The soft depth test's factor of each pair (ray/plane distance ``hit``, fragment depth ``z``, epsilon
    ``band``, ``inside`` its disk, the splat seen ``from_back``) against the nearest disk at its pixel, and
    (npix,) whether a disk covers each pixel's centre."""
    dtype, device = hit.dtype, hit.device
    # Guennebaud 2003, sec. 5: the nearest disk's depth at the pixel, offset by epsilon along the ray
    # for each side of the splats (seen from the front, from the back) apart: the side the eye sees
    # nearest is the pixel's (visibility.glsl's record), and with separate sides only it blends. One
    # scatter over (pixel, side) of every pair, the pairs beyond their disks at infinity
    offset_depth = torch.where(inside, hit + band, torch.full_like(hit, float("inf")))
    start = torch.full((2 * npix,), float("inf"), dtype=dtype, device=device)
    nearest = start.scatter_reduce(0, 2 * pixel + from_back.long(), offset_depth, "amin",
                                   include_self=True).view(npix, 2).unbind(1)
    pixel_back = nearest[1] < nearest[0]
    nearest_depth = torch.minimum(nearest[0], nearest[1])
    covered = torch.isfinite(nearest_depth)
    d = torch.where(covered, nearest_depth, torch.zeros_like(nearest_depth))[pixel]
    if options.depth_softness > 0:
        tau = options.depth_softness * band
        vis = torch.sigmoid((d - z) / tau)
        fringe = torch.sigmoid((z + 2.0 * band - d) / tau)
    else:
        vis = (z <= d).to(dtype)
        fringe = (z + 2.0 * band >= d).to(dtype)
    vis = torch.where(inside, vis, vis * fringe)
    if options.separate_sides:
        vis = torch.where(pixel_back[pixel] == from_back, vis, torch.zeros_like(vis))
    return torch.where(covered[pixel], vis, torch.ones_like(vis)), covered


@torch.no_grad()
def _visible_pairs(table: Table, sid: torch.Tensor, ix: torch.Tensor, iy: torch.Tensor, pixel: torch.Tensor,
                   npix: int, camera: DiffCamera, options: DiffOptions) -> torch.Tensor:
    """Which pairs the differentiable pass keeps: drawn (``_drawn``) and the soft depth test passes at least
    ``min_visibility``. The quantities of :func:`_pair_terms` that decide it (ray/plane distance, disk
    coordinates, footprint depth), from the rows the visibility needs only."""
    rows = _gather(_detached(table[_VISIBILITY]), sid)
    x, y = _pixel_rays(ix, iy, camera, detach=True)
    hit, s, r, z = ref.footprint_hits(rows, x, y)
    r2 = s * s + r * r
    band = options.depth_epsilon * rows[_RADIUS] * torch.rsqrt(x * x + y * y + 1.0)
    inside = (r2 <= 1.0) & (hit > 0)
    vis = _visibility(hit, z, band, inside, rows[_BACK] > 0.5, pixel, npix, options)[0]
    return _drawn(hit, options) & (vis >= options.min_visibility)


def _pixel_rays(ix: torch.Tensor, iy: torch.Tensor, camera: DiffCamera,
                detach: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
    """(x, y) of the rays ``(x, y, -1)`` through the centres of window pixels ``(ix, iy)`` (differentiable
    with respect to the focal length unless ``detach``)."""
    f = camera.focal.detach() if detach else camera.focal
    cx, cy = camera.principal
    return (ix.to(f.dtype) + (0.5 - cx)) / f, (iy.to(f.dtype) + (0.5 - cy)) / f


def _drawn(hit: torch.Tensor, options: DiffOptions) -> torch.Tensor:
    """Which pairs (ray/plane distance ``hit``) the accumulation draws: those whose ray meets the splat's
    plane in front of the eye, and with edge coverage also those meeting it behind the eye (a fringe
    fragment beyond the plane's horizon: splat_fragment.glsl's footprint_st), whose coverage counts."""
    finite = torch.isfinite(hit)
    return finite if options.edge_coverage else finite & (hit > 0)


def _pair_terms(table: Table, sid: torch.Tensor, ix: torch.Tensor, iy: torch.Tensor, pixel: torch.Tensor,
                npix: int, camera: DiffCamera, options: DiffOptions) -> dict[str, torch.Tensor]:
    """The per-pair terms of pairs (splat ``sid``, window pixel ``(ix, iy)``, band pixel index ``pixel``)."""
    rows = _gather(table[:_RIM.start], sid)   # flat arithmetic on (pairs,) rows
    dtype = table[0].dtype
    dx = ix.to(dtype) + 0.5 - rows[_CENTER_CONIC.start]
    dy = iy.to(dtype) + 0.5 - rows[_CENTER_CONIC.start + 1]
    beta = ref.conic_beta(rows[_CENTER_CONIC.start + 2], rows[_CENTER_CONIC.start + 3],
                          rows[_CENTER_CONIC.start + 4], dx, dy)
    x, y = _pixel_rays(ix, iy, camera)
    hit, s, r, z = ref.footprint_hits(rows, x, y)
    r2 = s * s + r * r
    band = options.depth_epsilon * rows[_RADIUS] * torch.rsqrt(x * x + y * y + 1.0)
    with torch.no_grad():
        inside = (r2 <= 1.0) & (hit > 0)   # a ray meeting the plane behind the eye does not hit the disk
        from_back = rows[_BACK] > 0.5
    vis, covered = _visibility(hit, z, band, inside, from_back, pixel, npix, options)
    return {"beta": beta, "r2": r2, "z": z, "vis": vis, "inside": inside, "scale": rows[_SCALE],
            "color": rows[_COLOR], "opacity": rows[_OPACITY], "rho": rows[_RHO], "hit": hit, "covered": covered,
            "dx": dx, "dy": dy}


def _gather(rows: tuple[torch.Tensor, ...], index: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """The entries ``index`` of each of the (splats,) feature ``rows``."""
    return tuple(torch.index_select(r, 0, index) for r in rows)


def _detached(rows: tuple[torch.Tensor, ...]) -> tuple[torch.Tensor, ...]:
    """The feature rows without their gradients."""
    return tuple(r.detach() for r in rows)


def _requires_grad(rows: tuple[torch.Tensor, ...]) -> bool:
    """Whether any feature row requires gradients."""
    return any(r.requires_grad for r in rows)


def _select(keep: torch.Tensor, *columns: torch.Tensor) -> tuple[torch.Tensor, ...]:
    """The entries of the (M,) integer ``columns`` where ``keep``: one nonzero and one gather for all."""
    index = torch.nonzero(keep).squeeze(1)
    return torch.stack(columns).index_select(1, index).unbind(0)


def _band(table: Table, box: torch.Tensor, camera: DiffCamera, options: DiffOptions, row0: int,
          row1: int) -> torch.Tensor:
    """Per-pixel sums of window rows [row0, row1): (rows * W, 6) = (sum w c, sum w, sum w z, sum log(1 - o m)),
    and with edge coverage 5 more: the soft maxima's sums (reference.soft_maxima) and whether a disk covers the
    pixel's centre."""
    width = camera.width
    dtype, device = table[0].dtype, table[0].device
    npix = (row1 - row0) * width
    differentiable = torch.is_grad_enabled() and _requires_grad(table)
    with torch.no_grad():
        # the pairs inside the cutoff ellipse whose ray meets the splat's plane in front of the eye, and
        # (those hidden far behind the nearest surface weigh nothing) whose soft depth test passes
        sid, ix, iy = _band_pairs(box, row0, row1)
        t = _detached(table)
        rows = _gather(t[_CENTER_CONIC], sid)   # centre and conic
        keep = ref.conic_beta(rows[2], rows[3], rows[4], ix.to(dtype) + 0.5 - rows[0],
                              iy.to(dtype) + 0.5 - rows[1]) <= options.cutoff
        sid, ix, iy = _select(keep, sid, ix, iy)
        pixel = (iy - row0) * width + ix
        if options.min_visibility > 0 and differentiable:
            keep = _visible_pairs(t, sid, ix, iy, pixel, npix, camera, options)
        else:
            rows = _gather(t[:4], sid)   # the normal and n . p
            x, y = _pixel_rays(ix, iy, camera, detach=True)
            keep = _drawn(rows[3] / (rows[0] * x + rows[1] * y - rows[2]), options)
        sid, ix, iy, pixel = _select(keep, sid, ix, iy, pixel)
    terms = _pair_terms(table, sid, ix, iy, pixel, npix, camera, options)
    opacity, r2 = terms["opacity"], terms["r2"]
    w = opacity * terms["scale"] * torch.exp(-terms["beta"]) * terms["vis"]
    if options.edge_softness > 0:
        rim = (1.0 - torch.sqrt(r2 + 1e-12)) * terms["rho"]   # pixels inside the rim
        m = torch.sigmoid(rim / options.edge_softness)
    else:
        m = terms["inside"].to(dtype)
    log_clear = torch.log1p(-torch.clamp(opacity * m, max=1.0 - 8.0 * torch.finfo(dtype).eps))
    color = terms["color"]
    columns = [w * color[0], w * color[1], w * color[2], w, w * terms["z"], log_clear]
    sums = torch.zeros((npix, len(columns)), dtype=dtype, device=device).index_add(0, pixel,
                                                                                  torch.stack(columns, dim=1))
    if options.edge_coverage:
        sums = torch.cat([sums, _edge_sums(table, sid, pixel, terms, camera, row0, row1)], dim=1)
    return sums


def _edge_sums(table: Table, sid: torch.Tensor, pixel: torch.Tensor, terms: dict[str, torch.Tensor],
               camera: DiffCamera, row0: int, row1: int) -> torch.Tensor:
    """(band pixels, 5): the soft maxima's sums of splat_fragment.glsl's out_cover (reference.soft_maxima),
    each fragment weighted by its depth test, and whether a disk covers the pixel's centre. Only the
    pixels whose alpha reads them are summed (reference.edge_alpha: those within one pixel of one that no
    disk covers, and the band's first and last rows, whose neighbours lie in other bands); the others
    are inside the surface and keep zeros."""
    covered = terms["covered"]
    dtype = table[0].dtype
    with torch.no_grad():
        uncovered = (~covered).to(dtype).reshape(1, 1, row1 - row0, camera.width)
        near = torch.nn.functional.max_pool2d(uncovered, 3, stride=1, padding=1)[0, 0] > 0
        if row0 > 0:
            near[0] = True
        if row1 < camera.height:
            near[-1] = True
        sub = torch.nonzero(near.reshape(-1)[pixel]).squeeze(1)
    jxx, jxy, jyx, jyy = _gather(table[_RIM], sid[sub])
    cover, d = ref.rim_coverage(jxx, jxy, jyx, jyy, terms["dx"][sub], terms["dy"][sub])
    fragment = ref.soft_maximum_terms(terms["opacity"][sub] * cover, d, terms["vis"][sub])
    sums = torch.zeros((len(covered), 4), dtype=dtype, device=covered.device)
    sums = sums.index_add(0, pixel[sub], torch.stack(fragment, dim=1))
    return torch.cat([sums, covered.to(dtype)[:, None]], dim=1)


def _bands(box: torch.Tensor, height: int, max_pairs: int) -> list[tuple[int, int]]:
    """Row ranges [r0, r1) holding at most ``max_pairs`` box pixels each (a row holding more: alone)."""
    nx = (box[:, 1] - box[:, 0] + 1).clamp(min=0)
    per_row = torch.zeros(height + 1, dtype=torch.long, device=box.device)
    valid = box[:, 3] >= box[:, 2]
    per_row.index_add_(0, box[valid, 2], nx[valid])
    per_row.index_add_(0, box[valid, 3] + 1, -nx[valid])
    counts = torch.cumsum(per_row, 0)[:height].cpu().tolist()
    bands, start, total = [], 0, 0
    for row, n in enumerate(counts):   # one step per image row, not per splat
        if total + n > max_pairs and row > start:
            bands.append((start, row))
            start, total = row, 0
        total += n
    bands.append((start, height))
    return bands


def render_frame(splats: Splats, camera: DiffCamera, *, lights: Lights | None = None,
                 background=(1.0, 1.0, 1.0), options: DiffOptions | None = None) -> DiffFrame:
    """Render ``splats`` seen by ``camera`` with EWA splatting: colour, alpha, depth and weight images.

    Differentiable with respect to every tensor of ``splats`` and ``camera`` (positions, axes, colours,
    opacity, normals; rotation, translation, focal length). ``lights``: None is the default headlight
    and material (:class:`~surfsplat.lighting.Lights`); ``Lights(enabled=False)`` renders the albedo.
    ``background``: RGB in [0, 1]. See the module docstring for the visibility and coverage models.
    """
    options = options or DiffOptions()
    lights = lights if lights is not None else Lights()
    if len(splats) == 0:
        raise InputError("no splats to render")
    table, box = _splat_table(splats, camera, lights, options)
    height, width = camera.height, camera.width
    bands = _bands(box, height, int(options.max_pairs))
    parts = []
    for row0, row1 in bands:   # one step per band of rows, not per splat
        if len(bands) > 1 and _requires_grad(table):
            parts.append(checkpoint(_band, table, box, camera, options, row0, row1, use_reentrant=False))
        else:
            parts.append(_band(table, box, camera, options, row0, row1))
    sums = torch.cat(parts, dim=0).reshape(height, width, -1).flip(0)   # window rows (y up) -> image rows
    weight = sums[..., 3]
    has = weight > 0
    safe = torch.where(has, weight, torch.ones_like(weight))
    color = torch.clamp(sums[..., :3] / safe[..., None], 0.0, 1.0)
    depth = torch.where(has, sums[..., 4] / safe, torch.zeros_like(weight))
    center = -torch.expm1(sums[..., 5])
    if options.edge_coverage:
        cover, distance, reached = ref.soft_maxima(sums[..., 6], sums[..., 7], sums[..., 8], sums[..., 9])
        center = ref.edge_alpha(sums[..., 10].detach() > 0.5, cover, distance, reached, center=center)
    alpha = torch.where(has, center, torch.zeros_like(weight))
    bg = torch.as_tensor(background, dtype=color.dtype, device=color.device)
    image = alpha[..., None] * color + (1.0 - alpha[..., None]) * bg
    return DiffFrame(color=image, alpha=alpha, depth=depth, weight=weight)


def render(splats: Splats, camera: DiffCamera, *, lights: Lights | None = None, background=(1.0, 1.0, 1.0),
           options: DiffOptions | None = None) -> torch.Tensor:
    """(H, W, 3) image of ``splats`` seen by ``camera`` (row 0 at the top), differentiable: see :func:`render_frame`."""
    return render_frame(splats, camera, lights=lights, background=background, options=options).color
