// The primitive a splat's vertex shader emits for its window box [lo, hi] (full-image pixels).
// Instanced quads (default): the corner in_corner of the box. GL_POINTS (POINT_PRIMITIVE, the
// small splats: Renderer.draw): one square point covering the box, its center inside the tile so
// OpenGL's point clipping (by the center) never drops it; the math runs once per splat instead of
// four times. Requires camera.glsl and splat_attributes.glsl.

uniform float u_max_point;   // largest point size the driver draws (GL_POINT_SIZE_RANGE), pixels

void emit_box(vec2 lo, vec2 hi) {
#ifdef POINT_PRIMITIVE
    // the pixel centers the box holds (pixel i: center i + 0.5), within the tile
    lo = max(ceil(lo - 0.5), tile_lo());
    hi = min(floor(hi - 0.5) + 1.0, tile_hi());
    vec2 side = hi - lo;
    if (any(lessThanEqual(side, vec2(0.0)))) { gl_Position = CULLED; gl_PointSize = 1.0; return; }
    gl_Position = px_to_clip(0.5 * (lo + hi));
    gl_PointSize = min(max(side.x, side.y), u_max_point);
#else
    gl_Position = px_to_clip(mix(lo, hi, in_corner * 0.5 + 0.5));
#endif
}
