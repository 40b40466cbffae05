// Quad of a splat drawn as its exact elliptical disk, ray-cast per pixel: the
// techniques "flat", "phong" and "blend" (and every visibility pass uses disk_bounds).
#include "camera.glsl"
#include "lighting.glsl"
#include "splat_attributes.glsl"
#include "splat_vertex.glsl"
#include "disk_vertex.glsl"
#include "splat_primitive.glsl"

void main() {
    Splat s;
    vec2 lo, hi;
    if (!camera_splat(s) || !disk_bounds(s, lo, hi)) { gl_Position = CULLED; return; }
    emit_box(lo, hi);
}
