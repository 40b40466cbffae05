// Transform feedback of the sequential-LOD interval test (tests/test_gpu_lod.py): 1 where the shared
// test of splat_attributes.glsl keeps the entry, 0 where it rejects it.
#include "camera.glsl"
#include "splat_attributes.glsl"

out float out_kept;

void main() {
    vec3 p = (u_view * vec4(in_position, 1.0)).xyz;
    out_kept = lod_rejected(p) ? 0.0 : 1.0;
}
