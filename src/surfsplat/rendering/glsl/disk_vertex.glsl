// Bounds of the quad of a splat drawn as its exact elliptical disk (ray-cast
// per pixel): used by "flat" and by every blended technique's visibility pass.

// Relative and absolute (pixels) margins on the exact box of a disk's image (conic_box): float
// rounding must never cut off a pixel the disk covers.
const float CONIC_BOX_MARGIN = 2e-3;
const float CONIC_BOX_MARGIN_PX = 1e-2;

// The exact window box of the disk's image where the whole disk lies in front of the eye by a
// margin (Zwicker 2004, eq. 7-9, as perspective.vert computes it, without the prefilter): the conic's
// center c + x_t and half extents sqrt(S_xx), sqrt(S_yy); false elsewhere (the parallelogram's box
// serves). The parallelogram's box is 1.64 times the ellipse's area on average over the axes'
// rotation (up to 2), and the pixels in it are what the visibility pass and "flat" pay for.
bool conic_box(Splat s, out vec2 lo, out vec2 hi) {
    float z = -s.p.z;
    float zext = length(vec2(s.u.z, s.v.z));
    if (!(z - zext >= max(u_near_far.x, PERSPECTIVE_NEAR_FRACTION * z))) return false;
    vec2 c_px = project_px(s.p);
    vec2 delta = c_px - 0.5 * u_viewport;
    vec2 U = u_focal * s.u.xy + delta * s.u.z;
    vec2 V = u_focal * s.v.xy + delta * s.v.z;
    float h = (z - zext) * (z + zext);
    vec2 xt = (U * s.u.z + V * s.v.z) / h;
    vec2 half_extent = sqrt(xt * xt + (U * U + V * V) / h);
    half_extent += CONIC_BOX_MARGIN * half_extent + CONIC_BOX_MARGIN_PX;
    lo = c_px + xt - half_extent;
    hi = c_px + xt + half_extent;
    return !(any(isnan(lo)) || any(isnan(hi)));
}

// Window-pixel box of the disk within the tile: the box of the projected parallelogram
// p +- u +- v, which contains the ellipse, cut down to the ellipse's own box (conic_box); the whole
// tile when a corner is not in front of the near plane. The box is shrunk to the pixel centers it
// holds; false when it holds none (a sub-pixel disk between centers cannot cover any: no primitive
// is sent).
bool disk_bounds(Splat s, out vec2 lo, out vec2 hi) {
    lo = vec2(1e30);
    hi = vec2(-1e30);
    bool behind = false;
    for (int i = 0; i < 4; ++i) {
        vec3 c = s.p + ((i & 1) == 0 ? s.u : -s.u) + ((i & 2) == 0 ? s.v : -s.v);
        behind = behind || (-c.z < u_near_far.x);
        vec2 q = project_px(c);
        lo = min(lo, q);
        hi = max(hi, q);
    }
#ifdef POINT_PRIMITIVE
    // A point-class splat is far smaller than the near distance (Renderer.draw): its corners project
    // where they are. One nearer than half the near distance cannot occur; it is not drawn.
    if (behind) {
        for (int i = 0; i < 4; ++i) {
            float z = -(s.p + ((i & 1) == 0 ? s.u : -s.u) + ((i & 2) == 0 ? s.v : -s.v)).z;
            if (z < 0.5 * u_near_far.x) return false;
        }
    }
#else
    if (behind) { lo = tile_lo() - 1.0; hi = tile_hi() + 1.0; }
#endif
    vec2 clo, chi;
    if (conic_box(s, clo, chi)) { lo = max(lo, clo); hi = min(hi, chi); }
    // pixel i (center i + 0.5) is inside when lo <= i + 0.5 <= hi
    lo = max(ceil(lo - 0.5), tile_lo());
    hi = min(floor(hi - 0.5) + 1.0, tile_hi());
    return all(lessThan(lo, hi));
}
