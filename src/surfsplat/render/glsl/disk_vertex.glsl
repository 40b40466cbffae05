// Bounds of the quad of a splat drawn as its exact elliptical disk (ray-cast
// per pixel): used by "flat" and by every blended technique's visibility pass.

// Window-pixel box of the projected parallelogram p +- u +- v, which contains
// the ellipse, within the tile; the whole tile when a corner is not in front of the near
// plane. The box is shrunk to the pixel centers it holds; false when it holds
// none (a sub-pixel disk between centers cannot cover any: no primitive is sent).
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
    // pixel i (center i + 0.5) is inside when lo <= i + 0.5 <= hi
    lo = max(ceil(lo - 0.5), tile_lo());
    hi = min(floor(hi - 0.5) + 1.0, tile_hi());
    return all(lessThan(lo, hi));
}
