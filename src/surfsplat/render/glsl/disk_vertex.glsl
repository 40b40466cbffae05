// Bounds of the quad of a splat drawn as its exact elliptical disk (ray-cast
// per pixel): used by "flat" and by every blended technique's visibility pass.

// Window-pixel box of the projected parallelogram p +- u +- v, which contains
// the ellipse; the whole viewport when a corner is not in front of the near
// plane. False when the box misses the viewport.
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
    if (behind) { lo = vec2(-1.0); hi = u_viewport + 1.0; }
    lo = max(floor(lo), vec2(-1.0));
    hi = min(ceil(hi), u_viewport + 1.0);
    return all(lessThan(lo, hi));
}
