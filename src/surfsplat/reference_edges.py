"""Reference of the edge-coverage formulas: antialiased silhouettes without supersampling.

``splat_fragment.glsl``'s ``disk_coverage`` (the fraction of a pixel a splat's disk covers and the signed
distance of the pixel's centre to its rim) and ``normalize.frag``'s ``edge_alpha`` (a pixel's alpha from
those of the splats reaching it and its neighbours'), vectorized and written against the array namespace
(:mod:`surfsplat.arrays`) like the ``ewa`` formulas of :mod:`surfsplat.reference`, which re-exports them:
the tests hold the shaders against them on NumPy and the differentiable renderer (:mod:`surfsplat.diff`)
runs them on tensors. Window pixels, y up.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .arrays import array_namespace, dot, norm


def _unit(a) -> Any:
    """Vectors over the last axis scaled to unit length."""
    return a / norm(a, keepdims=True)


# The constants are splat_fragment.glsl's, of the same names.

#: Sharpness of the soft maximum of the splats' pixel coverages at a pixel (coverages within about 1/32 of
#: the largest one weigh alike).
COVER_SHARPNESS = 32.0
#: Sharpness of the soft maximum of the signed distances of the pixel's centre to the splats' rims.
DISTANCE_SHARPNESS = 8.0
#: Rim distances are clamped to +-COVER_REACH pixels (beyond, a pixel is wholly in or out).
COVER_REACH = 2.0
#: The rim's squeeze along the foreshortened direction of a disk seen nearly edge-on, and the power of the
#: cosine off edge-on that fades it out for disks facing the eye.
RIM_SQUEEZE = 0.05
RIM_SQUEEZE_FALLOFF = 4.0


def halfplane_coverage(d, n) -> Any:
    """Area of the unit pixel box ``{|x|, |y| <= 1/2}`` on the inner side ``n . x <= d`` of a straight edge at
    signed distance ``d`` (pixels, > 0: the centre inside) with unit normal ``n`` (..., 2): the CDF at ``d``
    of ``n . x`` over the box, the convolution of two uniform distributions of widths ``|n_x|``, ``|n_y|``
    (a trapezoid). ``halfplane_coverage`` in splat_fragment.glsl."""
    xp = array_namespace(d, n)
    m = xp.abs(n)
    a = xp.maximum(m[..., 0], m[..., 1])
    b = xp.minimum(m[..., 0], m[..., 1])
    x = xp.abs(d)
    t = xp.clip(0.5 * (a + b) - x, 0.0, None)
    ab = a * b
    ok = ab > 1e-8
    ramp = xp.where(ok, 0.5 * t * t / xp.where(ok, ab, 1.0), 0.0)   # safe divisor: no NaN gradient
    tail = xp.where(x < 0.5 * (a - b), 0.5 - x / xp.where(a > 0, a, 1.0), ramp)
    return xp.where(d >= 0, 1.0 - tail, tail)


def rim_jacobian(focal, p_cam, n_cam, u_cam, v_cam) -> Any:
    """(N, 2, 2) derivative of a splat's (squeezed) normalized coordinates (s, t) with respect to the window
    pixel (x, y), the per-splat half of ``disk_coverage`` in splat_fragment.glsl: the disk mapped to the
    image by the affine approximation of the projection at its centre (Zwicker 2004, sec. 3; Guennebaud
    2003, sec. 6), squeezed to ``RIM_SQUEEZE`` of its width along its foreshortened direction ``w`` (the view
    direction's projection on its plane) by the weight ``|w|^RIM_SQUEEZE_FALLOFF``: a tangent disk of radius
    r at a silhouette whose surface curves with radius R reaches past it by up to r^2 / 2R, the squeezed
    one by that times RIM_SQUEEZE^2. Columns: d(s, t)/dx, d(s, t)/dy. Rows of splats whose plane the ray
    through their centre does not meet in front of the eye are zeros (no coverage).

    ``p_cam``, ``n_cam`` (unit or not: only the plane matters), ``u_cam``, ``v_cam``: (N, 3) camera space;
    ``focal`` in pixels.
    """
    xp = array_namespace(p_cam, n_cam, u_cam, v_cam, focal)
    z = -p_cam[:, 2]
    n_p = dot(n_cam, p_cam)
    # v_plane = n / (n . p): the plane is v_plane . x = 1; along the centre's ray p / z it is at 1 / denom
    ok = (z > 0) & (n_p != 0)
    plane = n_cam / xp.where(ok, n_p, 1.0)[:, None]
    ray = p_cam / xp.where(ok, z, 1.0)[:, None]
    denom = dot(plane, ray)
    ok = ok & (denom > 0)
    denom = xp.where(ok, denom, 1.0)
    q = ray / denom[:, None]
    udual = u_cam / dot(u_cam, u_cam, keepdims=True)
    vdual = v_cam / dot(v_cam, v_cam, keepdims=True)
    # d q / d px for the ray's derivatives (1 / f, 0, 0) and (0, 1 / f, 0)
    ex = xp.zeros_like(q)
    qx = (-q * plane[:, :1]) / (focal * denom[:, None])
    qy = (-q * plane[:, 1:2]) / (focal * denom[:, None])
    qx = qx + xp.stack([1.0 / (focal * denom), ex[:, 0], ex[:, 0]], axis=-1)
    qy = qy + xp.stack([ex[:, 0], 1.0 / (focal * denom), ex[:, 0]], axis=-1)
    sx = xp.stack([dot(qx, udual), dot(qx, vdual)], axis=-1)   # d (s, t) / d x
    sy = xp.stack([dot(qy, udual), dot(qy, vdual)], axis=-1)   # d (s, t) / d y
    toward = -_unit(p_cam)
    nrm = _unit(n_cam)
    w = toward - dot(toward, nrm, keepdims=True) * nrm   # |w|: the cosine of the angle off edge-on
    wst = xp.stack([dot(w, udual), dot(w, vdual)], axis=-1)
    wl = norm(wst)
    squeeze = wl > 1e-6
    wst = wst / xp.where(squeeze, wl, 1.0)[:, None]
    k = xp.where(squeeze, (1.0 / RIM_SQUEEZE - 1.0) * dot(w, w) ** (0.5 * RIM_SQUEEZE_FALLOFF), 0.0)
    # m = I + k wst wst^T; the columns m sx, m sy
    mx = sx + (k * dot(wst, sx))[:, None] * wst
    my = sy + (k * dot(wst, sy))[:, None] * wst
    jac = xp.stack([mx, my], axis=-1)
    return xp.where(ok[:, None, None], jac, 0.0)


def disk_coverage(rim_jac, offset) -> tuple[Any, Any]:
    """The fraction of a pixel a splat's disk covers and the signed distance of the pixel's centre to the
    disk's rim (pixels, > 0 inside, clamped to +-``COVER_REACH``), to first order in that distance: the
    distance of the (squeezed) disk coordinates' radius to 1 over the length of its gradient, and the
    half-plane coverage of that edge (:func:`halfplane_coverage`). The per-pixel half of
    ``disk_coverage`` in splat_fragment.glsl (no clip lines). ``rim_jac``: (..., 2, 2) of
    :func:`rim_jacobian` (zeros: coverage 0, distance ``-COVER_REACH``); ``offset``: (..., 2) pixel centre
    minus the projected splat centre, window pixels. Returns two (...) arrays."""
    return rim_coverage(rim_jac[..., 0, 0], rim_jac[..., 0, 1], rim_jac[..., 1, 0], rim_jac[..., 1, 1],
                        offset[..., 0], offset[..., 1])


def rim_coverage(jxx, jxy, jyx, jyy, dx, dy) -> tuple[Any, Any]:
    """:func:`disk_coverage` on the entries of the rim Jacobian (rows s, t; columns x, y) and the offsets
    ``(dx, dy)``, all (...) arrays."""
    xp = array_namespace(jxx, jxy, jyx, jyy, dx, dy)
    s = jxx * dx + jxy * dy
    t = jyx * dx + jyy * dy
    r2 = s * s + t * t
    far = r2 > 1e-12
    r = xp.sqrt(xp.where(far, r2, 1.0))
    rs = xp.where(far, s / r, 1.0)   # the radial direction (1, 0) at the centre
    rt = xp.where(far, t / r, 0.0)
    r = xp.where(far, r, 0.0)
    gx = rs * jxx + rt * jyx   # the gradient of |(s, t)| over the pixel, outward
    gy = rs * jxy + rt * jyy
    g2 = gx * gx + gy * gy
    has = g2 > 0   # else a zero Jacobian: a splat rim_jacobian leaves out
    g = xp.sqrt(xp.where(has, g2, 1.0))
    d = xp.where(has, (1.0 - r) / g, -COVER_REACH)
    n = xp.stack([xp.where(has, gx / g, 1.0), xp.where(has, gy / g, 0.0)], axis=-1)
    return xp.where(has, halfplane_coverage(d, n), 0.0), xp.clip(d, -COVER_REACH, COVER_REACH)


def _shifted(a, dy: int, dx: int, fill) -> Any:
    """(H, W) ``a`` at ``[y + dy, x + dx]``, ``fill`` beyond its borders."""
    xp = array_namespace(a)
    h, w = a.shape
    out = xp.full_like(a, fill)
    out[max(-dy, 0):h - max(dy, 0), max(-dx, 0):w - max(dx, 0)] = a[max(dy, 0):h + min(dy, 0),
                                                                    max(dx, 0):w + min(dx, 0)]
    return out


def soft_maximum_terms(cover, distance, weight) -> tuple[Any, Any, Any, Any]:
    """One fragment's four terms of the sums :func:`soft_maxima` reads (splat_fragment.glsl's
    ``out_cover``), each times ``weight`` (its depth test): ``e^(S (c - 1))``, ``c e^(S (c - 1))``,
    ``e^(S_d (d - R))`` and ``d e^(S_d (d - R))`` of its pixel coverage ``cover`` and rim distance
    ``distance`` (pixels)."""
    xp = array_namespace(cover, distance)
    e = weight * xp.exp(COVER_SHARPNESS * (cover - 1.0))
    ed = weight * xp.exp(DISTANCE_SHARPNESS * (distance - COVER_REACH))
    return e, cover * e, ed, distance * ed


def soft_maxima(sum_e, sum_ce, sum_ed, sum_dd) -> tuple[Any, Any, Any]:
    """A pixel's largest coverage by one disk and largest rim distance from the accumulated soft-maximum
    sums (``sum e^(S (c - 1))``, ``sum c e^(S (c - 1))``, ``sum e^(S_d (d - R))``, ``sum d e^(S_d (d - R))``,
    splat_fragment.glsl's ``out_cover``): ``(cover, distance, reached)``, cover 0 and distance -1e6 where no
    fragment reached the pixel (``cover_at`` in normalize.frag)."""
    xp = array_namespace(sum_e, sum_ce, sum_ed, sum_dd)
    has_c, reached = sum_e > 0, sum_ed > 0
    cover = xp.where(has_c, xp.clip(sum_ce / xp.where(has_c, sum_e, 1.0), 0.0, 1.0), 0.0)
    distance = xp.where(reached, sum_dd / xp.where(reached, sum_ed, 1.0), -1e6)
    return cover, distance, reached


def edge_alpha(covered, cover, distance, reached, center=None) -> Any:
    """(H, W) alpha of the pixels with edge coverage (``edge_alpha`` in normalize.frag, one sample per pixel).

    ``covered``: (H, W) bool, a disk covers the pixel's centre (the visibility pass's record); ``cover``,
    ``distance``, ``reached``: the pixel's :func:`soft_maxima`. Rows in either order (the rule is symmetric).
    A pixel no disk covers is a crack where 3 or 4 of its 4 neighbours are covered (the fringes fill it:
    alpha 1), else open: the largest coverage of one disk, at most 1/2 (outside, the nearest disk's rim is
    the union's). A covered pixel with no open pixel among its 8 neighbours has alpha 1; one on the rim
    the largest of its own coverage and the coverage ``1/2 + d`` of a straight rim at the distance ``d`` of
    its centre to the union's rim, bounded by each open neighbour q's rim distance plus ``|q - p|``
    (distances are 1-Lipschitz); its own coverage where no fragment reached an open neighbour.
    ``center``: (H, W) the differentiable renderer's soft coverage of the centre in [0, 1] (None:
    ``covered``): on the rim and outside, the alpha of a covered pixel and that of an uncovered one mixed
    by it; inside (covered, no open neighbour) ``center`` itself, which reads neither ``cover`` nor
    ``distance`` there.
    """
    xp = array_namespace(covered, cover, distance, reached)
    count = sum(_shifted(covered, dy, dx, False).astype(int) if xp is np else
                _shifted(covered, dy, dx, False).long() for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)))
    crack = ~covered & (count >= 3)
    open_ = ~covered & ~crack
    rim = xp.zeros_like(covered)
    d = xp.full_like(distance, 1e6)
    for dy in (-1, 0, 1):   # the 8 neighbours, not per pixel
        for dx in (-1, 0, 1):
            if dy == 0 and dx == 0:
                continue
            there = _shifted(open_, dy, dx, False)
            rim = rim | there
            dq = _shifted(xp.where(reached, distance, 1e6), dy, dx, 1e6) + float(np.hypot(dx, dy))
            d = xp.where(there, xp.minimum(d, dq), d)
    inner = xp.where(d < 1e5, xp.maximum(cover, xp.clip(0.5 + d, 0.0, 1.0)), cover)
    alpha_in = xp.where(rim, inner, 1.0)
    alpha_out = xp.where(crack, 1.0, xp.clip(cover, None, 0.5))
    if center is None:
        return xp.where(covered, alpha_in, alpha_out)
    return xp.where(covered & ~rim, center, center * alpha_in + (1.0 - center) * alpha_out)
