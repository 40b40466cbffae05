// After the normalization pass: screen-space hole filling (surfsplat.reference.fill_holes is the rule
// in NumPy; the two are held against each other by tests/test_fill_holes.py). A pixel is a hole when
// no splat covers it (or edge coverage covers it in part) or the splats covering it lie behind the surface
// around it; it is filled when the
// surface around it encloses it: along at least 3 of the 4 axes (horizontal, vertical, both diagonals)
// the nearest pixels on both sides that lie in front of it (any covered pixel, for an uncovered one)
// leave a gap of at most FILL_GAP pixels between them (their distances add up to at most
// FILL_GAP + 1) and lie on one surface (depths within the tolerance: a strip of a farther surface
// seen between two surfaces at different depths, e.g. through a bore past its rim, is no gap), and
// along the 4th axis too within FILL_REACH pixels (a crack of that length at most: a slit that opens
// into the background beyond a silhouette, a bay, is not closed). It takes
// the depth, color and weight of the front surface (and full coverage) among those neighbours (those within the
// tolerance of the nearest), each weighted by the inverse of its distance along its axis. A hole in a
// surface is enclosed; the background beyond a silhouette (convex or concave: a corner encloses it
// along one axis) is not, so silhouettes never grow; a larger hole is not. The screen-space rule of
// Pintus et al. 2011 (enclosure along the 4 axes, front neighbours only) with the bounded gap of
// Marroquim et al. 2007, searched directly: the gaps are a few pixels, where a pull-push pyramid
// (Grossman & Dally 1998) would fill holes of any size.
// FILL_GAP (a define: the searches unroll; passes.fill_gap) is the widest gap filled, pixels. Only
// depths are read while searching (u_norm_z, 4 bytes a texel; normalize.frag writes FILL_FAR beyond
// the full image); the color of the (at most 8) neighbours found is read once at the end.
// A pixel enclosed along 3 of the 4 axes is enclosed horizontally or vertically: the search looks at
// one side of those two first, and most pixels (a surface with nothing in front, the open background)
// stop after 2 FILL_GAP texels (llvmpipe skips a branch where a block's pixels all skip it).
#include "camera.glsl"

uniform sampler2D u_norm_color;   // normalize.frag's color (mixed over the background) and weight
uniform sampler2D u_norm_depth;   // normalize.frag's weighted depth sum and coverage alpha
uniform sampler2D u_norm_z;       // its depth (FILL_FAR: uncovered or beyond the full image)
uniform float u_fill_depth;       // depth tolerance in pixels: tau(z) = u_fill_depth * z / u_focal

layout(location = 0) out vec4 out_color;
layout(location = 1) out vec2 out_depth;
layout(location = 2) out float out_z;   // the next iteration's u_norm_z

// The depth tolerance at depth z: the surfaces of two pixels are apart when their depths differ by more.
float tolerance(float z) {
    return u_fill_depth * z / u_focal;
}

// Along direction dir from the fragment: the distance (0: none) and depth of the nearest pixel within
// FILL_GAP whose depth is below limit (in front of the fragment's).
ivec2 texel;
float limit;
int search(ivec2 dir, out float zq) {
    ivec2 hi = textureSize(u_norm_z, 0) - 1;
    zq = FILL_FAR;
    int found = 0;
    for (int k = FILL_GAP; k >= 1; --k) {   // unrolled; the nearest wins: written last
        float z = texelFetch(u_norm_z, clamp(texel + dir * k, ivec2(0), hi), 0).r;
        if (z < limit) {
            found = k;
            zq = z;
        }
    }
    return found;
}

// search() up to FILL_REACH pixels, stopping at the first pixel found (only the few pixels enclosed
// along exactly 3 axes look this far).
int reach(ivec2 dir, out float zq) {
    ivec2 hi = textureSize(u_norm_z, 0) - 1;
    zq = FILL_FAR;
    for (int k = 1; k <= FILL_REACH; ++k) {
        float z = texelFetch(u_norm_z, clamp(texel + dir * k, ivec2(0), hi), 0).r;
        if (z < limit) {
            zq = z;
            return k;
        }
    }
    return 0;
}

