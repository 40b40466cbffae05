// The visibility of the small splats as a compute shader (OpenGL 4.3; renderer.py uses it where the
// context has compute shaders, and GL_POINTS elsewhere): render/compute_visibility.py. One invocation
// per splat: the vertex shaders' per-splat work (camera_splat, disk_bounds), then the fragment shaders'
// exact ray/disk test at each pixel center of the disk's box. Depths are positive floats, whose bit
// patterns order as unsigned integers. COMPUTE_PASS selects what is kept:
// - COMPUTE_VISIBILITY_PASS (the blended techniques' first pass): the offset depth (Guennebaud 2003,
//   sec. 5: along the viewing ray) by an atomic minimum in the front or the back image, as the raster
//   pass's MIN blending keeps it in the side target (visibility.glsl); cracks.frag takes the smaller.
// - COMPUTE_OPAQUE_DEPTH ("flat", first): the nearest disk's depth, in image 0.
// - COMPUTE_OPAQUE_INDEX ("flat", second): of the disks at that depth, the smallest splat index (the one
//   a depth test in index order keeps), in image 1; opaque_resolve.frag then shades it.
//
// Why: llvmpipe spends most of a GL_POINTS pass per primitive (vertex pipeline, setup, binning, a
// 4x4-pixel block shaded per block a point touches); the loop over a small box costs a few times less
// (measured: benchmarks/render_passes.py).
#define COMPUTE_SPLATS 1
#include "camera.glsl"
#include "lighting.glsl"
#include "splat_attributes.glsl"
#include "splat_vertex.glsl"
#include "disk_vertex.glsl"
#include "disk_ray.glsl"
#include "splat_buffers.glsl"
#include "hiz.glsl"

layout(local_size_x = COMPUTE_GROUP) in;

// Visibility: the offset depths (float bits) of the nearest disks seen from the front (0) and from the
// back (1); opaque: the nearest depth (0) and the splat drawn there (1). Per pixel of the tile; cleared
// to NO_DEPTH's bits (no splat).
layout(r32ui, binding = 0) uniform uimage2D u_image0;
layout(r32ui, binding = 1) uniform uimage2D u_image1;

// frame_options.glsl: u_depth_epsilon
#include "frame_options.glsl"
uniform int u_first;   // the first splat of this dispatch
uniform int u_count;   // splats in it

void main() {
    int k = int(gl_GlobalInvocationID.x);
    if (k >= u_count) return;
    read_splat(u_first + k);
    Splat s;
    vec2 lo, hi;
    if (!camera_splat(s) || !disk_bounds(s, lo, hi)) return;
#if COMPUTE_PASS == COMPUTE_OPAQUE_INDEX && defined(HIZ_BLOCK)
    // behind the nearest disks wherever it reaches (hiz.frag of the first pass's depths): at no pixel its depth
    if (hidden_splat(lo, hi, -s.p.z - length(vec2(s.u.z, s.v.z)))) return;
#endif
    ivec2 origin = ivec2(tile_lo());
    for (float y = lo.y; y < hi.y; y += 1.0) {
        for (float x = lo.x; x < hi.x; x += 1.0) {
            vec2 px = vec2(x, y) + 0.5;   // the pixel's center, as FRAG_PX
            vec3 ray = pixel_ray(px);
            float z;
            if (!ray_disk(ray, z)) continue;
            ivec2 texel = ivec2(x, y) - origin;
#if COMPUTE_PASS == COMPUTE_VISIBILITY_PASS
            z += u_depth_epsilon * v_radius / length(ray);   // as emit (splat_fragment.glsl)
            if (v_back > 0.5) imageAtomicMin(u_image1, texel, floatBitsToUint(z));
            else imageAtomicMin(u_image0, texel, floatBitsToUint(z));
#elif COMPUTE_PASS == COMPUTE_OPAQUE_DEPTH
            imageAtomicMin(u_image0, texel, floatBitsToUint(z));
#else
            if (floatBitsToUint(z) == imageLoad(u_image0, texel).r) imageAtomicMin(u_image1, texel, uint(u_first + k));
#endif
        }
    }
}
