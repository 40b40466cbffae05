// "flat" after its compute passes (visibility.comp, COMPUTE_OPAQUE_DEPTH and COMPUTE_OPAQUE_INDEX): each
// pixel's nearest small disk, found by the compute passes, written as flat.frag writes a fragment of it
// (its lit color, its exact depth along the pixel's ray, its shading normal), with the depth test
// against the large splats the raster pass drew (drawn first: they keep the pixels where they tie, as
// a depth test in draw order keeps the first). OpenGL 4.3: the splat's attributes come from the
// attribute buffers (splat_buffers.glsl) and its per-splat values from the vertex shaders' camera_splat.
#define COMPUTE_SPLATS 1
#include "camera.glsl"
#include "lighting.glsl"
#include "splat_attributes.glsl"
#include "splat_vertex.glsl"
#include "splat_buffers.glsl"

uniform usampler2D u_opaque_depth;   // the nearest small disk's depth along the pixel's ray (float bits)
uniform usampler2D u_opaque_index;   // its splat; NO_DEPTH's bits: none

layout(location = 0) out vec4 out_color;   // as emit (splat_fragment.glsl) with weight 1
layout(location = 1) out vec4 out_aux;

void main() {
    ivec2 texel = ivec2(gl_FragCoord.xy);
    uint index = texelFetch(u_opaque_index, texel, 0).r;
    if (index == floatBitsToUint(NO_DEPTH)) discard;
    read_splat(int(index));
    Splat s;
    camera_splat(s);   // true: the compute passes drew this splat
    float z = uintBitsToFloat(texelFetch(u_opaque_depth, texel, 0).r);
    gl_FragDepth = window_depth(z);
    out_color = vec4(v_color, 1.0);
    out_aux = vec4(z, v_normal);
}