// Whether the pixels found on both sides of an axis enclose the fragment: a gap of at most FILL_GAP
// pixels between them, both on one surface.
bool encloses(int a, int b, float za, float zb, int gap) {
    return a > 0 && b > 0 && a + b <= gap + 1 && abs(za - zb) <= tolerance(min(za, zb));
}

void main() {
    texel = ivec2(gl_FragCoord.xy);
    vec4 color = texelFetch(u_norm_color, texel, 0);
    out_color = color;
    out_depth = texelFetch(u_norm_depth, texel, 0).rg;
    float z = texelFetch(u_norm_z, texel, 0).r;
    out_z = z;
    if (color.a < 0.0) return;   // a non-finite accumulation (counted by the renderer)
    // a neighbour in front: nearer than this; any covered one for a pixel not covered whole (edge
    // coverage's partly covered pixels at least half covered have a depth: normalize.frag)
    limit = z < FILL_FAR && out_depth.y >= 1.0 ? z - tolerance(z) : FILL_FAR;
    const ivec2 DIRS[8] = ivec2[8](ivec2(1, 0), ivec2(-1, 0), ivec2(0, 1), ivec2(0, -1), ivec2(1, 1),
                                   ivec2(-1, -1), ivec2(1, -1), ivec2(-1, 1));
    // per axis and side: the distance of the nearest pixel in front (0: none) and its depth
    int steps[8] = int[8](0, 0, 0, 0, 0, 0, 0, 0);
    float zs[8] = float[8](FILL_FAR, FILL_FAR, FILL_FAR, FILL_FAR, FILL_FAR, FILL_FAR, FILL_FAR, FILL_FAR);
    steps[0] = search(DIRS[0], zs[0]);
    steps[2] = search(DIRS[2], zs[2]);
    if (steps[0] == 0 && steps[2] == 0) return;   // neither horizontal nor vertical can enclose
    if (steps[0] > 0) steps[1] = search(DIRS[1], zs[1]);
    if (steps[2] > 0) steps[3] = search(DIRS[3], zs[3]);
    bool axis[4];
    axis[0] = encloses(steps[0], steps[1], zs[0], zs[1], FILL_GAP);
    axis[1] = encloses(steps[2], steps[3], zs[2], zs[3], FILL_GAP);
    if (!axis[0] && !axis[1]) return;
    for (int i = 4; i < 8; ++i) steps[i] = search(DIRS[i], zs[i]);
    axis[2] = encloses(steps[4], steps[5], zs[4], zs[5], FILL_GAP);
    axis[3] = encloses(steps[6], steps[7], zs[6], zs[7], FILL_GAP);
    int enclosed = int(axis[0]) + int(axis[1]) + int(axis[2]) + int(axis[3]);
    if (enclosed < 3) return;
    if (enclosed == 3) {   // a crack along the 4th axis: closed there within FILL_REACH, or open (a bay)
        int open = !axis[0] ? 0 : !axis[1] ? 1 : !axis[2] ? 2 : 3;
        float za, zb;
        int a = reach(DIRS[2 * open], za);
        int b = reach(DIRS[2 * open + 1], zb);
        if (!encloses(a, b, za, zb, FILL_REACH)) return;
    }
    float front = FILL_FAR;
    for (int i = 0; i < 8; ++i)
        if (axis[i / 2]) front = min(front, zs[i]);
    float keep = front + tolerance(front);
    vec4 sum_color = vec4(0.0);
    vec2 sum_depth = vec2(0.0);   // depth, sum of the inverse distances
    for (int i = 0; i < 8; ++i) {
        if (!axis[i / 2] || zs[i] > keep) continue;
        float w = 1.0 / float(steps[i]);
        ivec2 q = texel + DIRS[i] * steps[i];
        sum_color += w * texelFetch(u_norm_color, q, 0);
        sum_depth += w * vec2(zs[i], 1.0);
    }
    vec4 filled = sum_color / sum_depth.y;
    float zf = sum_depth.x / sum_depth.y;
    out_color = filled;
    out_depth = vec2(zf * filled.a, 1.0);   // enclosed by the surface: covered whole (reference.fill_holes)
    out_z = zf;
}
