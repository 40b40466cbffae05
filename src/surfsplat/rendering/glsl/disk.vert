// Quad of a splat drawn as its exact elliptical disk, ray-cast per pixel: the
// techniques "flat", "phong" and "blend" (and every visibility pass uses disk_bounds).
#include "camera.glsl"
#include "lighting.glsl"
#include "splat_attributes.glsl"
#include "splat_vertex.glsl"
#include "disk_vertex.glsl"
#include "splat_primitive.glsl"
#include "hiz.glsl"

void main() {
    Splat s;
    vec2 lo, hi;
    if (!camera_splat(s) || !disk_bounds(s, lo, hi)) { gl_Position = CULLED; return; }
#if PASS == PASS_ACCUMULATION && defined(HIZ_BLOCK)
    // behind the visible surface wherever it is drawn (its disk's depths are at least z minus its extent)
    if (hidden_splat(lo, hi, -s.p.z - length(vec2(s.u.z, s.v.z)))) { gl_Position = CULLED; return; }
#endif
    emit_box(lo, hi);
}
